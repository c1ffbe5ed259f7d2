"""A bpy script run in a fresh Python process (a scene per process: nothing of one solve lingers
in the next), with the add-on's folder and the Blender tests' folder (their scene builders) as its
first two arguments; the script prints a JSON object as its last line, which is returned."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run_script(script: str, *args: str) -> dict:
    with tempfile.TemporaryDirectory(prefix="bsgi-bench-home-") as home:  # Blender's config away from the user's
        out = subprocess.run([sys.executable, "-c", script, str(ROOT / "addon"), str(ROOT / "tests" / "blender"), *args],
                             cwd=ROOT, env={**os.environ, "HOME": home}, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])
