"""Runs the benchmarks and merges their figures into bench/results.json.

Every module ``bench/bench_<name>.py`` defines ``run() -> dict[str, float]`` returning named
figures. This runner imports them (all of them, or those named on the command line, e.g.
``python bench/run.py spline_eval``), merges the figures into the flat JSON object in
``bench/results.json`` (keys of other benchmarks are kept) and prints them. Timings are wall-clock
on a shared machine: read them as indications, not as assertions.
"""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results.json"


def load_module(path: Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main(argv: list[str]) -> int:
    wanted = set(argv)
    paths = sorted(HERE.glob("bench_*.py"))
    if wanted:
        paths = [p for p in paths if p.stem.removeprefix("bench_") in wanted]
        missing = wanted - {p.stem.removeprefix("bench_") for p in paths}
        if missing:
            print(f"no benchmark named {', '.join(sorted(missing))}", file=sys.stderr)
            return 2
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    for path in paths:
        print(f"== {path.stem}", flush=True)
        figures = load_module(path).run()
        for key, value in figures.items():
            print(f"{key}: {value:.6g}" if isinstance(value, float) else f"{key}: {value}")
        results.update(figures)
        # Written after each benchmark so that a failing one keeps the others' figures.
        RESULTS.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    print(f"wrote {RESULTS}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
