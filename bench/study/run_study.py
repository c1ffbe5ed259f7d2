"""`make study`: what each preset and knob of the solver costs and what error it buys, next to Cycles
baking, on every example scene. Writes bench/study/results.csv, one error-versus-time plot per
scene (bench/study/plots/) and bench/study/README.md (the tables, which the main README's preset
table is generated from).

    .venv/bin/python bench/study/run_study.py [--quick] [--scene NAME ...] [--setting NAME ...] [--blend FILE ...] [--out DIR]

Scenes: example_blends/*.blend (but the two interiors, NOT_STUDIED) and bench/study/scenes/*.blend
(Cornell boxes with a glossy and a near-mirror back wall; named apart from the examples). Per scene:
the three presets and one knob at a time around the preview preset (spatial coefficients,
angular coefficients, degree, hemisphere nodes, bounces; the costliest settings only where the
preview is quick, see EXPENSIVE_KNOBS); each solve in a
process of its own for its time and peak memory. Error: relative RMSE, sqrt(sum |L - L_ref|^2 / sum |L_ref|^2) over RGB,
against Mitsuba 3 at random visible (point, direction) pairs (references.py, cached). --quick: a
smoke run (the draft preset and one knob around it, a small Cycles bake, a small reference)."""
from __future__ import annotations

import argparse
import csv
import json
import pathlib
import subprocess
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

# One knob at a time around the preview preset: (knob, value shown, solver settings changed).
KNOBS = [
    ("spatial coefficients", 4, {"spatial_coeffs": 4}),
    ("spatial coefficients", 8, {"spatial_coeffs": 8}),
    ("spatial coefficients", 16, {"spatial_coeffs": 16}),
    ("spatial coefficients", 32, {"spatial_coeffs": 32}),
    ("angular coefficients", 4, {"angular_coeffs_min": 4, "angular_coeffs_max": 4}),
    ("angular coefficients", 8, {"angular_coeffs_min": 8, "angular_coeffs_max": 8}),
    ("angular coefficients", 16, {"angular_coeffs_min": 16, "angular_coeffs_max": 16}),
    ("degree", 1, {"spatial_degree": 1, "angular_degree": 1}),
    ("degree", 3, {"spatial_degree": 3, "angular_degree": 3}),
    ("hemisphere nodes", "4x8", {"hemisphere_nodes_theta": 4, "hemisphere_nodes_phi": 8}),
    ("hemisphere nodes", "8x16", {"hemisphere_nodes_theta": 8, "hemisphere_nodes_phi": 16}),
    ("hemisphere nodes", "16x32", {"hemisphere_nodes_theta": 16, "hemisphere_nodes_phi": 32}),
    ("bounces", 1, {"max_bounces": 1}),
    ("bounces", 2, {"max_bounces": 2}),
    ("bounces", 4, {"max_bounces": 4}),
]
PRESETS = ("draft", "preview", "final")
# The knobs are swept on every scene. Where the preview preset took more than this many CPU
# seconds, the two most expensive settings (on the glossy-wall box: spatial 32 = 7x the preview's
# time, hemisphere nodes 16x32 = 1.5x) and the final preset (after FINAL_AFTER_PREVIEW_SECONDS of
# wall time) are left out, so that a scene of the user's cannot take hours (no example scene's
# preview takes that long: every example gets the whole sweep).
EXPENSIVE_KNOBS = {("spatial coefficients", 32), ("hemisphere nodes", "16x32")}
EXPENSIVE_AFTER_PREVIEW_CPU_SECONDS = 60
FINAL_AFTER_PREVIEW_SECONDS = 60
CYCLES_SAMPLES = (16, 64, 256, 1024)
# The atlas: on the Cornell box 51 texels across a 2 m wall (4 cm), as fine as the preview
# preset's final gather (24 coefficients across the wall) at the same cost order; a user's bake
# would often be finer and proportionally slower.
CYCLES_RESOLUTION = 256
# The smoke run: around the draft preset, so that it stays short on the larger scenes too.
QUICK = {"presets": ("draft",), "base": "draft", "knobs": [("bounces", 1, {"max_bounces": 1})],
         "cycles_samples": (4,), "cycles_resolution": 64}
FIELDS = ["scene", "method", "setting", "knob", "value", "seconds", "cpu_seconds", "peak_mb", "coefficients", "rel_rmse",
          "rel_rmse_diffuse", "rel_rmse_glossy", "pairs", "reference_noise"]


# Example scenes the study leaves out: their image textures, world maps and window panes have no
# Mitsuba 3 scene here (mitsuba_scene.py). The textured interior is compared with Cycles
# (example_blends/render_comparison.py), the furnished interior measured for scale (bench/run.py scale).
NOT_STUDIED = {"textured_interior", "furnished_interior"}


def scenes(names=None):
    """The example scenes (whatever example_blends/ holds today, but NOT_STUDIED) and the study's own."""
    subprocess.run([sys.executable, str(HERE / "scenes" / "make_cornell_box_glossy.py"), "--if-missing"], check=True,
                   stdout=subprocess.DEVNULL)
    found = sorted((ROOT / "example_blends").glob("*.blend")) + sorted((HERE / "scenes").glob("*.blend"))
    return [p for p in found if p.stem not in NOT_STUDIED and (not names or p.stem in names)]


