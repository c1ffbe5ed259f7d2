"""Issue 16, memory that fits: the solve's own estimate before it starts
(bsgi.estimate_solve_bytes) against the peak resident memory the solve adds, measured by the
kernel (VmHWM after clearing it, minus the resident memory just before the solve), on the furnished
interior of bench/interior_core.py at three sizes, each in a fresh process.

The draft preset with one bounce keeps the three solves under a minute or so on the shared
machine; the bounces do not change what is allocated (the same receivers, packed copies and
final receivers), only how long the solve takes. The preview preset adds a regather (its
correction held in float32 beside the finals) and larger scatter tables."""
from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]

MEASURE = r"""
import ctypes, json, sys
sys.path.insert(0, sys.argv[2])
import interior_core, bsgi

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key + ":"):
            return int(line.split()[1]) * 1024

scene, _ = interior_core.build_scene(int(sys.argv[1]))
settings = bsgi.SolverSettings.preset(sys.argv[4])
settings.max_bounces = 1
settings.two_sided = sys.argv[3] == "two-sided"
estimate = bsgi.estimate_solve_bytes(scene, settings)
ctypes.CDLL("libc.so.6").malloc_trim(0)  # what the estimate's own probe freed goes back
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")  # resets VmHWM to the current resident memory
before = status("VmRSS")
bsgi.solve(scene, settings)
print(json.dumps({"estimate": estimate, "added": status("VmHWM") - before, "surfaces": len(scene)}))
"""


def _measure(objects: int, sides: str, preset: str = "draft") -> dict:
    out = subprocess.run([sys.executable, "-c", MEASURE, str(objects), str(ROOT / "bench"), sides, preset],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.skipif(not pathlib.Path("/proc/self/clear_refs").exists(), reason="needs Linux's VmHWM reset")
@pytest.mark.parametrize("sides", ["two-sided", "front-only"])
def test_estimate_within_25_percent_of_measured_peak_at_three_sizes(sides):
    # Measured 2026-12-05 at 10, 30, 100 objects (243, 363, 819 surfaces), estimate / added peak,
    # with the splines' layouts shared (by receivers of equal knots; TensorSpline 384 -> 72
    # bytes), the probe apart (the sides probed beforehand): two-sided 1.12, 1.12,
    # 1.17; front sides only 1.05, 1.11, 1.07 (before the shared layouts 1.14, 1.12, 1.11 and 1.11,
    # 1.11, 1.08; a 10-object solve's peak varies by 15% between runs). At 2,000 objects (preview,
    # coeffs_from_size, front sides) 1.05 (0.93 before), 1.04 with the finals in float32.
    # Issue 16 asks for 25%.
    for objects in (10, 30, 100):
        m = _measure(objects, sides)
        ratio = m["estimate"] / m["added"]
        assert 0.75 < ratio < 1.25, f"{objects} objects ({m['surfaces']} surfaces): estimate {m['estimate'] / 2**20:.1f} MiB, " \
                                  f"measured {m['added'] / 2**20:.1f} MiB"


@pytest.mark.slow
@pytest.mark.skipif(not pathlib.Path("/proc/self/clear_refs").exists(), reason="needs Linux's VmHWM reset")
def test_estimate_of_the_preview_with_its_regather_within_25_percent_at_three_sizes():
    # Measured 2026-12-05 (front sides only, one bounce): 1.00, 1.00, 1.01 at 10, 30 and 100
    # objects with the shared layouts (1.00, 1.01, 1.01 before); 2026-12-08 1.17 at 100 objects
    # (the same on the build of 12-07), and with the preview's adaptive knots 1.17, 1.19, 1.22 (the
    # estimate counts a layout a receiver; 698 of the 819 surfaces' finals at 100 objects kept
    # uniform knots, shared: their light flat).
    for objects in (10, 30, 100):
        m = _measure(objects, "front-only", "preview")
        ratio = m["estimate"] / m["added"]
        assert 0.75 < ratio < 1.25, f"{objects} objects ({m['surfaces']} surfaces): estimate {m['estimate'] / 2**20:.1f} MiB, " \
                                  f"measured {m['added'] / 2**20:.1f} MiB"
