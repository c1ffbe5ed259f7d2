"""Reference radiance from Mitsuba 3 (an independent path tracer) at (point, direction) pairs.

Mitsuba's LLVM variant traces all pairs' samples as one wide batch; it needs LLVM (Debian's
libllvm19), found through DRJIT_LIBLLVM_PATH."""
from __future__ import annotations

import glob
import os
import pathlib
import tempfile

import numpy as np

from .scene_spec import SceneSpec


def _llvm_path():
    # Dr.Jit needs a recent LLVM: Debian 12's libllvm19 (older ones on the machine do not work).
    found = sorted(glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM-19.so*"))
    return found[0] if found else None


def load_mitsuba():
    if "DRJIT_LIBLLVM_PATH" not in os.environ and _llvm_path():
        os.environ["DRJIT_LIBLLVM_PATH"] = _llvm_path()
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    return mi


def to_mitsuba(spec: SceneSpec, max_depth: int = -1):
    """One-sided diffuse patches and area emitters, as the solver models them."""
    mi = load_mitsuba()
    # Mitsuba reads the OBJ files while it loads the scene: the folder goes with the load.
    with tempfile.TemporaryDirectory(prefix="bsgi-mitsuba-") as name:
        folder = pathlib.Path(name)
        shapes = {"type": "scene", "integrator": {"type": "path", "max_depth": max_depth}}
        for i, p in enumerate(spec.patches):
            path = folder / f"patch{i}.obj"
            faces = "f 1 2 3 4" if len(p.corners) == 4 else "f 1 2 3"
            text = "".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in p.corners)
            if p.ggx_anisotropic:
                # The solver's tangent on a patch is its first edge (ds/du), turned by the rotation.
                c = np.asarray(p.corners, float)
                uv = lobe_coordinates(c, c[1] - c[0], p.ggx_anisotropic[2])
                text += "".join(f"vt {s:.17g} {t:.17g}\n" for s, t in uv)
                faces = " ".join(f"{k}/{k}" for k in faces.split()[1:])
                faces = "f " + faces
            path.write_text(text + faces + "\n")
            bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(p.albedo)}}
            if p.ggx_alpha > 0:
                bsdf = {"type": "roughconductor", "distribution": "ggx", "alpha": p.ggx_alpha, "material": "none"}
            if p.ggx_anisotropic:
                bsdf = {"type": "roughconductor", "distribution": "ggx", "alpha_u": p.ggx_anisotropic[0],
                        "alpha_v": p.ggx_anisotropic[1], "material": "none"}
            if p.dielectric:
                bsdf = {"type": "roughdielectric", "distribution": "ggx", "alpha": p.dielectric[1],
                        "int_ior": p.dielectric[0], "ext_ior": 1.0}
            if p.thin_glass:
                bsdf = {"type": "thindielectric", "int_ior": p.thin_glass, "ext_ior": 1.0}
            shape = {"type": "obj", "filename": str(path), "face_normals": True, "bsdf": bsdf}
            if max(p.emission) > 0:
                shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": list(p.emission)}}
            shapes[f"patch{i}"] = shape
        return mi.load_dict(shapes, optimize=False)


def visible_pairs(spec: SceneSpec, count: int, seed: int = 0, margin: float = 0.02):
    """Random (patch index, u, v, outgoing direction) on receiving patches, each seen from a point
    along its direction: returns patch indices, (u, v), points, directions, eye points. (u, v) lie
    in [margin, 1 - margin]."""
    mi = load_mitsuba()
    scene = to_mitsuba(spec)
    rng = np.random.default_rng(seed)
    receivers = [i for i, p in enumerate(spec.patches) if p.receiver]
    areas = np.array([_area(spec.patches[i].corners) for i in receivers])
    out = {k: [] for k in ("patch", "uv", "point", "direction", "eye")}
    while len(out["patch"]) < count:
        n = 4 * count
        pick = rng.choice(len(receivers), n, p=areas / areas.sum())
        uv = rng.uniform(margin, 1 - margin, (n, 2))
        pts, nrm = zip(*(_point(spec.patches[receivers[k]].corners, *uv[j]) for j, k in enumerate(pick)))
        pts, nrm = np.array(pts), np.array(nrm)
        # Transmitting patches are seen from both sides.
        flip = np.array([bool(spec.patches[receivers[k]].dielectric) for k in pick]) & (rng.uniform(0, 1, n) < 0.5)
        nrm[flip] *= -1
        d = cosine_directions(nrm, rng)
        scale = np.abs(pts).max() + 1
        origin = pts + nrm * 1e-5 * scale
        ray = mi.Ray3f(mi.Point3f(origin.T.astype(np.float32)), mi.Vector3f(d.T.astype(np.float32)))
        si = scene.ray_intersect(ray)
        t = np.array(si.t)
        escaped = ~np.isfinite(t)
        t = np.where(escaped, 1.0, t)
        eye = pts + d * (0.5 * np.minimum(t, 1.0))[:, None]
        # The eye must be in open space: the ray from the point leaves into the scene and meets a
        # surface's front (or nothing), not the inside of a closed object (the floor under a box).
        front = np.einsum("ij,ij->i", np.array(si.n).T, d) < 0
        # The back of a transmitting surface also faces open space.
        front |= np.array(mi.has_flag(si.bsdf().flags(), mi.BSDFFlags.Transmission), bool)
        keep = (escaped | front) & (np.linalg.norm(eye - pts, axis=1) > 1e-4 * scale)
        for j in np.nonzero(keep)[0][: count - len(out["patch"])]:
            out["patch"].append(receivers[pick[j]])
            out["uv"].append(uv[j])
            out["point"].append(pts[j])
            out["direction"].append(d[j])
            out["eye"].append(eye[j])
    return {k: np.array(v) for k, v in out.items()}


