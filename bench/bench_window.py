"""A room lit through a window, with and without a pane of glass in it (issue 18): the solve's
time and peak memory at the preview preset (each in a fresh process), and the room lit through
the pane against Mitsuba 3's thindielectric.

The sun (a delta direction) cannot be reached by Mitsuba's path tracer through a delta BSDF, so
the Mitsuba comparison lights the same room through the window by an area light outside it."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from reference import mitsuba_reference, scene_spec  # noqa: E402
from reference.scene_spec import quad  # noqa: E402

ETA = 1.5
SUN = np.array([math.cos(math.radians(35)), 0.2, math.sin(math.radians(35))])
SUN_IRRADIANCE = [4.0, 3.6, 3.0]


def window_room(pane, lamp: bool = False) -> scene_spec.SceneSpec:
    """A 4 x 4 x 2.5 room (faces inwards), a 1.2 x 1 window in its +x wall, a pane of glass in
    it (pane "solid": the rough dielectric of roughness 0.2 that smooth glass was solved as
    before); with `lamp` an area light outside facing the window."""
    spec = scene_spec.SceneSpec()
    white, floor = (0.7,) * 3, (0.5, 0.45, 0.4)
    spec.add("floor", quad([0, 0, 0], [2, 0, 0], [0, 2, 0]), floor)
    spec.add("ceiling", quad([0, 0, 2.5], [0, 2, 0], [2, 0, 0]), white)
    spec.add("wall -x", quad([-2, 0, 1.25], [0, 2, 0], [0, 0, 1.25]), white)
    spec.add("wall -y", quad([0, -2, 1.25], [0, 0, 1.25], [2, 0, 0]), white)
    spec.add("wall +y", quad([0, 2, 1.25], [2, 0, 0], [0, 0, 1.25]), white)
    y0, y1, z0, z1 = -0.6, 0.6, 0.8, 1.8  # the opening in the +x wall (facing -x)
    for name, (ya, yb, za, zb) in {"below": (-2, 2, 0, z0), "above": (-2, 2, z1, 2.5),
                                   "left": (-2, y0, z0, z1), "right": (y1, 2, z0, z1)}.items():
        spec.add(f"wall +x {name}", quad([2, (ya + yb) / 2, (za + zb) / 2], [0, 0, (zb - za) / 2],
                                         [0, (yb - ya) / 2, 0]), white)
    opening = quad([2, 0, (z0 + z1) / 2], [0, 0, (z1 - z0) / 2], [0, (y1 - y0) / 2, 0])
    if pane == "solid":
        spec.add("pane", opening, dielectric=(ETA, 0.2**2))
    elif pane:
        spec.add("pane", opening, receiver=False, thin_glass=ETA)
    if lamp:
        # 1.5 m outside, higher than the window, facing it: its light falls into the room.
        spec.add("sky panel", quad([3.5, 0, 2.8], [0, 0, 1.0], [0, 1.0, 0]), emission=(5.0, 4.5, 4.0), receiver=False)
    return spec


def scene(pane: bool):
    s = scene_spec.to_bsgi(window_room(pane))
    s.add_distant_light("sun", SUN, SUN_IRRADIANCE, math.radians(0.53))
    return s


def solve_once(pane) -> dict:
    """One preview solve in this process: wall time, the solve's memory estimate, peak RSS."""
    import resource
    import time

    import bsgi

    s = scene(pane)
    t0 = time.perf_counter()
    solution = bsgi.solve(s, bsgi.SolverSettings.preset("preview"))
    seconds = time.perf_counter() - t0
    return {"seconds": seconds, "bytes": solution.stats["bytes"],
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def _in_subprocess(pane) -> dict:
    arg = {True: "pane", False: "no-pane", "solid": "solid"}[pane]
    out = subprocess.run([sys.executable, __file__, "--solve", arg], check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def error_vs_mitsuba() -> tuple:
    """Floor points of the room lit through the pane by the panel outside: the relative error of
    the mean radiance and the NRMSE against Mitsuba's path tracer (full global illumination)."""
    import bsgi

    spec = window_room(pane=True, lamp=True)
    rng = np.random.default_rng(2)
    xy = rng.uniform(-1.9, 1.9, (300, 2))
    points = np.column_stack([xy, np.zeros(len(xy))])
    eye = points + np.array([-0.1, 0.05, 0.5])
    reference = mitsuba_reference.to_mitsuba(spec)
    ref, stderr = mitsuba_reference.radiance_along(reference, eye, points, spp=1 << 16, seed=5)
    s = scene_spec.to_bsgi(spec)
    sol = bsgi.solve(s, bsgi.SolverSettings.preset("preview"))
    ours = sol.radiance[0].evaluate((xy + 2) / 4)
    mean_err = ours.sum() / ref.sum() - 1
    nrmse = math.sqrt(((ours - ref) ** 2).sum() / (ref**2).sum())
    noise = math.sqrt((stderr**2).sum() / (ref**2).sum())
    return mean_err, nrmse, noise


def run() -> dict:
    with_pane, without, solid = _in_subprocess(True), _in_subprocess(False), _in_subprocess("solid")
    mean_err, nrmse, noise = error_vs_mitsuba()
    return {
        "window_solid_pane_seconds": solid["seconds"],
        "window_solid_pane_peak_mb": solid["peak_mb"],
        "window_pane_seconds": with_pane["seconds"],
        "window_no_pane_seconds": without["seconds"],
        "window_pane_peak_mb": with_pane["peak_mb"],
        "window_no_pane_peak_mb": without["peak_mb"],
        "window_pane_estimate_mb": with_pane["bytes"] / 2**20,
        "window_no_pane_estimate_mb": without["bytes"] / 2**20,
        "window_pane_rel_err_vs_mitsuba": mean_err,
        "window_pane_nrmse_vs_mitsuba": nrmse,
        "window_pane_mitsuba_noise": noise,
    }


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--solve":
        print(json.dumps(solve_once({"pane": True, "no-pane": False, "solid": "solid"}[sys.argv[2]])))
    else:
        for key, value in run().items():
            print(f"{key}: {value:.4g}")