def rel_rmse(ours, ref, mask=None):
    """sqrt(sum |ours - ref|^2 / sum |ref|^2) over the pairs in mask (NaN if none)."""
    mask = np.ones(len(ref), bool) if mask is None else mask
    if not mask.any():
        return float("nan")
    return float(np.sqrt(((ours[mask] - ref[mask]) ** 2).sum() / (ref[mask] ** 2).sum()))


def emitting_objects(description) -> list:
    return [o.name for o in description["objects"] if any(max(m.emission) > 0 for m in o.materials)]


def errors(ours, data, valid):
    kind = data["kind"]
    return {"rel_rmse": rel_rmse(ours, data["reference"], valid),
            "rel_rmse_diffuse": rel_rmse(ours, data["reference"], valid & (kind == "diffuse")),
            "rel_rmse_glossy": rel_rmse(ours, data["reference"], valid & (kind != "diffuse")),
            "pairs": int(valid.sum())}


def cycles_bakes(blend, pairs_npz, work, samples, resolution):
    """Cycles bakes of the scene at each sample count (cycles_bake.py, in a process of its own),
    looked up at the pairs: [(samples, seconds, CPU seconds, radiance (n, 3))]."""
    out = pathlib.Path(work) / "cycles.npz"
    result = subprocess.run([sys.executable, str(HERE / "cycles_bake.py"), str(blend), str(pairs_npz), str(out),
                             str(resolution), *map(str, samples)], capture_output=True, text=True)
    if result.returncode:
        raise RuntimeError(f"{pathlib.Path(blend).stem}: Cycles bake failed:\n{result.stderr[-3000:]}")
    baked = np.load(out)
    return [(n, float(baked[f"seconds_{n}"]), float(baked[f"cpu_seconds_{n}"]), baked[f"radiance_{n}"]) for n in samples]