def reference_radiance(spec: SceneSpec, pairs, spp: int, seed: int = 0, batch: int = 2_000_000):
    """Mean radiance Mitsuba's path tracer finds along each eye -> point ray, and its standard
    error (per pair, RGB)."""
    return radiance_along(to_mitsuba(spec), pairs["eye"], pairs["point"], spp, seed, batch)


def radiance_along(scene, eye, point, spp: int, seed: int = 0, batch: int = 2_000_000):
    """Mean radiance of a loaded Mitsuba scene along each eye -> point ray, and its standard error."""
    mi = load_mitsuba()
    import drjit as dr

    sampler = mi.load_dict({"type": "independent"})
    integrator = scene.integrator()
    d = point - eye
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = len(eye)
    total = np.zeros((n, 3))
    total2 = np.zeros((n, 3))
    per_batch = max(1, batch // n)
    done, round_ = 0, 0
    while done < spp:
        k = min(per_batch, spp - done)
        o = np.repeat(eye, k, axis=0).astype(np.float32)
        v = np.repeat(d, k, axis=0).astype(np.float32)
        sampler.seed(seed * 1000003 + round_, n * k)
        ray = mi.Ray3f(mi.Point3f(o.T), mi.Vector3f(v.T))
        color, _, _ = integrator.sample(scene, sampler, ray)
        c = np.array(mi.Vector3f(color)).T.reshape(n, k, 3)
        total += c.sum(axis=1)
        total2 += (c * c).sum(axis=1)
        done += k
        round_ += 1
        dr.eval()
    mean = total / spp
    var = np.maximum(total2 / spp - mean * mean, 0)
    return mean, np.sqrt(var / spp)


def cosine_directions(normals, rng):
    """One outgoing direction per normal, cosine-distributed about it (unit vectors, (n, 3))."""
    n = len(normals)
    r, phi = np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 2 * np.pi, n)
    t1 = np.cross(normals, np.where(np.abs(normals[:, :1]) > 0.5, [[0, 1, 0]], [[1, 0, 0]]))
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(normals, t1)
    return (r * np.cos(phi))[:, None] * t1 + (r * np.sin(phi))[:, None] * t2 + np.sqrt(1 - r * r)[:, None] * normals


def lobe_coordinates(corners, tangent, rotation=0.0):
    """Texture coordinates of a planar polygon's corners along `tangent` turned by `rotation`
    about the front normal, and along the normal x that direction. Mitsuba's shading frame
    follows dp/du, so an anisotropic BSDF's alpha_u then lies along the turned tangent."""
    c = np.asarray(corners, float)
    n = np.cross(c[1] - c[0], c[-1] - c[0])
    if not np.linalg.norm(n) > 0:
        return [(0.0, 0.0)] * len(c)  # no area, never hit
    n /= np.linalg.norm(n)
    e = np.asarray(tangent, float) - n * np.dot(tangent, n)
    e /= np.linalg.norm(e)
    t = np.cos(rotation) * e + np.sin(rotation) * np.cross(n, e)
    b = np.cross(n, t)
    return [(float(np.dot(p - c[0], t)), float(np.dot(p - c[0], b))) for p in c]


def _area(c):
    if len(c) == 3:
        return 0.5 * np.linalg.norm(np.cross(c[1] - c[0], c[2] - c[0]))
    return np.linalg.norm(np.cross(c[1] - c[0], c[3] - c[0]))


def _point(c, u, v):
    """Point and unit normal at (u, v) with the solver's parameterizations."""
    if len(c) == 4:
        p = (1 - u) * (1 - v) * c[0] + u * (1 - v) * c[1] + u * v * c[2] + (1 - u) * v * c[3]
        n = np.cross((c[1] - c[0]) * (1 - v) + (c[2] - c[3]) * v, (c[3] - c[0]) * (1 - u) + (c[2] - c[1]) * u)
    else:
        p = c[0] + u * (c[1] - c[0]) + u * v * (c[2] - c[1])
        n = np.cross(c[1] - c[0], c[2] - c[0])
    return p, n / np.linalg.norm(n)
