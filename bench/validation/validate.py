"""The validation scenes (issue 15; make_scenes.py) against Mitsuba 3, with the study's machinery:
references made by bench/study/references.py (committed in references/), solves by
bench/study/solve_blend.py in a process of their own, errors by run_study.errors. Adds what the
study does not print: per object (per surface) the mean radiance ratio ours / Mitsuba, the
relative RMSE and the reference's noise there. `cycles`: the study's Cycles bake (run_study.cycles_bakes,
its sample counts and atlas) of each scene, the same errors, written to cycles.csv (which
bench/bench_accuracy.py reads for the time a bake needs to reach a solve's error).

    .venv/bin/python bench/validation/validate.py references            (make missing or stale references)
    .venv/bin/python bench/validation/validate.py measure [--scene S ...] [--preset P ...] [--overrides JSON] [--markdown]
    .venv/bin/python bench/validation/validate.py cycles [--scene S ...] [--samples N ...] [--markdown]

The references render the objects make_scenes.TWO_SIDED names two-sided and the lights
transparent (Blender's lights cast no shadow), as Cycles and the solver see the scenes; the Cycles
bake bakes those objects' back sides too (cycles_bake.py).
"""
from __future__ import annotations

import argparse
import csv
import json
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
STUDY = HERE.parent / "study"
sys.path.insert(0, str(STUDY))
sys.path.insert(0, str(HERE))

from make_scenes import TWO_SIDED  # noqa: E402

SCENES = tuple(TWO_SIDED)
PRESETS = ("draft", "preview", "final")
REFERENCES = HERE / "references"
# 3,000 pairs as the study; 32,768 samples a pair leave the noise at 0.1-0.2% (printed).
SETTINGS = {"pairs": 3000, "spp": 32768, "seed": 11}
# Objects with fewer pairs than this get no per-surface figures (too noisy a mean).
MIN_PAIRS = 20
CYCLES_CSV = HERE / "cycles.csv"
CYCLES_FIELDS = ["scene", "samples", "seconds", "cpu_seconds", "rel_rmse", "rel_rmse_diffuse", "rel_rmse_glossy", "pairs",
                 "reference_noise", "worst_surface", "worst_surface_ratio"]


def blend_path(scene: str) -> pathlib.Path:
    return HERE / "scenes" / f"{scene}.blend"


def settings(scene: str) -> dict:
    return {**SETTINGS, "two_sided": TWO_SIDED[scene]}


def load_reference(scene: str) -> dict:
    """The committed reference (used even if the .blend was regenerated since: the geometry is the same)."""
    return dict(np.load(REFERENCES / f"{scene}.npz", allow_pickle=False))


def make_references(scenes=SCENES):
    import references

    for scene in scenes:
        data = references.reference(blend_path(scene), cache=REFERENCES, settings=settings(scene))
        print(json.dumps({"scene": scene, "pairs": len(data["point"]), "reference_seconds": float(data["reference_seconds"]),
                          "reference_noise": noise(data)}), flush=True)


def noise(data, mask=None) -> float:
    """The reference's relative noise (references.relative_noise) over the pairs in mask (all)."""
    from references import relative_noise

    return relative_noise(data["reference"], data["stderr"], np.ones(len(data["reference"]), bool) if mask is None else mask)


def write_pairs(scene: str, data: dict, work: pathlib.Path) -> pathlib.Path:
    """The reference's pairs for solve_blend.py and cycles_bake.py, with the scene's two-sided objects."""
    work.mkdir(parents=True, exist_ok=True)
    np.savez(work / "pairs.npz", two_sided=np.array(TWO_SIDED[scene], str),
             **{k: data[k] for k in ("object", "polygon", "point", "eye")})
    return work / "pairs.npz"


def compared(emitting, data, radiance):
    """The pairs compared: those a method returns (finite) off the emitting objects (whose
    emission every method returns exactly), as run_study compares them."""
    return ~np.isin(data["object"], emitting) & np.isfinite(radiance).all(axis=1)


