"""The solve on Ray (bsgi.RayExecutor) against the local solve, on a core-only scene of many boxes
on a floor under one light (issue 16's boxes scene; the furnished 1,000-object interior it names
does not exist yet): ray_2workers_speedup is 1 single-threaded worker's time over 2 single-threaded
workers', ray_overhead_fraction 2 workers' time over the local solve on 2 threads, minus 1. Ray runs
locally (ray.init(num_cpus=2)); worker start-up (process, scene, BVH) counts in its times.
ray_cpu_overhead_fraction compares CPU time (the driver's and the workers' processes) instead.
ray_bounce_mb is what one bounce puts into the object store (the increment L of all receivers,
float64), which a cluster sends once to each machine; the workers send as much back.

    .venv/bin/python bench/bench_ray.py [--boxes N] [--preset NAME]
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import bsgi


def boxes_scene(boxes: int, seed: int = 1) -> bsgi.Scene:
    """`boxes` boxes of 0.2-0.6 m (5 quads each, no bottom) scattered on a 20 m floor under a
    square lamp: 5 * boxes + 1 receiving surfaces."""
    rng = np.random.default_rng(seed)
    scene = bsgi.Scene()
    f = 10.0
    scene.add_bilinear_patch("floor", np.array([[-f, -f, 0], [f, -f, 0], [f, f, 0], [-f, f, 0]]), albedo=[0.6] * 3,
                             emission=[0] * 3)
    scene.add_bilinear_patch("lamp", np.array([[-2, -2, 6], [-2, 2, 6], [2, 2, 6], [2, -2, 6]]), albedo=[0] * 3,
                             emission=[20] * 3, receiver=False, occluder=False)
    for b in range(boxes):
        x, y = rng.uniform(-f + 1, f - 1, 2)
        w, d, h = rng.uniform(0.2, 0.6, 3)
        albedo = list(rng.uniform(0.3, 0.8, 3))
        x0, x1, y0, y1 = x - w / 2, x + w / 2, y - d / 2, y + d / 2
        faces = {
            "top": [[x0, y0, h], [x1, y0, h], [x1, y1, h], [x0, y1, h]],
            "south": [[x0, y0, 0], [x1, y0, 0], [x1, y0, h], [x0, y0, h]],
            "north": [[x1, y1, 0], [x0, y1, 0], [x0, y1, h], [x1, y1, h]],
            "west": [[x0, y1, 0], [x0, y0, 0], [x0, y0, h], [x0, y1, h]],
            "east": [[x1, y0, 0], [x1, y1, 0], [x1, y1, h], [x1, y0, h]],
        }
        for name, corners in faces.items():
            scene.add_bilinear_patch(f"box {b} {name}", np.array(corners), albedo=albedo, emission=[0] * 3)
    return scene


def timed(scene, settings, executor=None):
    """Wall-clock seconds, CPU seconds (this process's and the workers') and the solution."""
    start, cpu = time.perf_counter(), time.process_time()
    solution = bsgi.solve(scene, settings, executor=executor)
    cpu = time.process_time() - cpu + (sum(executor.worker_cpu_seconds) if executor else 0)
    return time.perf_counter() - start, cpu, solution


def run(boxes: int = 100, preset: str = "preview") -> dict:
    try:
        import ray
    except ImportError:
        print("  Ray is not installed (pip install ray): skipped")
        return {}
    scene = boxes_scene(boxes)
    settings = bsgi.SolverSettings.preset(preset)
    settings.threads = 2
    local_seconds, local_cpu, local = timed(scene, settings)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        one_seconds, one_cpu, _ = timed(scene, settings, bsgi.RayExecutor(workers=1))
        two = bsgi.RayExecutor(workers=2)
        two_seconds, two_cpu, solution = timed(scene, settings, two)
    finally:
        ray.shutdown()
    same = all(np.array_equal(a.coefficients, b.coefficients)
               for a, b in zip(local.radiance, solution.radiance) if a is not None)
    print(f"  {len(scene)} surfaces ({boxes} boxes), {preset}: local on 2 threads {local_seconds:.1f} s, "
          f"Ray 1 worker {one_seconds:.1f} s, 2 workers {two_seconds:.1f} s (CPU: {local_cpu:.1f}, {one_cpu:.1f}, "
          f"{two_cpu:.1f} s); "
          f"{local.stats['bounces']} bounces; coefficients equal: {same}")
    return {
        "ray_boxes_surfaces": len(scene),
        "ray_local_2threads_seconds": local_seconds,
        "ray_1worker_seconds": one_seconds,
        "ray_2workers_seconds": two_seconds,
        "ray_2workers_speedup": one_seconds / two_seconds,
        "ray_overhead_fraction": two_seconds / local_seconds - 1,
        # The same in CPU time (the driver's and the workers' processes): what Ray costs in work,
        # which the shared machine's load does not blur as it blurs the wall clock.
        "ray_local_cpu_seconds": local_cpu,
        "ray_2workers_cpu_seconds": two_cpu,
        "ray_cpu_overhead_fraction": two_cpu / local_cpu - 1,
        "ray_bounce_mb": two.bytes_sent[1] / 2**20,
        "ray_final_gather_mb": two.bytes_sent[-1] / 2**20 if settings.final_gather else 0.0,
        "ray_equal_to_local": float(same),
    }


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--boxes", type=int, default=100)
    parser.add_argument("--preset", default="preview")
    args = parser.parse_args()
    for key, value in run(args.boxes, args.preset).items():
        print(f"{key}: {value:.6g}")
    sys.exit(0)
