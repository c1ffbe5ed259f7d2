"""Where a Ray solve's time goes, phase by phase: the furnished interior of bench/interior_core.py
solved at the preview preset on a local Ray of this machine's 2 CPUs, printing each phase's wall
seconds, how busy the workers were in it (their groups' seconds over workers x wall),
its groups and its longest group, and the gaps between phases (the driver alone).

    .venv/bin/python bench/ray_phases.py [--objects 1000] [--workers 2] [--threads-per-worker 1]
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

import bsgi

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import interior_core  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--threads-per-worker", type=int, default=1)
    args = parser.parse_args()
    import ray

    scene, _ = interior_core.build_scene(args.objects)
    settings = bsgi.SolverSettings.preset("preview")
    settings.threads = 2
    executor = bsgi.RayExecutor(workers=args.workers, threads_per_worker=args.threads_per_worker)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        start = time.perf_counter()
        bsgi.solve(scene, settings, executor=executor)
        total = time.perf_counter() - start
    finally:
        ray.shutdown()
    print(f"{len(scene)} surfaces ({args.objects} objects), {args.workers} workers of "
          f"{args.threads_per_worker} threads: {total:.1f} s")
    driver_since = start
    for phase, began, ended, seconds in executor.phase_times:
        if began - driver_since > 0.5:
            print(f"  {'(driver)':16s} {began - driver_since:7.1f} s")
        wall = ended - began
        print(f"  {phase:16s} {wall:7.1f} s  busy {sum(seconds) / (args.workers * wall):.2f}  "
              f"{len(seconds)} groups, longest {max(seconds, default=0.0):.1f} s")
        driver_since = ended


if __name__ == "__main__":
    main()
