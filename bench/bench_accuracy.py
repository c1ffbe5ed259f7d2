"""Accuracy per scene and preset (issue 15): each scene solved at draft, preview and final (the
validation scenes also at reference) in a process of its own (bench/study/solve_blend.py: the
add-on's export of the .blend, as a user's solve gets it) and compared with its committed
Mitsuba 3 reference (bench/study/references/, 3,000 random visible (point, direction) pairs; a
reference made for an earlier version of the scene file is still used: the pairs and the scene's
geometry are the same). Figures:

- acc_<scene>_<preset>_rel_rmse, acc_<scene>_<preset>_seconds (CPU seconds of the solve),
- acc_<scene>_<preset>_worst_surface_ratio: the mean radiance ratio (ours / Mitsuba) of the object
  farthest from 1 among those with at least 20 pairs,
- acc_<scene>_<preset>_cycles_seconds: the CPU time a Cycles bake of the same surfaces needed to
  reach that error, from the committed bakes at 16 to 1,024 samples against the same reference
  (the study's scenes: bench/study/results.csv; the validation scenes: bench/validation/cycles.csv,
  `validate.py cycles`), interpolated in log time; absent if no bake reached it,
- acc_<scene>_worst_surface_ratio: the final preset's worst object ratio.

Scenes: the study's and the validation scenes (bench/validation: open_box, table_spheres,
ceiling_light, thin_occluder, with their own committed references, 3,000 pairs each).
BSGI_BENCH_ACCURACY=cornell_box,mug chooses the scenes (default: the diffuse study scenes, the
glossy-wall box and the validation scenes; the near-mirror box, the spheres and the glass sheet
take many minutes each).

    python bench/run.py accuracy
"""
from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
STUDY = HERE / "study"
sys.path.insert(0, str(STUDY))

sys.path.insert(0, str(HERE / "validation"))
SCENES = os.environ.get("BSGI_BENCH_ACCURACY", "cornell_box,contact_shadows,mug,bezier_patches,cornell_box_glossy_wall,"
                        "open_box,table_spheres,ceiling_light,thin_occluder,leaning_board").split(",")
PRESETS = ("draft", "preview", "final")
# The reference preset (5-8 times final's cost) on the validation scenes only, where the README
# states its figures.
REFERENCE_SCENES = ("open_box", "table_spheres", "ceiling_light", "thin_occluder", "leaning_board")


def cycles_seconds(scene: str, error: float) -> float | None:
    """CPU seconds of the scene's committed Cycles bakes (the validation scenes' cycles.csv, else
    the study's results.csv) at the given error: the cheapest bake that reached it, interpolated
    in log time from the one before it."""
    import validate

    if scene in validate.SCENES:
        rows = list(csv.DictReader(open(validate.CYCLES_CSV)))
    else:
        rows = [r for r in csv.DictReader(open(STUDY / "results.csv")) if r["method"] == "cycles bake"]
    bakes = sorted((float(r["cpu_seconds"]), float(r["rel_rmse"])) for r in rows if r["scene"] == scene)  # by time
    for k, (t1, e1) in enumerate(bakes):
        if e1 > error:
            continue
        if k == 0:
            return t1
        t0, e0 = bakes[k - 1]
        f = (e0 - error) / (e0 - e1)
        return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
    return None


def measure(scene: str, preset: str, work: Path) -> dict:
    import run_study
    import validate
    from references import describe

    if scene in validate.SCENES:
        row = validate.measure(scene, preset, work=work)
        return {k: row[k] for k in ("rel_rmse", "seconds", "worst_surface_ratio")}

    blend = next(p for p in run_study.scenes([scene]))
    data = dict(np.load(STUDY / "references" / f"{scene}.npz", allow_pickle=False))
    np.savez(work / "pairs.npz", **{k: data[k] for k in ("object", "polygon", "point", "eye")})
    (work / "settings.json").write_text(json.dumps({"preset": preset}))
    out = subprocess.run([sys.executable, str(STUDY / "solve_blend.py"), str(blend), str(work / "settings.json"),
                          str(work / "pairs.npz"), str(work / "solve.npz")], capture_output=True, text=True, check=True)
    figures = json.loads(out.stdout.strip().splitlines()[-1])
    ours = np.load(work / "solve.npz")["radiance"]
    valid = ~np.isin(data["object"], run_study.emitting_objects(describe(blend))) & np.isfinite(ours).all(axis=1)
    error = run_study.errors(ours, data, valid)["rel_rmse"]
    ratios = []
    for name in sorted(set(data["object"][valid].tolist())):
        m = valid & (data["object"] == name)
        if m.sum() >= 20:
            ratios.append(ours[m].sum() / data["reference"][m].sum())
    worst = max(ratios, key=lambda r: abs(r - 1))
    return {"rel_rmse": error, "seconds": figures["cpu_seconds"], "worst_surface_ratio": worst}


def run() -> dict:
    figures = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in SCENES:
            for preset in PRESETS + (("reference",) if scene in REFERENCE_SCENES else ()):
                row = measure(scene, preset, Path(tmp))
                for key, value in row.items():
                    figures[f"acc_{scene}_{preset}_{key}"] = value
                if preset == "final":
                    figures[f"acc_{scene}_worst_surface_ratio"] = row["worst_surface_ratio"]
                cycles = cycles_seconds(scene, row["rel_rmse"])
                if cycles is not None:
                    figures[f"acc_{scene}_{preset}_cycles_seconds"] = cycles
                print(f"  {scene} {preset}: {100 * row['rel_rmse']:.2f}% in {row['seconds']:.1f} s CPU, worst object ratio "
                      f"{row['worst_surface_ratio']:.4f}; Cycles bake to the same error: "
                      f"{'not reached' if cycles is None else f'{cycles:.1f} s'}", flush=True)
    return figures


if __name__ == "__main__":
    print(json.dumps(run(), indent=2))
