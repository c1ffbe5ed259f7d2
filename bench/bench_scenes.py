"""Everyday Blender scenes solved and compared with Cycles (issue 14's scenes: two-sided rooms,
textured materials, textured worlds): per scene `scene_<name>_seconds` (export, solve and bake)
and `scene_<name>_rel_diff_vs_cycles` (the baked render against a Cycles path-traced render of the
same camera, the statistic each test bounds). The figures come from the tests themselves
(tests/figures.py): this runs them with BSGI_FIGURES set and collects what they record."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# The tests that compare a scene with Cycles and record its figures.
TESTS = [
    "tests/blender/test_two_sided.py",
    "tests/blender/test_textures.py",
    "tests/blender/test_world_map.py",
    "tests/blender/test_principled_materials.py",
]


def run() -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        figures = Path(tmp) / "figures.json"
        env = {**os.environ, "BSGI_FIGURES": str(figures)}
        tests = [t for t in TESTS if (ROOT / t).exists()]
        status = subprocess.run([sys.executable, "-m", "pytest", "-q", "-m", "slow", *tests], cwd=ROOT, env=env).returncode
        results = json.loads(figures.read_text()) if figures.exists() else {}
    if status != 0:
        print(f"bench_scenes: the tests failed (exit {status}); their figures are those recorded", file=sys.stderr)
    return results
