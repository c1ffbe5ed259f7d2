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
from bsgi.refine import coarse_coeffs, receivers

sys.path.insert(0, str(Path(__file__).resolve().parent))
import interior_core  # noqa: E402
from bench_effort import surface_errors  # noqa: E402

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
    """(scene, box faces): the interior with its boxes per face or as charts; per box face (in
    the same order either way) the scene index holding it and its island (None for a patch)."""
    faces = []

    def add_box(scene, name, quads, material):
        if as_charts:
            faces.extend((len(scene), island(f)) for f in range(len(quads)))
            scene.add_surface(box_chart(name, quads), emission=(0, 0, 0), **material)
        else:
            faces.extend((len(scene) + f, None) for f in range(len(quads)))
            interior_core.add_box_per_face(scene, name, quads, material)

    scene, _ = interior_core.build_scene(OBJECTS, add_box)
    return scene, faces


def face_samples(solution, faces: list) -> dict:
    """{(face, side): radiance (R + G + B) at POINTS fixed random points of box face number
    `face` (a metal face's along its normal), the same face points whether the face is a patch
    or an island; faces numbered as the per-face scene's indices, so that
    bench_effort.surface_errors weighs them by that scene's areas."""
    rng = np.random.default_rng(7)
    out = {}
    first = faces[0][0]  # the per-face scene's index of the first box face (the room's quads before)
    for k, (index, rect) in enumerate(faces):
        uv = rng.uniform(0.02, 0.98, (POINTS, 2))
        surface = solution.surfaces[index]
        if surface is None:
            continue
        if rect is not None:
            u0, v0, du, dv = rect
            uv = np.column_stack([u0 + du * uv[:, 0], v0 + dv * uv[:, 1]])
        for side, part in enumerate((surface.upper, surface.lower)):
            if part is not None:
                out[first + k, side] = surface.evaluate(uv, np.tile([0, 0, 1.0 - 2 * side], (POINTS, 1))).sum(axis=1)
    return out


def solve(scene, preset: str) -> tuple:
    settings = bsgi.SolverSettings.preset(preset)
    start = time.perf_counter()
    solution = bsgi.solve(scene, settings)
    return solution, time.perf_counter() - start


def run() -> dict:
    per_face, faces = build(False)
    reference = face_samples(solve(per_face, "final")[0], faces)
    charts_scene, chart_faces = build(True)
    figures = {}

    def measure(name, scene, where):
        solution, seconds = solve(scene, "preview")
        samples = face_samples(solution, where)
        median, p90, weighed = surface_errors(samples, reference, per_face)
        missing = len(reference.keys() - samples.keys())
        print(f"  {name}: {len(scene)} surfaces, {seconds:.1f} s, {solution.stats['rays'] / 1e6:.1f} M rays, "
              f"{solution.stats['coefficients']} coefficients; box sides' error median {median:.4f}, "
              f"90th percentile {p90:.4f}, area-weighted {weighed:.4f} ({missing} sides live per face are "
              f"not live as charts)")
        figures.update({f"box_charts_{name}_seconds": seconds, f"box_charts_{name}_rays": solution.stats["rays"],
                        f"box_charts_{name}_surfaces": len(scene),
                        f"box_charts_{name}_coefficients": solution.stats["coefficients"],
                        f"box_charts_{name}_error_median": median, f"box_charts_{name}_error_p90": p90,
                        f"box_charts_{name}_area_weighted_error": weighed})
        return solution

    measure("per_face", per_face, faces)
    charts = measure("charts", charts_scene, chart_faces)
    # Then the charts with twice the spatial coefficients per axis the preset gave them, which is
    # where their error meets the per-face solve's.
    preview = bsgi.SolverSettings.preset("preview")
    coarse = dict(zip(receivers(charts), (coarse_coeffs(r, preview) for r in charts.reports)))
    for index in {i for i, _ in chart_faces}:
        charts_scene.set_spatial_coeffs(index, 2 * coarse[index])
    measure("charts_2x", charts_scene, chart_faces)
    figures["box_charts_2x_rays_over_per_face"] = figures["box_charts_charts_2x_rays"] / figures["box_charts_per_face_rays"]
    return figures


if __name__ == "__main__":
    for key, value in run().items():
        print(f"{key}: {value:.6g}")
