"""Solves every example scene at a preset and prints a line per scene: solve time (wall clock,
and the CPU time of all threads, which other load on the machine changes less), surfaces,
coefficients, bounces and what the solver chose. Nothing is saved. Run with the `bpy` module:

    .venv/bin/python example_blends/solve_times.py [--preset draft|preview|final] [scene.blend ...]
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "addon"))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("blends", nargs="*", help="scenes (default: every .blend beside this script)")
    parser.add_argument("--preset", default="preview", choices=["draft", "preview", "final"])
    args = parser.parse_args(argv)

    import bpy

    import cli  # addon/cli.py loads the add-on as a package

    addon = cli.load_addon()
    addon.register()
    from bsgi_addon import pipeline

    blends = [pathlib.Path(b) for b in args.blends] or sorted(HERE.glob("*.blend"))
    print(f"preset {args.preset}")
    print(f"{'scene':<22} {'solve s':>8} {'CPU s':>8} {'surfaces':>8} {'coefficients':>12} {'bounces':>7}  "
          "representations")
    for blend in blends:
        bpy.ops.wm.open_mainfile(filepath=str(blend.resolve()))
        bpy.context.scene.bsgi.preset = args.preset.upper()
        cpu = time.process_time()
        rep = pipeline.solve_and_bake(bpy.context)
        cpu = time.process_time() - cpu
        print(f"{blend.stem:<22} {rep['solve_seconds']:8.2f} {cpu:8.1f} {rep['surfaces']:8d} {rep['coefficients']:12d} "
              f"{rep['bounces']:7d}  {pipeline.summary_text(rep)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
