"""Small meshes as one UV chart or as one surface per face (issue 16: "a cube, a book become one
surface over their own or generated UVs instead of one per face where that is cheaper"): the
furnished interior of bench/interior_core.py at 100 objects, every box (book, shelf board, table
top, chair part) once as six bilinear patches and once as one bsgi.MeshChart whose UV map lays its
six faces on a 3 x 2 grid of islands (as Blender's cube projection does), at the preview preset.
Figures: time, rays, coefficients and surfaces of each solve (and of the charts with twice
their spatial coefficients per axis), and each one's error against the per-face solve at the
final preset at the same points of every box face (16 random points a
face side, mapped into the face's island for the chart): the median and 90th percentile over the
box sides at least 1% as bright as the scene's mean of the RMS difference over the side's mean,
and the error of all box sides with each weighed by its area.

    python bench/run.py box_charts
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import bsgi

sys.path.insert(0, str(Path(__file__).resolve().parent))
import interior_core  # noqa: E402
import interior_layout  # noqa: E402  (example_blends/, on the path interior_core set)

OBJECTS = 100
POINTS = 16
MARGIN = 0.02  # between a chart's islands, as a UV unwrap leaves one
GRID = (3, 2)  # islands across u and v


def island(face: int) -> tuple:
    """(u0, v0, du, dv): the rectangle of a box's face `face` in its chart's UV square."""
    col, row = face % GRID[0], face // GRID[0]
    du, dv = 1 / GRID[0], 1 / GRID[1]
    return col * du + MARGIN, row * dv + MARGIN, du - 2 * MARGIN, dv - 2 * MARGIN


def box_chart(name: str, quads: list) -> bsgi.MeshChart:
    """The box's six quads (p00, p10, p11, p01 each) as one chart, face f on island(f)."""
    positions, triangles, uvs = [], [], []
    for f, quad in enumerate(quads):
        u0, v0, du, dv = island(f)
        base = len(positions)
        positions.extend(np.asarray(quad, float))
        corner = [(u0, v0), (u0 + du, v0), (u0 + du, v0 + dv), (u0, v0 + dv)]
        for tri in ((0, 1, 2), (0, 2, 3)):
            triangles.append([base + t for t in tri])
            uvs.extend(corner[t] for t in tri)
    return bsgi.MeshChart(name, np.array(positions), np.array(triangles), np.array(uvs))


def build(as_charts: bool) -> tuple:
    """(scene, box faces): the interior with its boxes per face or as charts; per box face
    (its name, the scene index holding it, its island or None)."""
    interior = interior_layout.furnished_interior(OBJECTS)
    scene = bsgi.Scene()
    materials = {name: interior_core._material(name) for name in interior_layout.MATERIALS}
    for k, (material, quad) in enumerate(interior_layout.room_quads(interior)):
        scene.add_bilinear_patch(f"Room {k}", np.array(quad, float), emission=(0, 0, 0), **materials[material])
    faces = []
    for thing in interior.things:
        for p, piece in enumerate(thing.pieces):
            if isinstance(piece, interior_layout.Ball):
                piece = interior_layout.Box(piece.centre, (2 * piece.radius,) * 3, piece.material)
            quads = interior_layout.box_quads(piece)
            if as_charts:
                index = len(scene)
                scene.add_surface(box_chart(f"{thing.name} {p}", quads), emission=(0, 0, 0), **materials[piece.material])
                faces += [(f"{thing.name} {p}.{f}", index, island(f)) for f in range(len(quads))]
            else:
                for f, quad in enumerate(quads):
                    faces.append((f"{thing.name} {p}.{f}", len(scene), None))
                    scene.add_bilinear_patch(f"{thing.name} {p}.{f}", np.array(quad, float), emission=(0, 0, 0),
                                             **materials[piece.material])
    scene.add_distant_light("Sun", np.array(interior.sun_direction), np.full(3, interior_core.SUN_IRRADIANCE),
                            np.radians(0.53))
    scene.world_radiance = np.array(interior_core.SKY_RADIANCE)
    return scene, faces


