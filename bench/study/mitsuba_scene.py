"""A Blender scene (as blend_scene describes it) in Mitsuba 3: the triangles Blender renders, each
material as its nodes state it (not the solver's single-BSDF approximation, so that what the
solver drops shows as error; anisotropic metals along the tangent Cycles gives them), and the area
lights as one-sided emitting rectangles and discs that rays pass through."""
from __future__ import annotations

import atexit
import pathlib
import shutil
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from reference.mitsuba_reference import lobe_coordinates, load_mitsuba  # noqa: E402

import cycles_glass  # noqa: E402  (beside this file)
import cycles_glossy  # noqa: E402
import cycles_principled  # noqa: E402

# Below this roughness Mitsuba's smooth models are used (GGX with alpha -> 0 is the mirror).
SMOOTH_ROUGHNESS = 0.02


def anisotropic(material) -> bool:
    return material.stretch != 1


def bsdf(material) -> dict:
    """The Mitsuba BSDF of a material: whichever of diffuse, metal and glass carries most energy,
    as Blender's Principled BSDF splits it (a dielectric coat over a diffuse base: roughplastic).
    Anisotropic metals get alpha_u along the tangent (the shape's texture coordinates say where)."""
    diffuse = sum(material.albedo) / 3
    glossy = sum(material.specular) / 3
    alpha = max(material.roughness, 0.0) ** 2
    smooth = material.roughness < SMOOTH_ROUGHNESS
    if material.transmission > max(diffuse, glossy):
        ior = max(material.ior, 1.0 + 1e-3)
        if smooth:
            return {"type": "dielectric", "int_ior": ior, "ext_ior": 1.0}
        # Cycles' glass (its shadowing, its light carried across without the radiance's
        # (n_o / n_i)^2, its Multiscatter GGX): cycles_glass.py.
        return cycles_glass.bsdf_dict(ior, alpha, getattr(material, "multiscatter", False))
    if glossy > diffuse:
        f0 = np.clip(np.asarray(material.specular, float), 0.0, 1.0)
        white = f0.min() >= 1 - 1e-6  # Fresnel 1
        if not smooth:
            # Cycles' metal (the Principled BSDF's F82 tint model with its default white tint:
            # Schlick's Fresnel from f0 = the base colour) or Glossy BSDF (its colour times GGX,
            # no Fresnel), with Cycles' height-correlated shadowing and, with Multiscatter GGX,
            # its multiple scattering (cycles_glossy.py). Its anisotropy: alpha_u = alpha stretch
            # along the tangent (the shape's texture coordinates say where), alpha_v = alpha / stretch.
            return cycles_glossy.bsdf_dict(f0, material.schlick and not white, alpha * material.stretch,
                                           alpha / material.stretch, getattr(material, "multiscatter", False))
        if white:
            return {"type": "conductor", "material": "none"}
        if not material.schlick:
            # A mirror Glossy BSDF: its colour times the mirror, without Fresnel.
            return {"type": "conductor", "material": "none", "specular_reflectance": {"type": "rgb", "value": f0.tolist()}}
        # A mirror: a conductor whose Fresnel reflectance at normal incidence is the colour
        # (k = 0, eta from f0 = ((eta - 1) / (eta + 1))^2), near Schlick's but for grazing angles.
        s = np.sqrt(np.minimum(f0, 1 - 1e-4))
        eta = (1 + s) / (1 - s)
        return {"type": "conductor", "eta": {"type": "rgb", "value": eta.tolist()}, "k": {"type": "rgb", "value": [0.0] * 3}}
    if glossy > 0 and getattr(material, "coat", False):
        # Cycles' Principled dielectric: its base under the coat, layered as Cycles layers it
        # (roughplastic reflected 0.60 of a base of 0.8 at roughness 0.5, Cycles 0.81).
        return cycles_principled.bsdf_dict(material.albedo, material.roughness, float(np.mean(material.specular)),
                                           getattr(material, "multiscatter", False))
    if glossy > 0.01:
        return {"type": "roughplastic", "distribution": "ggx", "alpha": max(alpha, 1e-4),
                "int_ior": max(material.ior, 1.0 + 1e-3),
                "diffuse_reflectance": {"type": "rgb", "value": list(material.albedo)}}
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(material.albedo)}}


