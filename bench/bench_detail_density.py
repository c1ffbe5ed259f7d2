"""What SolverSettings.detail_density_max costs and buys (issue 16): the furnished interior of
bench/interior_core.py (sun through a window, sky, shelves of books) solved at the preview preset
with coeffs_from_size and detail_tolerance 0.005 (the preset's), and the density cap at 16 (the
default), 32 and unlimited, and with them off (the preset's 12 x 12 on every surface): each solve's seconds and coefficients, and its relative RMS error against Mitsuba 3 (an
independent path tracer) at visible (point, direction) pairs on the receivers' fronts, chosen by
area, over all of them and over those on surfaces under 0.8 m (where the cap acts), and the
solver's own error estimate pooled over those small surfaces against their measured error. The
reference's own noise is taken out of the errors. Mitsuba's sun is a directional light (the
solver's has the sun's 0.53 degrees): the same for every cap.

    python bench/run.py detail_density          (300 objects, 4,096 samples: about a minute)
    BSGI_BENCH_DETAIL_OBJECTS=100 BSGI_BENCH_DETAIL_SPP=1024 BSGI_BENCH_DETAIL_CAPS=16,inf python bench/run.py detail_density
"""
from __future__ import annotations

import os
import pathlib
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE.parent / "example_blends"))

import interior_core  # noqa: E402
import interior_layout  # noqa: E402
from reference import mitsuba_reference  # noqa: E402

OBJECTS = int(os.environ.get("BSGI_BENCH_DETAIL_OBJECTS", "300"))
SPP = int(os.environ.get("BSGI_BENCH_DETAIL_SPP", "4096"))
PAIRS = 2000
CAPS = tuple(float(c) for c in os.environ.get("BSGI_BENCH_DETAIL_CAPS", "16,32,inf").split(","))
SMALL = 0.8  # m: the square root of a surface's area under which the cap acts here


def quads(interior):
    """The scene's quads in bsgi.Scene order, with their materials."""
    out = list(interior_layout.room_quads(interior))
    for thing in interior.things:
        for piece in thing.pieces:
            if isinstance(piece, interior_layout.Ball):
                piece = interior_layout.Box(piece.centre, (2 * piece.radius,) * 3, piece.material)
            out += [(piece.material, q) for q in interior_layout.box_quads(piece)]
    return [(m, np.asarray(q, float)) for m, q in out]


def to_mitsuba(interior, folder: pathlib.Path):
    """One OBJ a material (face normals: the quads are planar), the sun and the sky."""
    mi = mitsuba_reference.load_mitsuba()
    by_material: dict = {}
    for material, q in quads(interior):
        by_material.setdefault(material, []).append(q)
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": -1}}
    for k, (material, qs) in enumerate(by_material.items()):
        path = folder / f"m{k}.obj"
        lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for q in qs for x, y, z in q]
        lines += [f"f {4 * j + 1} {4 * j + 2} {4 * j + 3} {4 * j + 4}" for j in range(len(qs))]
        path.write_text("\n".join(lines) + "\n")
        rgb, metallic, roughness = interior_layout.MATERIALS[material]
        bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(rgb)}}
        if metallic:  # as bench/interior_core.py: GGX with Fresnel 1, tinted
            bsdf = {"type": "roughconductor", "distribution": "ggx", "alpha": roughness * roughness, "material": "none",
                    "specular_reflectance": {"type": "rgb", "value": list(rgb)}}
        scene[f"m{k}"] = {"type": "obj", "filename": str(path), "face_normals": True, "bsdf": bsdf}
    scene["sun"] = {"type": "directional", "direction": [-c for c in interior.sun_direction],
                    "irradiance": {"type": "rgb", "value": [interior_core.SUN_IRRADIANCE] * 3}}
    scene["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": list(interior_core.SKY_RADIANCE)}}
    return mi.load_dict(scene, optimize=False)


def visible_pairs(mitsuba_scene, patches, count: int, seed: int = 0, margin: float = 0.02):
    """As tests/reference/mitsuba_reference.visible_pairs: points on the quads' fronts by area,
    cosine-distributed directions, each seen from a point in open space along it."""
    mi = mitsuba_reference.load_mitsuba()
    rng = np.random.default_rng(seed)
    areas = np.array([mitsuba_reference._area(q) for _, q in patches])
    out = {k: [] for k in ("patch", "uv", "point", "direction", "eye")}
    while len(out["patch"]) < count:
        n = 4 * count
        pick = rng.choice(len(patches), n, p=areas / areas.sum())
        uv = rng.uniform(margin, 1 - margin, (n, 2))
        pts, nrm = map(np.array, zip(*(mitsuba_reference._point(patches[k][1], *uv[j]) for j, k in enumerate(pick))))
        d = mitsuba_reference.cosine_directions(nrm, rng)
        origin = pts + nrm * 1e-4
        si = mitsuba_scene.ray_intersect(mi.Ray3f(mi.Point3f(origin.T.astype(np.float32)), mi.Vector3f(d.T.astype(np.float32))))
        t = np.array(si.t)
        escaped = ~np.isfinite(t)
        eye = pts + d * (0.5 * np.minimum(np.where(escaped, 1.0, t), 1.0))[:, None]
        front = np.einsum("ij,ij->i", np.array(si.n).T, d) < 0
        keep = (escaped | front) & (np.linalg.norm(eye - pts, axis=1) > 1e-3)
        for j in np.nonzero(keep)[0][: count - len(out["patch"])]:
            for key, value in (("patch", pick[j]), ("uv", uv[j]), ("point", pts[j]), ("direction", d[j]), ("eye", eye[j])):
                out[key].append(value)
    return {k: np.array(v) for k, v in out.items()}