def solve(scene: str, spec: dict, data: dict, work: pathlib.Path):
    """One solve of the scene (solve_blend.py, its own process) and its radiance at the pairs:
    (radiance (n, 3), the solve's figures, mask of the pairs compared). With spec["first_pass"]
    (a refined solve) the figures hold under "first_pass" its first pass's, as one solve's:
    (radiance, figures, mask) too."""
    import run_study
    from references import describe

    blend = blend_path(scene)
    write_pairs(scene, data, work)
    (work / "settings.json").write_text(json.dumps(spec))
    out = subprocess.run([sys.executable, str(STUDY / "solve_blend.py"), str(blend), str(work / "settings.json"),
                          str(work / "pairs.npz"), str(work / "solve.npz")], capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(f"{scene}: solve failed:\n{out.stderr[-3000:]}")
    figures = json.loads(out.stdout.strip().splitlines()[-1])
    emitting = run_study.emitting_objects(describe(blend))
    ours = read_solution(work / "solve.npz", figures)
    if "first_pass" in figures:
        first = figures["first_pass"]
        radiance = read_solution(work / "solve.first.npz", first)
        figures["first_pass"] = (radiance, first, compared(emitting, data, radiance))
    return ours, figures, compared(emitting, data, ours)


def read_solution(path: pathlib.Path, figures: dict):
    """The radiance at the pairs solve_blend.py wrote to `path`; into `figures` the solver's own
    estimate of its error and its parts, per pair those of the surface the pair lies on (NaN where
    it lies on none)."""
    solved = np.load(path)
    row_of = {k: i for i, k in enumerate(solved["receivers"].tolist())}
    rows = np.array([row_of.get(int(k), -1) for k in solved["surface"]], dtype=int)
    known = rows >= 0
    figures["estimate_at_pairs"] = np.where(known, solved["estimated_error"][rows], np.nan)
    figures["parts_at_pairs"] = np.where(known[:, None], solved["error_parts"][rows], np.nan)
    return solved["radiance"]


def per_surface(ours, data, valid, estimate=None, parts=None) -> dict:
    """Per object with at least MIN_PAIRS pairs: mean ratio (sum of ours / sum of the reference,
    RGB), relative RMSE, reference noise (of the mean and per pair) and the pair count; with the
    solver's per-pair `estimate`, its RMS over the object's pairs (`estimated`) beside the relative
    RMSE with the reference's noise taken out in quadrature (`measured`)."""
    import run_study

    out = {}
    for name in sorted(set(data["object"][valid].tolist())):
        m = valid & (data["object"] == name)
        if m.sum() < MIN_PAIRS:
            continue
        ref = data["reference"][m]
        out[name] = {"ratio": float(ours[m].sum() / ref.sum()), "rel_rmse": run_study.rel_rmse(ours, data["reference"], m),
                     "mean_noise": float(np.sqrt((data["stderr"][m] ** 2).sum()) / ref.sum()), "noise": noise(data, m),
                     "pairs": int(m.sum())}
        if estimate is not None:
            surface = out[name]
            surface["estimated"] = float(np.sqrt(np.nanmean(estimate[m] ** 2)))
            surface["measured"] = float(np.sqrt(max(surface["rel_rmse"] ** 2 - surface["noise"] ** 2, 0.0)))
        if parts is not None:  # the estimate's parts (solve_blend.ERROR_PARTS), each its RMS over the pairs
            out[name]["parts"] = np.sqrt(np.nanmean(parts[m] ** 2, axis=0)).tolist()
    return out


def worst_ratio(surfaces: dict) -> float:
    return max((s["ratio"] for s in surfaces.values()), key=lambda r: abs(r - 1))


def measure(scene: str, preset: str, overrides=None, work=None, first_pass=False) -> dict:
    """Errors of one solve against the committed reference: run_study.errors' figures, the
    solve's CPU seconds, per-surface figures and the worst surface's mean ratio. With
    `first_pass` (a refined solve) "first_pass" holds the same of its first pass (one solve)."""
    data = load_reference(scene)
    spec = {"preset": preset, **({"overrides": overrides} if overrides else {}), **({"first_pass": True} if first_pass else {})}
    with tempfile.TemporaryDirectory() as tmp:
        ours, figures, valid = solve(scene, spec, data, pathlib.Path(work or tmp))
    out = measured(ours, figures, valid, data)
    if "first_pass" in figures:
        out["first_pass"] = measured(*figures["first_pass"], data)
    return out


def measured(ours, figures: dict, valid, data) -> dict:
    """measure's figures of one solution."""
    import run_study

    surfaces = per_surface(ours, data, valid, figures["estimate_at_pairs"], figures["parts_at_pairs"])
    return {**run_study.errors(ours, data, valid), "seconds": figures["cpu_seconds"], "wall_seconds": figures["seconds"],
            "reference_noise": noise(data, valid), "surfaces": surfaces, "worst_surface_ratio": worst_ratio(surfaces),
            "refinement": figures.get("refinement")}


def cycles(scene: str, samples, resolution, work=None) -> list:
    """The study's Cycles bakes of the scene (one process, the sample counts in turn) against the
    committed reference: per sample count a cycles.csv row (run_study.errors' figures, seconds,
    the worst surface's mean ratio) with the per-surface figures under "surfaces"."""
    import run_study
    from references import describe

    data = load_reference(scene)
    emitting = run_study.emitting_objects(describe(blend_path(scene)))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(work or tmp)
        pairs = write_pairs(scene, data, work)
        for n, seconds, cpu_seconds, baked in run_study.cycles_bakes(blend_path(scene), pairs, work, samples, resolution):
            valid = compared(emitting, data, baked)
            surfaces = per_surface(baked, data, valid)
            worst = max(surfaces, key=lambda name: abs(surfaces[name]["ratio"] - 1))
            rows.append({"scene": scene, "samples": n, "seconds": seconds, "cpu_seconds": cpu_seconds,
                         **run_study.errors(baked, data, valid), "reference_noise": noise(data, valid),
                         "worst_surface": worst, "worst_surface_ratio": surfaces[worst]["ratio"], "surfaces": surfaces})
    return rows


def write_cycles_csv(rows):
    """cycles.csv with these rows, keeping an earlier run's rows of the other scenes."""
    done = {r["scene"] for r in rows}
    kept = [r for r in csv.DictReader(open(CYCLES_CSV)) if r["scene"] not in done] if CYCLES_CSV.exists() else []
    with open(CYCLES_CSV, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CYCLES_FIELDS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(kept)
        writer.writerows({k: round(v, 4) if isinstance(v, float) else v for k, v in r.items()} for r in rows)


def cycles_markdown(rows) -> str:
    """A table row per bake: samples, CPU time, errors (all / diffuse / glossy), worst surface."""
    lines = ["| scene | samples | CPU time | error (all / diffuse / glossy) | worst surface: mean ratio |",
             "|---|---|---|---|---|"]
    for r in rows:
        errors = " / ".join("–" if np.isnan(float(r[k])) else f"{100 * float(r[k]):.1f}%"
                            for k in ("rel_rmse", "rel_rmse_diffuse", "rel_rmse_glossy"))
        lines.append(f"| {r['scene']} | {r['samples']} | {float(r['cpu_seconds']):.1f} s | {errors} | "
                     f"{r['worst_surface']} {float(r['worst_surface_ratio']):.3f} |")
    return "\n".join(lines)


def print_row(scene, setting, r):
    glossy = "" if np.isnan(r["rel_rmse_glossy"]) else f", glossy {100 * r['rel_rmse_glossy']:.2f}%"
    print(f"{scene} {setting}: {100 * r['rel_rmse']:.2f}% (diffuse {100 * r['rel_rmse_diffuse']:.2f}%{glossy}) "
          f"in {r['seconds']:.1f} s CPU; reference noise {100 * r['reference_noise']:.2f}%", flush=True)
    for name, s in r["surfaces"].items():
        print(f"    {name:16s} ratio {s['ratio']:.4f} (noise {100 * s['mean_noise']:.2f}%)  rel RMSE "
              f"{100 * s['rel_rmse']:5.2f}% (noise {100 * s['noise']:.2f}%)  {s['pairs']} pairs"
              + (f"  estimated {100 * s['estimated']:.2f}% against {100 * s['measured']:.2f}%" if "estimated" in s else "")
              + (" (fit, input, integration, tail: " + ", ".join(f"{100 * x:.2f}%" for x in s["parts"]) + ")" if "parts" in s else ""),
              flush=True)


def markdown(figures: dict) -> str:
    """A table row per solve: errors (all / diffuse / glossy pairs), CPU time, and per object its
    mean ratio ours / Mitsuba and (in brackets) its relative RMSE."""
    lines = ["| scene | preset | CPU time | error (all / diffuse / glossy) | per surface: mean ratio (rel. RMSE) |",
             "|---|---|---|---|---|"]
    for key, r in figures.items():
        scene, preset = key.rsplit("_", 1)
        errors = " / ".join("–" if np.isnan(r[k]) else f"{100 * r[k]:.1f}%"
                            for k in ("rel_rmse", "rel_rmse_diffuse", "rel_rmse_glossy"))
        surfaces = ", ".join(f"{n} {s['ratio']:.3f} ({100 * s['rel_rmse']:.1f}%)" for n, s in r["surfaces"].items())
        lines.append(f"| {scene} | {preset} | {r['seconds']:.1f} s | {errors} | {surfaces} |")
    return "\n".join(lines)


def main(argv=None):
    import run_study

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("command", choices=("references", "measure", "cycles"))
    parser.add_argument("--scene", nargs="*", default=list(SCENES))
    parser.add_argument("--preset", nargs="*", default=list(PRESETS))
    parser.add_argument("--overrides", default=None, help='solver settings changed, JSON: \'{"max_bounces": 2}\'')
    parser.add_argument("--samples", nargs="*", type=int, default=list(run_study.CYCLES_SAMPLES),
                        help="cycles: the bakes' sample counts (default the study's)")
    parser.add_argument("--markdown", action="store_true", help="end with a Markdown table (the README's)")
    args = parser.parse_args(argv)
    if args.command == "references":
        make_references(args.scene)
        return
    if args.command == "cycles":
        rows = []
        for scene in args.scene:
            rows += cycles(scene, args.samples, run_study.CYCLES_RESOLUTION)
            for r in rows[-len(args.samples):]:
                print_row(scene, f"Cycles bake {r['samples']} samples", {**r, "seconds": r["cpu_seconds"]})
            write_cycles_csv(rows)
        if args.markdown:
            print(cycles_markdown(rows))
        return
    overrides = json.loads(args.overrides) if args.overrides else None
    figures = {}
    for scene in args.scene:
        for preset in args.preset:
            r = measure(scene, preset, overrides)
            print_row(scene, preset + (f" {args.overrides}" if overrides else ""), r)
            figures[f"{scene}_{preset}"] = r
    print(json.dumps(figures))
    if args.markdown:
        print(markdown(figures))


if __name__ == "__main__":
    main()
