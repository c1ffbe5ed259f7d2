"""Faults injected into a solve and its bake (issue 17, item 4), each in a fresh process running
tests/blender/fault_runs.py: cancels at 100 random moments of the solve and 100 of the bake of a
small scene (each must leave the saved .blend as it was), and the resident memory over 100
solve/cancel cycles after 10 that fill the caches. tests/blender/test_faults.py asserts the same.

    cancel_points_tested      cancels at random moments that left the scene as it was (of 200)
    leak_mb_after_100_cycles  resident memory after the 100 cycles minus before them, MiB
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "tests" / "blender" / "fault_runs.py"


def _run(*args) -> dict:
    done = subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=1800)
    if done.returncode != 0:
        raise RuntimeError(f"fault_runs.py {' '.join(args)} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def run() -> dict:
    held = 0
    for phase in ("solve", "bake"):
        result = _run("cancel", "--moments", "100", "--phase", phase)
        held += sum(result["stopped"].values()) - len(result["changed"])
    leak = _run("leak", "--cycles", "100")
    return {"cancel_points_tested": held, "leak_mb_after_100_cycles": round(leak["leak_mb"], 2)}


if __name__ == "__main__":
    print(run())