def rel_rmse(got, want, stderr, mask):
    squared = np.mean(np.sum((got[mask] - want[mask]) ** 2, axis=1)) - np.mean(np.sum(stderr[mask] ** 2, axis=1))
    return float(np.sqrt(max(squared, 0.0)) / np.sqrt(np.mean(np.sum(want[mask] ** 2, axis=1))))


def run() -> dict:
    import bsgi
    from reference.scene_spec import solved_radiance

    scene, interior = interior_core.build_scene(OBJECTS)
    patches = quads(interior)
    with tempfile.TemporaryDirectory(prefix="bsgi-detail-") as folder:
        reference_scene = to_mitsuba(interior, pathlib.Path(folder))
        pairs = visible_pairs(reference_scene, patches, PAIRS, seed=3)
        start = time.perf_counter()
        want, stderr = mitsuba_reference.radiance_along(reference_scene, pairs["eye"], pairs["point"], SPP, seed=7)
        mitsuba_seconds = time.perf_counter() - start
    size = np.array([np.sqrt(mitsuba_reference._area(patches[i][1])) for i in pairs["patch"]])
    small = size < SMALL
    everywhere = np.ones(len(size), bool)
    noise = float(np.sqrt(np.mean(np.sum(stderr ** 2, axis=1)) / np.mean(np.sum(want ** 2, axis=1))))
    print(f"  {OBJECTS} objects, {len(scene)} surfaces; Mitsuba {SPP} spp in {mitsuba_seconds:.0f} s, its noise {noise:.4f} "
          f"relative; {small.sum()} of {len(size)} pairs on surfaces under {SMALL} m", flush=True)
    figures = {"detail_objects": OBJECTS, "detail_reference_noise": noise}
    sides = None
    for cap in (None,) + CAPS:  # None: the preset with the adaptive coefficients off, every surface 12 x 12
        settings = bsgi.SolverSettings.preset("preview")
        settings.memory_budget_mb = 24000
        if cap is None:
            settings.coeffs_from_size, settings.detail_tolerance = False, 0.0
        else:
            settings.coeffs_from_size, settings.detail_tolerance, settings.detail_density_max = True, 0.005, cap
        if sides is None:
            sides = bsgi.probe_sides(scene, settings)[0]
        start = time.perf_counter()
        solution = bsgi.solve(scene, settings, sides=sides)
        seconds = time.perf_counter() - start
        got = solved_radiance(scene, solution, pairs)
        name = "uniform" if cap is None else f"{int(cap)}" if np.isfinite(cap) else "unlimited"
        figures[f"detail_{name}_seconds"] = seconds
        figures[f"detail_{name}_coefficients"] = solution.stats["coefficients"]
        figures[f"detail_{name}_rel_rmse"] = rel_rmse(got, want, stderr, everywhere)
        figures[f"detail_{name}_small_rel_rmse"] = rel_rmse(got, want, stderr, small)
        # The error estimate on the small surfaces (most with 16 checks, a quarter of their
        # nodes), pooled: each pair's surface's estimate times the pair's radiance, against the
        # error measured there.
        estimated = np.array([solution.reports[int(i)]["estimated_error"] for i in pairs["patch"]])
        pooled = small & np.isfinite(estimated)
        figures[f"detail_{name}_small_estimate_ratio"] = float(
            np.sqrt(np.mean(estimated[pooled] ** 2 * np.sum(got[pooled] ** 2, axis=1)) / np.mean(np.sum(want[pooled] ** 2, axis=1)))
            / rel_rmse(got, want, stderr, pooled))
        print(f"  {'the same coefficients everywhere' if cap is None else 'detail_density_max ' + name}: {seconds:.1f} s, {solution.stats['coefficients']} coefficients, "
              f"relative RMSE {figures[f'detail_{name}_rel_rmse']:.4f} (surfaces under {SMALL} m "
              f"{figures[f'detail_{name}_small_rel_rmse']:.4f}, their error estimate {figures[f'detail_{name}_small_estimate_ratio']:.2f}x "
              f"the measured)", flush=True)
    return figures


if __name__ == "__main__":
    for key, value in run().items():
        print(key, value)
