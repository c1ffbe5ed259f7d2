"""Figures a test measures, for the benchmark: `record(scene_floor_seconds=0.2, ...)` writes them
into the JSON file named by the environment variable BSGI_FIGURES (bench/bench_scenes.py runs the
tests with it set); without it, nothing is written. The figures the README states for these
scenes thus come from the very tests that bound them."""
from __future__ import annotations

import json
import os
import pathlib


def record(**figures: float) -> None:
    path = os.environ.get("BSGI_FIGURES")
    if not path:
        return
    path = pathlib.Path(path)
    known = json.loads(path.read_text()) if path.exists() else {}
    known.update({key: float(value) for key, value in figures.items()})
    path.write_text(json.dumps(known, indent=2, sort_keys=True) + "\n")