def run_scene(blend, work, quick, cache, log, only=None, earlier=()):
    """The scene's rows; with `only` (setting names) just those settings' (no Cycles bakes unless
    a "Cycles bake N samples" is named), the preview's time for the rules above from `earlier` rows."""
    name = blend.stem
    work.mkdir(parents=True, exist_ok=True)
    args = [sys.executable, str(HERE / "references.py"), str(blend), "--cache", str(cache)] + (["--quick"] if quick else [])
    log(f"{name}: Mitsuba 3 reference")
    subprocess.run(args, check=True)
    from references import describe, load_cached, relative_noise

    data = load_cached(blend, quick, cache)
    pairs_npz = work / "pairs.npz"
    np.savez(pairs_npz, **{k: data[k] for k in ("object", "polygon", "point", "eye")})
    glossy_scene = bool((data["kind"] != "diffuse").any())
    rows = []
    # Pairs the solver's geometry does not see as the reference does (NaN) are left out of every
    # method's error alike, and so are pairs on emitting objects: every method returns their
    # emission exactly, and its size would swamp the relative error of everything lit by it.
    valid = ~np.isin(data["object"], emitting_objects(describe(blend)))

    def solve(setting, knob, value, spec):
        if only is not None and setting not in only:
            return
        settings_json = work / "settings.json"
        settings_json.write_text(json.dumps(spec))
        out = work / "solve.npz"
        result = subprocess.run([sys.executable, str(HERE / "solve_blend.py"), str(blend), str(settings_json),
                                 str(pairs_npz), str(out)], capture_output=True, text=True)
        if result.returncode:
            # A setting the solver refuses (or that runs out of memory) is reported, not fatal.
            log(f"{name}: {setting}: solve failed: {result.stderr.strip().splitlines()[-1]}")
            return
        figures = json.loads(result.stdout.strip().splitlines()[-1])
        ours = np.load(out)["radiance"]
        nonlocal valid
        valid &= np.isfinite(ours).all(axis=1)
        row = {"scene": name, "method": "bsgi", "setting": setting, "knob": knob, "value": value,
               "seconds": round(figures["seconds"], 3), "cpu_seconds": round(figures["cpu_seconds"], 3), "peak_mb": round(figures["peak_mb"], 1),
               "coefficients": figures["coefficients"]}
        rows.append((row, ours))
        log(f"{name}: {setting}: {figures['seconds']:.2f} s ({figures['cpu_seconds']:.2f} s CPU), {figures['coefficients']} coefficients, "
            f"error {rel_rmse(ours, data['reference'], np.isfinite(ours).all(axis=1)):.4f}")

    for preset in QUICK["presets"] if quick else PRESETS:
        preview = next((float(r["seconds"]) for r in [r for r, _ in rows] + list(earlier) if r["setting"] == "preview"), 0)
        if preset == "final" and preview > FINAL_AFTER_PREVIEW_SECONDS:
            log(f"{name}: final preset skipped (preview took {preview:.0f} s; the final preset is several times slower)")
            continue
        solve(preset, "preset", preset, {"preset": preset})
    knobs = QUICK["knobs"] if quick else KNOBS
    preview_cpu = next((float(r["cpu_seconds"]) for r in [r for r, _ in rows] + list(earlier) if r["setting"] == "preview"), 0)
    for knob, value, overrides in knobs:
        if knob == "angular coefficients" and not glossy_scene:
            continue  # no glossy surface: the knob changes nothing
        if (knob, value) in EXPENSIVE_KNOBS and preview_cpu > EXPENSIVE_AFTER_PREVIEW_CPU_SECONDS:
            log(f"{name}: {knob} {value} skipped (the preview took {preview_cpu:.0f} s CPU; this setting costs several times more)")
            continue
        base = QUICK["base"] if quick else "preview"
        solve(f"{base}, {knob} {value}", knob, value, {"preset": base, "overrides": overrides})

    samples = QUICK["cycles_samples"] if quick else CYCLES_SAMPLES
    resolution = QUICK["cycles_resolution"] if quick else CYCLES_RESOLUTION
    if only is not None:
        samples = [n for n in samples if f"Cycles bake {n} samples" in only]
    if samples:
        log(f"{name}: Cycles bake at {', '.join(map(str, samples))} samples, {resolution}x{resolution} atlas")
    for n, seconds, cpu_seconds, radiance in cycles_bakes(blend, pairs_npz, work, samples, resolution) if samples else []:
        row = {"scene": name, "method": "cycles bake", "setting": f"Cycles bake {n} samples", "knob": "samples",
               "value": n, "seconds": round(seconds, 3), "cpu_seconds": round(cpu_seconds, 3), "peak_mb": "",
               "coefficients": resolution * resolution}
        rows.append((row, radiance))
    # The reference's noise over the pairs compared: the emitters' pairs, exact and bright, would
    # hide it (glossy_spheres' bulb made 0.9% look like 0.06%).
    noise = relative_noise(data["reference"], data["stderr"], valid)
    out_rows = []
    for row, radiance in rows:
        row["reference_noise"] = round(noise, 4)
        row.update({k: (round(v, 4) if isinstance(v, float) else v) for k, v in errors(radiance, data, valid).items()})
        out_rows.append(row)
    log(f"{name}: {int(valid.sum())} of {len(valid)} pairs compared; reference noise {noise:.4f}")
    return out_rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smoke run: draft preset, one knob, small bake and reference")
    parser.add_argument("--scene", nargs="*", help="scene names (file stems) to run; default all")
    parser.add_argument("--blend", nargs="*", help="other .blend files to study (e.g. your own scene)")
    parser.add_argument("--out", help="folder for results.csv, plots/ and README.md (default bench/study; "
                        "build/study-quick with --quick, so a smoke run never replaces the study's results)")
    parser.add_argument("--cache", help="folder of the cached references (default bench/study/references; "
                        "build/study-quick/references with --quick)")
    parser.add_argument("--setting", nargs="*", help="run only these settings (as the tables name them, e.g. "
                        "final or 'preview, bounces 1') and keep the other rows of the earlier run as they were (each "
                        "setting's error over the pairs its own run compared)")
    parser.add_argument("--work", default=str(ROOT / "build" / "study"), help="folder for intermediate files")
    args = parser.parse_args(argv)
    quick_dir = ROOT / "build" / "study-quick"
    args.out = args.out or str(quick_dir if args.quick else HERE)
    args.cache = args.cache or str(quick_dir / "references" if args.quick else HERE / "references")
    out = pathlib.Path(args.out)
    start = time.perf_counter()

    def log(text):
        print(f"study [{time.perf_counter() - start:6.0f} s] {text}", flush=True)

    earlier = []
    if (args.scene or args.blend or args.setting) and (out / "results.csv").exists():
        with open(out / "results.csv", newline="") as f:
            earlier = list(csv.DictReader(f))
    rows = []
    blends = [pathlib.Path(b).resolve() for b in args.blend] if args.blend else scenes(args.scene)
    only = set(args.setting) if args.setting else None
    for blend in blends:
        rows += run_scene(blend, pathlib.Path(args.work) / blend.stem, args.quick, pathlib.Path(args.cache), log, only,
                          [r for r in earlier if r["scene"] == blend.stem])
    out.mkdir(parents=True, exist_ok=True)
    # A run of some scenes (or settings) keeps the other scenes' (settings') rows of an earlier run,
    # in their order.
    if earlier:
        studied = {b.stem for b in blends}

        def redone(r):
            return r["scene"] in studied and (only is None or r["setting"] in only)

        if only is None:
            rows = [r for r in earlier if not redone(r)] + rows
        else:  # in place (a setting that failed this time is left out, not kept stale)
            new = {(r["scene"], r["setting"]): r for r in rows}
            rows = [new.pop((r["scene"], r["setting"]), None) if redone(r) else r for r in earlier]
            rows = [r for r in rows if r is not None] + list(new.values())
    with open(out / "results.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    import report

    # The main README's preset table comes from the full study written to its usual place.
    readme = ROOT / "README.md" if out.resolve() == HERE and not args.quick else None
    report.write(out, rows, readme)
    log(f"wrote {out / 'results.csv'}, {out / 'README.md'} and plots")


if __name__ == "__main__":
    main()
