"""Runs the benchmarks and merges their figures into bench/results.json. `make bench` calls this.

Every module ``bench/bench_<name>.py`` defines ``run() -> dict`` of named figures. This runner
imports them (all of them, or those named on the command line as ``bench_<name>`` or ``<name>``,
e.g. ``python bench/run.py spline_eval``), merges the figures into the flat JSON object in
``bench/results.json`` (keys of other benchmarks are kept; the file is written after each
benchmark, so a failing one keeps the others' figures) and prints them. Timings are wall-clock on
a shared machine: indications, not assertions.
"""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str]) -> int:
    only = {name.removeprefix("bench_") for name in argv[1:]}
    paths = [p for p in sorted(HERE.glob("bench_*.py")) if not only or p.stem.removeprefix("bench_") in only]
    missing = only - {p.stem.removeprefix("bench_") for p in paths}
    if missing:
        print(f"no benchmark named {', '.join(sorted(missing))}", file=sys.stderr)
        return 2
    results_path = HERE / "results.json"
    results = json.loads(results_path.read_text()) if results_path.exists() else {}
    for path in paths:
        spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        print(f"== {path.stem}", flush=True)
        figures = module.run()
        for key, value in figures.items():
            print(f"  {key}: {value:.6g}" if isinstance(value, float) else f"  {key}: {value}")
        results.update(figures)
        results_path.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    print(f"wrote {results_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
