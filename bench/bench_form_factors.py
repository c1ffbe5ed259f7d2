"""When the generalized form factors (36)-(37) pay: the diffuse Cornell box solved with the rays
cast every bounce and with the transport operator assembled once, for a few bounces and many."""
from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import bsgi  # noqa: E402
from reference import scene_spec  # noqa: E402


def run() -> dict:
    scene = scene_spec.to_bsgi(scene_spec.cornell_box())
    out = {}
    for bounces in (2, 8, 32):
        times = {}
        for form_factors in (False, True):
            settings = bsgi.SolverSettings()
            settings.max_bounces = bounces
            settings.tolerance = 0
            settings.form_factors = form_factors
            start = time.perf_counter()
            solution = bsgi.solve(scene, settings)
            times[form_factors] = time.perf_counter() - start
            if form_factors:
                out["ff_transport_mb"] = round(solution.stats["transport_terms"] * 12 / 2**20, 1)
        out[f"ff_{bounces}_bounces_rays_seconds"] = round(times[False], 3)
        out[f"ff_{bounces}_bounces_operator_seconds"] = round(times[True], 3)
        out[f"ff_{bounces}_bounces_speedup"] = round(times[False] / times[True], 2)
    return out
