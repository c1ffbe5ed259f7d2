"""Mitsuba 3 reference radiance at random visible (point, direction) pairs of a .blend, cached in
bench/study/references/<scene>[_quick].npz under a key (the .blend's hash, the settings and the
hash of the scripts that make it, tests/reference/mitsuba_reference.py included), so a stale cache is detected and remade.

    python bench/study/references.py scene.blend [--quick]     (Python with mitsuba; no bpy needed)

The pairs are drawn on Blender's own triangles (area-weighted, cosine-distributed directions),
each seen from an eye point in open space along its direction; nothing of the solver is used."""
from __future__ import annotations

import hashlib
import json
import pathlib
import pickle
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import mitsuba_scene  # noqa: E402
from mitsuba_scene import load_mitsuba  # noqa: E402
from reference.mitsuba_reference import cosine_directions, radiance_along  # noqa: E402

CACHE = HERE / "references"
# "noise": more passes of spp samples (each its own seed) until the reference's relative noise
# over the pairs not on emitters is below it, at most max_spp samples a pair: a small bright
# bulb left glossy_spheres at 0.9% after one pass, the rest 0.1-0.5% (glass_sheet's caustics 2.1%).
FULL = {"pairs": 3000, "spp": 32768, "seed": 11, "noise": 0.004, "max_spp": 32768 * 32}
QUICK = {"pairs": 200, "spp": 1024, "seed": 11}
SOURCES = ("blend_scene.py", "mitsuba_scene.py", "cycles_bsdf.py", "cycles_principled.py", "cycles_glossy.py",
           "cycles_glass.py", "references.py",
           "../../tests/reference/mitsuba_reference.py")


def describe(blend) -> dict:
    """blend_scene's description of the file, read by the bpy module in its own process."""
    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp) / "scene.pickle"
        subprocess.run([sys.executable, str(HERE / "blend_scene.py"), str(blend), str(out)], check=True,
                       stdout=subprocess.DEVNULL)
        return pickle.loads(out.read_bytes())


def cache_key(blend, settings) -> str:
    h = hashlib.sha256(pathlib.Path(blend).read_bytes())
    for name in SOURCES:
        h.update((HERE / name).read_bytes())
    h.update(json.dumps(settings, sort_keys=True).encode())
    return h.hexdigest()


def cache_path(blend, quick: bool, cache=CACHE) -> pathlib.Path:
    return pathlib.Path(cache) / f"{pathlib.Path(blend).stem}{'_quick' if quick else ''}.npz"


def load_cached(blend, quick: bool, cache=CACHE, settings=None):
    """The cached pairs and reference, or None if missing or stale (another .blend or settings)."""
    path = cache_path(blend, quick, cache)
    if not path.exists():
        return None
    data = dict(np.load(path, allow_pickle=False))
    if str(data["key"]) != cache_key(blend, settings or (QUICK if quick else FULL)):
        print(f"study: {path.name} is stale (scene or settings changed): remaking it", flush=True)
        return None
    return data


def reference(blend, quick: bool = False, cache=CACHE, settings=None) -> dict:
    """Pairs and reference for a .blend, from the cache or made now (and cached). settings:
    instead of FULL / QUICK, e.g. the validation scenes' (bench/validation), which may add
    "two_sided" (object names seen and lit from both sides; see mitsuba_scene.scene_dict)."""
    cached = load_cached(blend, quick, cache, settings)
    if cached is not None:
        return cached
    settings = settings or (QUICK if quick else FULL)
    two_sided = settings.get("two_sided", ())
    description = describe(blend)
    scene = mitsuba_scene.load_scene(description, two_sided=two_sided)
    pairs = visible_pairs(description, mitsuba_scene.load_scene(description, two_sided=two_sided, pairs_only=True),
                          settings["pairs"], settings["seed"], two_sided)
    start = time.perf_counter()
    lit = ~np.isin(pairs["object"], [o.name for o in description["objects"] if any(max(m.emission) > 0 for m in o.materials)])
    mean, stderr, spp = sampled_until_quiet(scene, pairs, lit, settings)
    pairs.update(reference=mean, stderr=stderr, reference_seconds=time.perf_counter() - start,
                 key=cache_key(blend, settings), spp=spp)
    path = cache_path(blend, quick, cache)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **pairs)
    return dict(np.load(path, allow_pickle=False))


def relative_noise(mean, stderr, mask) -> float:
    """The standard error's RMS against the radiance's RMS over the pairs in mask."""
    return float(np.sqrt((stderr[mask] ** 2).sum() / max((mean[mask] ** 2).sum(), 1e-300)))


