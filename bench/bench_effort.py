"""Effort where the light needs it (issue 16, item 1): the issue's scene of boxes (five 0.4 m
quads each) scattered on a 20 m floor under one square light, solved at the preview preset with
the core API, with spatial coefficients from each surface's size and its light's detail
(coeffs_from_size, detail_tolerance; on in the preset) against the same preset with them off,
12 x 12 everywhere. Figures: time, rays of the whole solve, and rays per box face, i.e. the
solve's rays less those of the floor and light alone, over the box faces. The same for the furnished interior of bench/interior_core.py
at 100 objects (books on shelves, a table, chairs; a sun and a sky): time and rays per surface,
and each solve's error per surface against the final preset's solve (no path tracer reaches a
core-only scene): the median and 90th percentile, over the diffuse sides at least 1% as bright
as the scene's mean, of the RMS difference at 16 random points over the side's mean, and the
scene's error with each side weighed by its area.

    python bench/run.py effort
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import bsgi

BOXES = 40
INTERIOR_OBJECTS = 100
FLOOR = 20.0
BOX = 0.4
ADAPTIVE = {"coeffs_from_size": True, "detail_tolerance": 0.005}  # the preview preset
UNIFORM = {"coeffs_from_size": False, "detail_tolerance": 0.0}  # the preset with them off (12 x 12 everywhere)


def boxes_scene(boxes: int, seed: int = 1) -> bsgi.Scene:
    """A 20 m floor, `boxes` 0.4 m boxes (no bottom face) at random places on it, and a 1 m
    square light 5 m above the floor's centre, facing down."""
    scene = bsgi.Scene()
    h = FLOOR / 2
    scene.add_bilinear_patch("Floor", np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], float),
                             albedo=(0.5, 0.5, 0.5), emission=(0, 0, 0))
    scene.add_bilinear_patch("Light", np.array([[-0.5, -0.5, 5], [-0.5, 0.5, 5], [0.5, 0.5, 5], [0.5, -0.5, 5]], float),
                             albedo=(0, 0, 0), emission=(30, 30, 30), receiver=False)
    rng = np.random.default_rng(seed)
    for k, (x, y) in enumerate(rng.uniform(-h + 1, h - 1, size=(boxes, 2))):
        for f, quad in enumerate(box_quads((x, y), BOX)):
            scene.add_bilinear_patch(f"Box {k}.{f}", quad, albedo=(0.7, 0.6, 0.4), emission=(0, 0, 0))
    return scene


def box_quads(centre, size):
    """The top and four sides of a box standing on z = 0, outward, counter-clockwise."""
    x, y = centre
    s = size / 2
    c = [np.array([x + dx, y + dy, z]) for z in (0, size) for dx, dy in ((-s, -s), (s, -s), (s, s), (-s, s))]
    quads = [[c[4], c[5], c[6], c[7]]]
    for i in range(4):
        j = (i + 1) % 4
        quads.append([c[i], c[j], c[4 + j], c[4 + i]])
    return [np.array(q, float) for q in quads]


def solve(scene, overrides: dict, preset: str = "preview") -> dict:
    settings = bsgi.SolverSettings.preset(preset)
    for name, value in overrides.items():
        setattr(settings, name, value)
    start = time.perf_counter()
    solution = bsgi.solve(scene, settings)
    return {"seconds": time.perf_counter() - start, "rays": solution.stats["rays"],
            "coefficients": solution.stats["coefficients"], "samples": diffuse_samples(solution)}


def diffuse_samples(solution, points: int = 16) -> dict:
    """{(surface, side): radiance (R + G + B) at `points` fixed random points} of the diffuse sides."""
    rng = np.random.default_rng(7)
    out = {}
    for i, (surface, report) in enumerate(zip(solution.surfaces, solution.reports)):
        uv = rng.uniform(0.02, 0.98, (points, 2))  # for every surface: the same points in every solve
        if surface is None or not report["representation"].startswith("diffuse"):
            continue
        for side, part in enumerate((surface.upper, surface.lower)):
            if part is not None:
                out[i, side] = surface.evaluate(uv, np.tile([0, 0, 1.0 - 2 * side], (points, 1))).sum(axis=1)
    return out


def surface_errors(samples: dict, reference: dict, scene) -> tuple:
    """(median, 90th percentile) over the sides at least 1% as bright as the mean of the
    reference's: the RMS difference from the reference over its mean; and over the whole scene,
    each side weighed by its area (what random points of it see), the RMS difference over the
    mean radiance."""
    scene_mean = np.mean([r.mean() for r in reference.values()])
    errors = [np.sqrt(np.mean((samples[k] - r) ** 2)) / r.mean() for k, r in reference.items()
              if k in samples and r.mean() >= 0.01 * scene_mean]
    sides = [k for k in reference if k in samples]
    area = np.array([scene.area(k[0]) for k in sides])
    squares = np.array([np.mean((samples[k] - reference[k]) ** 2) for k in sides])
    means = np.array([reference[k].mean() for k in sides])
    weighed = np.sqrt((area * squares).sum() / area.sum()) / ((area * means).sum() / area.sum())
    return float(np.median(errors)), float(np.percentile(errors, 90)), float(weighed)


def run() -> dict:
    figures = {}
    for name, overrides in (("uniform", UNIFORM), ("adaptive", ADAPTIVE)):
        alone = solve(boxes_scene(0), overrides)
        full = solve(boxes_scene(BOXES), overrides)
        per_face = (full["rays"] - alone["rays"]) / (5 * BOXES)
        figures.update({f"effort_boxes_{name}_seconds": full["seconds"], f"effort_boxes_{name}_rays": full["rays"],
                        f"effort_boxes_{name}_rays_per_box_face": per_face,
                        f"effort_boxes_{name}_floor_rays": alone["rays"]})
    figures["effort_boxes_rays_per_box_face_reduction"] = (figures["effort_boxes_uniform_rays_per_box_face"] /
                                                          figures["effort_boxes_adaptive_rays_per_box_face"])
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import interior_core

    scene, _ = interior_core.build_scene(INTERIOR_OBJECTS)
    reference = solve(scene, {}, "final")["samples"]
    for name, overrides in (("uniform", UNIFORM), ("adaptive", ADAPTIVE)):
        solved = solve(scene, overrides)
        median, p90, weighed = surface_errors(solved["samples"], reference, scene)
        figures.update({f"effort_interior_{INTERIOR_OBJECTS}_{name}_seconds": solved["seconds"],
                        f"effort_interior_{INTERIOR_OBJECTS}_{name}_rays_per_surface": solved["rays"] / len(scene),
                        f"effort_interior_{INTERIOR_OBJECTS}_{name}_coefficients": solved["coefficients"],
                        f"effort_interior_{INTERIOR_OBJECTS}_{name}_surface_error_median": median,
                        f"effort_interior_{INTERIOR_OBJECTS}_{name}_surface_error_p90": p90,
                        f"effort_interior_{INTERIOR_OBJECTS}_{name}_area_weighted_error": weighed})
    return figures


if __name__ == "__main__":
    for key, value in run().items():
        print(f"{key}: {value:.6g}")
