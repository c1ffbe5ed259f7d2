"""Memory that fits (issue 16): the furnished interior of bench/interior_core.py at 50,000 objects
(BSGI_BENCH_MEMORY_OBJECTS sets another count), without solving it: the resident memory of the
core scene built from Python, of the ray caster (Embree's BVH and the per-triangle records), and
the solve's own estimate (bsgi.estimate_solve_bytes) at the preview preset, as is and with
coeffs_from_size (small faces fewer coefficients), with and without the final gather, and with
coeffs_from_size and detail_tolerance 0.005 as the scale benchmark solves. The
estimates are of front sides only (two_sided off): the sides probe of every surface's both sides
would take about half an hour at this size (and hold about 3.7 GB, 12 GB before 5 December's
compact records); its own memory is the
`memory_probe_bytes_per_surface` figure, measured
at 100 objects by the probe's own count (bsgi.probe_sides), and that times this size's surfaces.
In a process of its own.

    python bench/run.py memory
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
OBJECTS = int(os.environ.get("BSGI_BENCH_MEMORY_OBJECTS", "50000"))


def _resident_mb() -> float:
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def measure(objects: int) -> dict:
    sys.path.insert(0, str(HERE))
    import interior_core

    import bsgi

    start = _resident_mb()
    scene, _ = interior_core.build_scene(objects)
    built = _resident_mb()
    caster = bsgi.RayCaster([scene.surface(i) for i in range(len(scene))])
    with_caster = _resident_mb()
    figures = {f"memory_{objects}_surfaces": len(scene), f"memory_{objects}_scene_mb": built - start,
               f"memory_{objects}_ray_caster_mb": with_caster - built,
               f"memory_{objects}_triangles": caster.triangle_count}
    del caster
    for label, changes in [("preview", {}), ("preview_coeffs_from_size", {"coeffs_from_size": True}),
                           ("preview_coeffs_from_size_no_final_gather", {"coeffs_from_size": True, "final_gather": False}),
                           # as the scale benchmark solves (the estimate bounds the light's detail by detail_density_max)
                           ("preview_detail", {"coeffs_from_size": True, "detail_tolerance": 0.005})]:
        settings = bsgi.SolverSettings.preset("preview")
        settings.two_sided = False
        for key, value in changes.items():
            setattr(settings, key, value)
        figures[f"memory_{objects}_estimate_{label}_mb"] = bsgi.estimate_solve_bytes(scene, settings) / 2**20
    # The sides probe's peak a surface, its own count at 100 objects (bsgi.probe_sides), and what
    # that makes at this size.
    small, _ = interior_core.build_scene(100)
    per_surface = bsgi.probe_sides(small, bsgi.SolverSettings.preset("draft"))[1] / len(small)
    figures["memory_probe_bytes_per_surface"] = per_surface
    figures[f"memory_{objects}_probe_mb_extrapolated"] = per_surface * len(scene) / 2**20
    return figures


def run() -> dict:
    out = subprocess.run([sys.executable, __file__, "--one", str(OBJECTS)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    if sys.argv[1:2] == ["--one"]:
        print(json.dumps(measure(int(sys.argv[2]))))
    else:
        print(json.dumps(run(), indent=2))