def sampled_until_quiet(scene, pairs, lit, settings):
    """The radiance along the pairs' eye rays in passes of settings["spp"] samples (seeds 5, 6,
    ...): one pass, then as many as its noise over the `lit` pairs says settings["noise"] needs,
    within settings["max_spp"]. (mean, standard error, samples a pair)."""
    spp = settings["spp"]
    mean, stderr = radiance_along(scene, pairs["eye"], pairs["point"], spp, seed=5)
    target, noise = settings.get("noise"), relative_noise(mean, stderr, lit)
    if not target or noise <= target:
        return mean, stderr, spp
    passes = min(int(np.ceil((noise / target) ** 2)), settings["max_spp"] // spp)
    means, variances = [mean], [stderr ** 2]
    for k in range(1, passes):
        m, e = radiance_along(scene, pairs["eye"], pairs["point"], spp, seed=5 + k)
        means.append(m)
        variances.append(e ** 2)
    print(f"references: noise {noise:.4f} after {spp} samples a pair: {passes} passes, "
          f"{relative_noise(np.mean(means, 0), np.sqrt(np.sum(variances, 0)) / passes, lit):.4f}", flush=True)
    return np.mean(means, 0), np.sqrt(np.sum(variances, 0)) / passes, passes * spp


def _back_seen(si):
    """Whether the surfaces hit may be seen from behind: transmitting, two-sided or a light (transparent)."""
    mi = load_mitsuba()
    flags = si.bsdf().flags()
    return np.array(mi.has_flag(flags, mi.BSDFFlags.Transmission) | mi.has_flag(flags, mi.BSDFFlags.BackSide)
                    | mi.has_flag(flags, mi.BSDFFlags.Null), bool)


def _in_open_space(scene, eye, rng, rays: int = 8):
    """Whether each eye point is in the scene's open space: rays from it in random directions
    meet only fronts of surfaces (or nothing), or backs that may be seen (_back_seen). An eye
    under a floor or inside a closed object (e.g. looking at the bottom of a box standing on the
    floor) sees a back first."""
    mi = load_mitsuba()
    ok = np.ones(len(eye), bool)
    for _ in range(rays):
        d = rng.normal(size=eye.shape)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(eye.T.astype(np.float32)), mi.Vector3f(d.T.astype(np.float32))))
        back = np.isfinite(np.array(si.t)) & (np.einsum("ij,ij->i", np.array(si.n).T, d) > 0)
        back &= ~_back_seen(si)
        ok &= ~back
    return ok


def _kind(material) -> str:
    """What the pair's surface is, for errors per kind: glass, glossy (metal) or diffuse."""
    diffuse, glossy = sum(material.albedo) / 3, sum(material.specular) / 3
    if material.transmission > max(diffuse, glossy):
        return "glass"
    return "glossy" if glossy > diffuse else "diffuse"


def visible_pairs(description, scene, count: int, seed: int, two_sided=()) -> dict:
    """Random points on the scene's triangles (area-weighted) with cosine-distributed outgoing
    directions, each with an eye point along its direction in open space. Transmitting surfaces
    and the objects named in two_sided are seen from both sides."""
    mi = load_mitsuba()
    rng = np.random.default_rng(seed)
    objects = description["objects"]
    tri = [(k, t) for k, o in enumerate(objects) for t in range(len(o.triangles))]
    corners = np.array([objects[k].positions[objects[k].triangles[t]] for k, t in tri])
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / np.maximum(2 * area, 1e-300)[:, None]
    transmits = np.array([objects[k].materials[objects[k].material[t]].transmission > 0.5 or objects[k].name in two_sided
                          for k, t in tri])
    lo, hi = corners.reshape(-1, 3).min(0), corners.reshape(-1, 3).max(0)
    scale = float(np.linalg.norm(hi - lo))
    kinds = np.array([_kind(objects[k].materials[objects[k].material[t]]) for k, t in tri])
    out = {k: [] for k in ("object", "polygon", "kind", "point", "direction", "eye")}
    while len(out["object"]) < count:
        n = 4 * count
        pick = rng.choice(len(tri), n, p=area / area.sum())
        r1, r2 = np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 1, n)
        c = corners[pick]
        pts = (1 - r1)[:, None] * c[:, 0] + (r1 * (1 - r2))[:, None] * c[:, 1] + (r1 * r2)[:, None] * c[:, 2]
        nrm = normal[pick].copy()
        # Transmitting surfaces are seen from both sides.
        flip = transmits[pick] & (rng.uniform(0, 1, n) < 0.5)
        nrm[flip] *= -1
        d = cosine_directions(nrm, rng)
        origin = pts + nrm * 1e-5 * scale
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(origin.T.astype(np.float32)), mi.Vector3f(d.T.astype(np.float32))))
        t = np.array(si.t)
        escaped = ~np.isfinite(t)
        t = np.where(escaped, scale, t)
        eye = pts + d * (0.5 * np.minimum(t, 0.5 * scale))[:, None]
        # The eye must be in open space: the ray leaves into the scene and meets a surface's
        # front (or the back of a transmitting one), or nothing.
        front = np.einsum("ij,ij->i", np.array(si.n).T, d) < 0
        front |= _back_seen(si)
        keep = (escaped | front) & (np.linalg.norm(eye - pts, axis=1) > 1e-4 * scale)
        keep &= _in_open_space(scene, eye, rng)
        for j in np.nonzero(keep)[0][: count - len(out["object"])]:
            k, t_ = tri[pick[j]]
            out["object"].append(objects[k].name)
            out["polygon"].append(objects[k].polygon[t_])
            out["kind"].append(kinds[pick[j]])
            out["point"].append(pts[j])
            out["direction"].append(d[j])
            out["eye"].append(eye[j])
    return {k: np.array(v) for k, v in out.items()}


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description="Mitsuba 3 reference of a .blend at random visible pairs (cached).")
    parser.add_argument("blend")
    parser.add_argument("--quick", action="store_true", help="few pairs and samples (smoke runs)")
    parser.add_argument("--cache", default=str(CACHE), help="cache folder")
    args = parser.parse_args()
    data = reference(args.blend, quick=args.quick, cache=args.cache)
    print(json.dumps({"pairs": len(data["point"]), "reference_seconds": float(data["reference_seconds"]),
                      "reference_noise": float(np.sqrt((data["stderr"] ** 2).sum() / (data["reference"] ** 2).sum()))}))
