"""Where a Ray solve's time goes, phase by phase: the furnished interior of bench/interior_core.py
solved at the preview preset on a local Ray of this machine's 2 CPUs, printing each phase's wall
seconds, how busy the workers were in it (their groups' seconds over workers x threads x wall),
its groups and its longest group, and the gaps between phases (the driver alone).

    .venv/bin/python bench/ray_phases.py [--objects 1000] [--workers 2] [--threads-per-worker 1]
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

import bsgi
from bsgi import ray_executor

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
    rows, groups, last_end = [], [], [0.0]
    run_phase, learn_costs = ray_executor.RayExecutor.run_phase, ray_executor.RayExecutor.learn_costs

    def timed_phase(self, ray_, progress, phase, coefficients, nodes):
        start = time.perf_counter()
        rows.append(("(driver)", start - last_end[0], None, None, None))
        out = run_phase(self, ray_, progress, phase, coefficients, nodes)
        wall = time.perf_counter() - start
        seconds = [s for *_, s in groups[-1]]
        rows.append((phase, wall, sum(seconds) / (args.workers * wall), len(seconds), max(seconds, default=0.0)))
        last_end[0] = time.perf_counter()
        return out

    def kept_costs(self, measured, nodes):
        groups.append(list(measured))
        return learn_costs(self, measured, nodes)

    ray_executor.RayExecutor.run_phase, ray_executor.RayExecutor.learn_costs = timed_phase, kept_costs
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        start = last_end[0] = time.perf_counter()
        bsgi.solve(scene, settings, executor=bsgi.RayExecutor(workers=args.workers,
                                                              threads_per_worker=args.threads_per_worker))
        total = time.perf_counter() - start
    finally:
        ray.shutdown()
    print(f"{len(scene)} surfaces ({args.objects} objects), {args.workers} workers of "
          f"{args.threads_per_worker} threads: {total:.1f} s")
    for phase, wall, busy, count, longest in rows:
        if busy is None:
            if wall > 0.5:
                print(f"  {phase:16s} {wall:7.1f} s")
        else:
            print(f"  {phase:16s} {wall:7.1f} s  busy {busy:.2f}  {count} groups, longest {longest:.1f} s")


if __name__ == "__main__":
    main()
