"""Scale (issue 16): the furnished interior (bench/interior_core.py) solved at the preview preset
with the core API, each size in a process of its own: wall time, the process's peak resident
memory, the solve's own memory estimate before it starts (bsgi.estimate_solve_bytes), and the
growth exponent of time and memory between sizes. 100 and 1,000 objects by default;
BSGI_BENCH_SCALE=100,1000,10000 sets the sizes (10,000 objects: about 10 minutes). With
BSGI_BENCH_SCALE_OVERRIDES='{"coeffs_from_size": false, "detail_tolerance": 0}' (the preset's
coefficients on every surface, over the 4 GB budget at 10,000 objects: add "memory_budget_mb") the
preset's settings are changed and the keys are scale_custom_<objects>_* (scale_custom_overrides
says how).
Each row also gives the phases' seconds (the error estimate's among them), the sides probe's
(once, for the memory estimate and the solve) and the memory estimate's own seconds.

    python bench/run.py scale
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SIZES = [int(n) for n in os.environ.get("BSGI_BENCH_SCALE", "100,1000").split(",")]
OVERRIDES = os.environ.get("BSGI_BENCH_SCALE_OVERRIDES", "")


def measure(objects: int) -> dict:
    """In this process (a fresh one): build, estimate, solve."""
    import resource
    import time

    sys.path.insert(0, str(HERE))
    import interior_core

    import bsgi

    settings = bsgi.SolverSettings.preset("preview")
    for name, value in (json.loads(OVERRIDES) if OVERRIDES else {}).items():
        setattr(settings, name, value)
    start = time.perf_counter()
    scene, _ = interior_core.build_scene(objects)
    probing = time.perf_counter()
    sides = bsgi.probe_sides(scene, settings)[0]  # once, for the estimate and the solve
    estimating = time.perf_counter()
    estimate = bsgi.estimate_solve_bytes(scene, settings, sides)
    solving = time.perf_counter()
    solution = bsgi.solve(scene, settings, sides=sides)
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    stats = solution.stats
    return {"objects": objects, "surfaces": len(scene), "seconds": seconds, "peak_mb": peak,
            "estimate_mb": estimate / 2**20, "coefficients": stats["coefficients"], "rays": stats["rays"],
            "bounces": stats["bounces"], "probe_seconds": estimating - probing, "estimate_seconds": solving - estimating,
            **{k: stats[k] for k in ("seconds_direct", "seconds_indirect", "seconds_final", "seconds_estimate")}}


def run() -> dict:
    prefix = "scale_custom" if OVERRIDES else "scale"
    figures, rows = ({"scale_custom_overrides": OVERRIDES} if OVERRIDES else {}), []
    for objects in SIZES:
        out = subprocess.run([sys.executable, __file__, "--one", str(objects)], capture_output=True, text=True, check=True)
        row = json.loads(out.stdout.strip().splitlines()[-1])
        rows.append(row)
        print(f"  {objects} objects, {row['surfaces']} surfaces: {row['seconds']:.1f} s (sides probe {row['probe_seconds']:.1f} s, estimate {row['estimate_seconds']:.1f} s, "
              f"direct {row['seconds_direct']:.1f} s, {row['bounces']} bounces {row['seconds_indirect']:.1f} s, final "
              f"{row['seconds_final']:.1f} s, error estimate {row['seconds_estimate']:.1f} s), peak {row['peak_mb']:.0f} MB, estimate {row['estimate_mb']:.0f} MB", flush=True)
        figures[f"{prefix}_{objects}_seconds"] = row["seconds"]
        figures[f"{prefix}_{objects}_peak_mb"] = row["peak_mb"]
        figures[f"{prefix}_{objects}_estimate_mb"] = row["estimate_mb"]
        figures[f"{prefix}_{objects}_surfaces"] = row["surfaces"]
        figures[f"{prefix}_{objects}_rays_per_surface"] = row["rays"] / row["surfaces"]
    for a, b in zip(rows, rows[1:]):
        ratio = math.log(b["objects"] / a["objects"])
        figures[f"{prefix}_growth_exponent_{a['objects']}_{b['objects']}"] = math.log(b["seconds"] / a["seconds"]) / ratio
    return figures


if __name__ == "__main__":
    if sys.argv[1:2] == ["--one"]:
        print(json.dumps(measure(int(sys.argv[2]))))
    else:
        print(json.dumps(run(), indent=2))
