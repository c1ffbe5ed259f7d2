"""A Blender scene (as blend_scene describes it) in Mitsuba 3: the triangles Blender renders, each
material as its nodes state it (not the solver's single-BSDF approximation, so that what the
solver drops shows as error), and the area lights as one-sided emitting rectangles and discs."""
from __future__ import annotations

import pathlib
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from reference.mitsuba_reference import load_mitsuba  # noqa: E402

# Below this roughness Mitsuba's smooth models are used (GGX with alpha -> 0 is the mirror).
SMOOTH_ROUGHNESS = 0.02


def bsdf(material) -> dict:
    """The Mitsuba BSDF of a material: whichever of diffuse, metal and glass carries most energy,
    as Blender's Principled BSDF splits it (a dielectric coat over a diffuse base: roughplastic)."""
    diffuse = sum(material.albedo) / 3
    glossy = sum(material.specular) / 3
    alpha = max(material.roughness, 0.0) ** 2
    smooth = material.roughness < SMOOTH_ROUGHNESS
    if material.transmission > max(diffuse, glossy):
        ior = max(material.ior, 1.0 + 1e-3)
        if smooth:
            return {"type": "dielectric", "int_ior": ior, "ext_ior": 1.0}
        return {"type": "roughdielectric", "distribution": "ggx", "alpha": alpha, "int_ior": ior, "ext_ior": 1.0}
    if glossy > diffuse:
        # A conductor whose Fresnel reflectance at normal incidence is the specular colour:
        # k = 0 and eta from f0 = ((eta - 1) / (eta + 1))^2 (f0 = 1: Fresnel 1, material 'none').
        f0 = np.clip(np.asarray(material.specular, float), 0.0, 1.0)
        if f0.min() >= 1 - 1e-6:
            conductor = {"material": "none"}
        else:
            s = np.sqrt(np.minimum(f0, 1 - 1e-4))
            eta = (1 + s) / (1 - s)
            conductor = {"eta": {"type": "rgb", "value": eta.tolist()}, "k": {"type": "rgb", "value": [0.0] * 3}}
        if smooth:
            return {"type": "conductor", **conductor}
        return {"type": "roughconductor", "distribution": "ggx", "alpha": alpha, **conductor}
    if glossy > 0.01:
        return {"type": "roughplastic", "distribution": "ggx", "alpha": max(alpha, 1e-4),
                "int_ior": max(material.ior, 1.0 + 1e-3),
                "diffuse_reflectance": {"type": "rgb", "value": list(material.albedo)}}
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(material.albedo)}}


def _obj_text(positions, triangles):
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in positions]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    return "\n".join(lines) + "\n"


def scene_dict(description, max_depth: int = -1) -> dict:
    mi = load_mitsuba()
    folder = pathlib.Path(tempfile.mkdtemp(prefix="bsgi-study-"))
    shapes = {"type": "scene", "integrator": {"type": "path", "max_depth": max_depth}}
    for k, obj in enumerate(description["objects"]):
        for m, material in enumerate(obj.materials):
            tris = obj.triangles[obj.material == m]
            if not len(tris):
                continue
            path = folder / f"object{k}_{m}.obj"
            path.write_text(_obj_text(obj.positions, tris))
            shape = {"type": "obj", "filename": str(path), "face_normals": True, "bsdf": bsdf(material)}
            if max(material.emission) > 0:
                shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": list(material.emission)}}
            shapes[f"object{k}_{m}"] = shape
    for k, light in enumerate(description["lights"]):
        # Mitsuba's rectangle and disc span [-1, 1]^2 / the unit disc with the normal +z; Blender's
        # area lights emit along their local -z: scale by the half sizes and turn about x.
        local = np.diag([light.half_a, -light.half_b, -1.0, 1.0])
        shapes[f"light{k}"] = {
            "type": "rectangle" if light.shape == "RECTANGLE" else "disk",
            "to_world": mi.ScalarTransform4f(light.matrix @ local),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": list(light.radiance)}},
        }
    return shapes


def load_scene(description, max_depth: int = -1):
    mi = load_mitsuba()
    return mi.load_dict(scene_dict(description, max_depth), optimize=False)
