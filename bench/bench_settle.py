"""Settled receivers (SolverSettings.settle_factor, issue 16): the furnished interior
(bench/interior_core.py) at the preview preset solved with every receiver gathering every bounce
and with settled receivers stopping, one after the other in this process: the bounces' seconds,
rays and bounces of each and the nodes that did not gather. Both are compared with the same
solve converged ten times further (tolerance / 10, every receiver gathering), spline by spline:
the largest difference relative to the spline's own largest coefficient (median, 99th
percentile, worst) and the largest shift of a surface's mean, so that settling is judged by the
error it adds to the preset's own convergence error.
BSGI_BENCH_SETTLE_OBJECTS sets the objects (10 by default: three solves take about 3 minutes).

    python bench/run.py settle
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OBJECTS = int(os.environ.get("BSGI_BENCH_SETTLE_OBJECTS", "10"))


def splines(solution):
    for k, surface in enumerate(solution.surfaces):
        if surface is None:
            continue
        for part in (surface.upper, surface.lower, surface.diffuse, surface.lower_diffuse):
            if part is not None:
                yield k, np.asarray(part.coefficients)


def run() -> dict:
    sys.path.insert(0, str(HERE))
    import interior_core

    import bsgi

    scene, _ = interior_core.build_scene(OBJECTS)
    base = bsgi.SolverSettings.preset("preview")
    sides = bsgi.probe_sides(scene, base)[0]
    solves = {}
    for name, factor, tighter in (("all", 0.0, 1), ("settle", base.settle_factor or 0.5, 1), ("converged", 0.0, 10)):
        settings = bsgi.SolverSettings.preset("preview")
        settings.settle_factor = factor
        settings.tolerance /= tighter
        start = time.perf_counter()
        solves[name] = (bsgi.solve(scene, settings, sides=sides), time.perf_counter() - start, factor)
    (full, full_seconds, _), (settled, settled_seconds, factor) = solves["all"], solves["settle"]
    a, b = full.stats, settled.stats
    figures = {}
    for name, solution in (("all", full), ("settle", settled)):
        diffs, shifts = [], []
        for (k, x), (_, y) in zip(splines(solves["converged"][0]), splines(solution)):
            scale = np.abs(x).max()
            if scale > 0:
                diffs.append(np.abs(y - x).max() / scale)
            if abs(x.mean()) > 0:
                shifts.append(abs(y.mean() / x.mean() - 1))
        diffs = np.array(diffs)
        print(f"  {name} against converged, difference per spline (of its largest): median {np.median(diffs):.2e}, 99th "
              f"percentile {np.percentile(diffs, 99):.2e}, worst {diffs.max():.2e}; largest mean shift {max(shifts):.2e}", flush=True)
        figures.update({f"settle_{name}_diff_median": float(np.median(diffs)), f"settle_{name}_diff_p99": float(np.percentile(diffs, 99)),
                        f"settle_{name}_diff_worst": float(diffs.max()), f"settle_{name}_mean_shift_worst": float(max(shifts))})
    print(f"  {OBJECTS} objects, {len(scene)} surfaces, settle_factor {factor}: bounces {a['bounces']} -> {b['bounces']} "
          f"(converged: {solves['converged'][0].stats['bounces']}), their seconds {a['seconds_indirect']:.1f} -> "
          f"{b['seconds_indirect']:.1f}, total {full_seconds:.1f} -> {settled_seconds:.1f} s, rays {a['rays']} -> {b['rays']}, "
          f"{b['settled_nodes']} nodes settled over the bounces", flush=True)
    return {**figures,
        "settle_interior_objects": OBJECTS,
        "settle_bounce_seconds_ratio": b["seconds_indirect"] / a["seconds_indirect"],
        "settle_seconds_ratio": settled_seconds / full_seconds,
        "settle_rays_ratio": b["rays"] / a["rays"],
        "settle_bounces_all": a["bounces"],
        "settle_bounces_settled": b["bounces"],
    }


if __name__ == "__main__":
    for key, value in run().items():
        print(f"{key}: {value}")
