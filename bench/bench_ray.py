"""The solve on Ray (bsgi.RayExecutor) against the local solve, on issue 16's scene: the furnished
interior of bench/interior_core.py at 1,000 objects (BSGI_BENCH_RAY_OBJECTS or --objects sets
another count; 1,000 take about 40 minutes: the local solve, then 1 worker, then 2).
ray_2workers_speedup is 1 single-threaded worker's time over 2 single-threaded workers',
ray_overhead_fraction 2 workers' time over the local solve on 2 threads, minus 1. Ray runs
locally (ray.init(num_cpus=2)); worker start-up (process, scene, BVH) counts in its times.
ray_cpu_overhead_fraction compares CPU time (the driver's and the workers' processes) instead.
ray_bounce_mb is what one bounce puts into the object store (the increment L of all receivers,
float64), which a cluster sends once to each machine; the workers send as much back.
ray_final_gather_mb, ray_regather_mb and ray_estimate_mb: the same for the final gather (the
coarse Le), a regather (the finals' Le and the coarse Le) and the error estimate's input pass
(those, each surface's input scale and the checks pass's records).
The sides probe runs on the workers too, in parts (bsgi.SidesProbe): ray_probe_seconds is its
wall time on 2 workers, ray_probe_rounds its rounds of settling, ray_probe_mb the lit cells it
puts into the object store in all (a bit a cell of every surface side, once a round).

    .venv/bin/python bench/bench_ray.py [--objects N] [--preset NAME]
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np

import bsgi

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import interior_core  # noqa: E402

OBJECTS = int(os.environ.get("BSGI_BENCH_RAY_OBJECTS", "1000"))


def timed(scene, settings, executor=None):
    """Wall-clock seconds, CPU seconds (this process's and the workers') and the solution."""
    start, cpu = time.perf_counter(), time.process_time()
    solution = bsgi.solve(scene, settings, executor=executor)
    cpu = time.process_time() - cpu + (sum(executor.worker_cpu_seconds) if executor else 0)
    return time.perf_counter() - start, cpu, solution


def run(objects: int = OBJECTS, preset: str = "preview") -> dict:
    try:
        import ray
    except ImportError:
        print("  Ray is not installed (pip install ray): skipped")
        return {}
    scene, _ = interior_core.build_scene(objects)
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
    print(f"  {len(scene)} surfaces ({objects} objects), {preset}: local on 2 threads {local_seconds:.1f} s, "
          f"Ray 1 worker {one_seconds:.1f} s, 2 workers {two_seconds:.1f} s (CPU: {local_cpu:.1f}, {one_cpu:.1f}, "
          f"{two_cpu:.1f} s); "
          f"{local.stats['bounces']} bounces; coefficients equal: {same}; the driver's error estimate "
          f"{solution.stats['seconds_estimate']:.1f} s of the 2 workers' solve")
    bounces = solution.stats["bounces"]
    return {
        "ray_objects": objects,
        "ray_surfaces": len(scene),
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
        # Phases in order: the direct light, the bounces, the final gather and its regathers, the
        # error estimate's two passes (see bsgi.SolveSteps).
        "ray_final_gather_mb": two.bytes_sent[1 + bounces] / 2**20 if settings.final_gather else 0.0,
        "ray_regather_mb": two.bytes_sent[2 + bounces] / 2**20 if settings.final_passes > 1 else 0.0,
        "ray_estimate_mb": two.bytes_sent[-1] / 2**20 if settings.estimate_error else 0.0,
        "ray_probe_seconds": next(ended - began for phase, began, ended, _ in two.phase_times if phase == "probing sides"),
        "ray_probe_rounds": two.probe_rounds,
        "ray_probe_mb": two.probe_bytes / 2**20,
        "ray_equal_to_local": float(same),
        "ray_2workers_estimate_seconds": solution.stats["seconds_estimate"],
    }


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=OBJECTS)
    parser.add_argument("--preset", default="preview")
    args = parser.parse_args()
    for key, value in run(args.objects, args.preset).items():
        print(f"{key}: {value:.6g}")
    sys.exit(0)