def _obj_text(positions, triangles, normals, tangents=None, rotation=0.0):
    """OBJ text of triangles, each with its own corners and their shading normals ((T, 3, 3),
    blend_scene.corner_normals); with tangents (per triangle), texture coordinates along its
    tangent turned by `rotation` (see lobe_coordinates)."""
    lines = []
    for k, tri in enumerate(triangles):
        lines += [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in positions[tri]]
        lines += [f"vn {x:.17g} {y:.17g} {z:.17g}" for x, y, z in normals[k]]
        if tangents is None:
            lines.append("f " + " ".join(f"{3 * k + j}//{3 * k + j}" for j in (1, 2, 3)))
        else:
            lines += [f"vt {s:.17g} {t:.17g}" for s, t in lobe_coordinates(positions[tri], tangents[k], rotation)]
            lines.append("f " + " ".join(f"{3 * k + j}/{3 * k + j}/{3 * k + j}" for j in (1, 2, 3)))
    return "\n".join(lines) + "\n"


def scene_dict(description, max_depth: int = -1, two_sided=(), pairs_only: bool = False) -> dict:
    """two_sided: names of objects rendered with `twosided` (Cycles shades both sides of every
    surface; the study's scenes leave it empty, their backs seeing no light). The area lights'
    shapes let rays through (a `null` BSDF), as Blender's lights, which cast no shadow: an opaque
    black shape darkened the study's Cornell box by 0.85% against Cycles' bake. (Mitsuba's shadow
    rays still stop at them: with one light per scene only rays towards that light, which end
    short of it.)"""
    mi = load_mitsuba()
    cycles_principled.register(mi)
    cycles_glossy.register(mi)
    cycles_glass.register(mi)
    folder = pathlib.Path(tempfile.mkdtemp(prefix="bsgi-study-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)  # the dict names its files: kept until exit
    shapes = {"type": "scene", "integrator": {"type": "path", "max_depth": max_depth}}
    for k, obj in enumerate(description["objects"]):
        for m, material in enumerate(obj.materials):
            chosen = obj.material == m
            tris = obj.triangles[chosen]
            if not len(tris):
                continue
            path = folder / f"object{k}_{m}.obj"
            path.write_text(_obj_text(obj.positions, tris, obj.normals[chosen],
                                      *((obj.tangent[chosen], material.rotation) if anisotropic(material) else ())))
            chosen_bsdf = bsdf(material)
            if pairs_only and chosen_bsdf["type"] == "principled":
                # Mitsuba's principled BSDF flags a back side it does not shade: drawing pairs
                # (references.visible_pairs) would take its backs for ones that may be seen.
                chosen_bsdf = {"type": "diffuse"}
            if obj.name in two_sided and material.transmission <= 0.5:
                chosen_bsdf = {"type": "twosided", "bsdf": chosen_bsdf}
            # Cycles' shading normals: a smooth surface's interpolated (flat facets made the study's
            # NURBS spheres' highlights 4-5% off at their flanks, either way), a flat face's own.
            shape = {"type": "obj", "filename": str(path), "bsdf": chosen_bsdf}
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
            "bsdf": {"type": "null"},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": list(light.radiance)}},
        }
    return shapes


def load_scene(description, max_depth: int = -1, two_sided=(), pairs_only: bool = False):
    """pairs_only: the scene for drawing visible pairs, whose BSDFs' flags say which sides may be
    seen (see scene_dict), not for rendering."""
    mi = load_mitsuba()
    return mi.load_dict(scene_dict(description, max_depth, two_sided, pairs_only), optimize=False)