def face_samples(solution, faces: list) -> dict:
    """{(face name, side): radiance (R + G + B) at POINTS fixed random points of the face (a
    metal face's along its normal) of the box faces, the same face points whether the face is a
    patch or an island."""
    rng = np.random.default_rng(7)
    out = {}
    for name, index, rect in faces:
        uv = rng.uniform(0.02, 0.98, (POINTS, 2))
        surface = solution.surfaces[index]
        if surface is None:
            continue
        if rect is not None:
            u0, v0, du, dv = rect
            uv = np.column_stack([u0 + du * uv[:, 0], v0 + dv * uv[:, 1]])
        for side, part in enumerate((surface.upper, surface.lower)):
            if part is not None:
                out[name, side] = surface.evaluate(uv, np.tile([0, 0, 1.0 - 2 * side], (POINTS, 1))).sum(axis=1)
    return out


def solve(scene, preset: str) -> tuple:
    settings = bsgi.SolverSettings.preset(preset)
    start = time.perf_counter()
    solution = bsgi.solve(scene, settings)
    return solution, time.perf_counter() - start


def errors(samples: dict, reference: dict, area: dict) -> tuple:
    """(median, 90th percentile, area-weighted) as bench_effort.surface_errors, over the box
    sides both solves have, and how many of the reference's this one lacks."""
    scene_mean = np.mean([r.mean() for r in reference.values()])
    keys = [k for k in reference if k in samples]
    each = [np.sqrt(np.mean((samples[k] - reference[k]) ** 2)) / reference[k].mean() for k in keys
            if reference[k].mean() >= 0.01 * scene_mean]
    a = np.array([area[k[0]] for k in keys])
    squares = np.array([np.mean((samples[k] - reference[k]) ** 2) for k in keys])
    means = np.array([reference[k].mean() for k in keys])
    weighed = np.sqrt((a * squares).sum() / a.sum()) / ((a * means).sum() / a.sum())
    missing = len(reference) - len(keys)
    return float(np.median(each)), float(np.percentile(each, 90)), float(weighed), missing


def run() -> dict:
    per_face, faces = build(False)
    area = {name: per_face.area(index) for name, index, _ in faces}
    reference_solution, _ = solve(per_face, "final")
    reference = face_samples(reference_solution, faces)
    figures, chart_coeffs = {}, {}
    charts_scene, chart_faces = build(True)
    # Per face and as charts at the preset; then the charts with twice the spatial coefficients
    # per axis that the preset gave them, which is where their error meets the per-face solve's.
    runs = (("per_face", per_face, faces, 1), ("charts", charts_scene, chart_faces, 1),
            ("charts_2x", charts_scene, chart_faces, 2))
    for name, scene, where, factor in runs:
        if factor != 1:
            for index in {i for _, i, _ in where}:
                scene.set_spatial_coeffs(index, factor * chart_coeffs[index])
        solution, seconds = solve(scene, "preview")
        if name == "charts":  # each chart's spatial coefficients per axis before the final gather's factor
            receivers = [i for i, r in enumerate(solution.radiance) if r is not None]
            factor_final = bsgi.SolverSettings.preset("preview").final_spatial_factor
            chart_coeffs = {i: max(r["shape"][:2]) // factor_final for i, r in zip(receivers, solution.reports)}
        median, p90, weighed, missing = errors(face_samples(solution, where), reference, area)
        print(f"  {name}: {len(scene)} surfaces, {seconds:.1f} s, {solution.stats['rays'] / 1e6:.1f} M rays, "
              f"{solution.stats['coefficients']} coefficients; box sides' error median {median:.4f}, "
              f"90th percentile {p90:.4f}, area-weighted {weighed:.4f} ({missing} sides live per face are "
              f"not live as charts)")
        figures.update({f"box_charts_{name}_seconds": seconds, f"box_charts_{name}_rays": solution.stats["rays"],
                        f"box_charts_{name}_surfaces": len(scene),
                        f"box_charts_{name}_coefficients": solution.stats["coefficients"],
                        f"box_charts_{name}_error_median": median, f"box_charts_{name}_error_p90": p90,
                        f"box_charts_{name}_area_weighted_error": weighed})
    figures["box_charts_2x_rays_over_per_face"] = figures["box_charts_charts_2x_rays"] / figures["box_charts_per_face_rays"]
    return figures


if __name__ == "__main__":
    for key, value in run().items():
        print(f"{key}: {value:.6g}")
