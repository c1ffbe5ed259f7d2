"""The preview preset against the preview preset with some settings changed, on the study's
scenes and their committed Mitsuba 3 references (no Cycles bakes, no knob sweep: a quick check
that a change of the solver's defaults costs no accuracy). Prints one line per scene and solve,
and a JSON line of the figures at the end.

    python bench/study/compare_preview.py '{"coeffs_from_size": true, "detail_tolerance": 0.02}' [scene ...]
    python bench/study/compare_preview.py --preset final '{}' [scene ...]   (another preset as the base)
    python bench/study/compare_preview.py --validation '{...}' [scene ...]   (bench/validation's scenes)
"""
from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import run_study  # noqa: E402
from references import describe, load_cached  # noqa: E402


def compare(blend, overrides: dict, work: pathlib.Path, preset: str = "preview", references: pathlib.Path = HERE / "references") -> dict:
    data = load_cached(blend, False, references)
    if data is None:
        # Stale (a source file or the .blend changed since): both solves still meet the same
        # pairs and reference, which is what this comparison needs.
        data = dict(np.load(references / f"{blend.stem}.npz", allow_pickle=False))
    work.mkdir(parents=True, exist_ok=True)
    pairs = work / "pairs.npz"
    np.savez(pairs, **{k: data[k] for k in ("object", "polygon", "point", "eye")})
    valid = ~np.isin(data["object"], run_study.emitting_objects(describe(blend)))
    out = {}
    for name, spec in ((preset, {"preset": preset}), ("changed", {"preset": preset, "overrides": overrides})):
        if name == "changed" and not overrides:
            continue  # the preset alone
        (work / "settings.json").write_text(json.dumps(spec))
        result = subprocess.run([sys.executable, str(HERE / "solve_blend.py"), str(blend), str(work / "settings.json"),
                                 str(pairs), str(work / "solve.npz")], capture_output=True, text=True, check=True)
        figures = json.loads(result.stdout.strip().splitlines()[-1])
        ours = np.load(work / "solve.npz")["radiance"]
        ok = valid & np.isfinite(ours).all(axis=1)
        out[name] = {"seconds": figures["seconds"], "cpu_seconds": figures["cpu_seconds"],
                     "coefficients": figures["coefficients"], "rays": figures["rays"],
                     "refinement": figures["refinement"], **run_study.errors(ours, data, ok)}
        print(f"{blend.stem}: {name}: {out[name]['cpu_seconds']:.2f} s CPU, {out[name]['coefficients']} coefficients, {out[name]['rays']} rays, "
              f"error {out[name]['rel_rmse']:.4f} (diffuse {out[name]['rel_rmse_diffuse']:.4f}, "
              f"glossy {out[name]['rel_rmse_glossy']:.4f})", flush=True)
    return out


if __name__ == "__main__":
    args = sys.argv[1:]
    preset = "preview"
    if args[:1] == ["--preset"]:
        preset, args = args[1], args[2:]
    references, blends = HERE / "references", None
    if args[:1] == ["--validation"]:
        validation = HERE.parent / "validation"
        references, args = validation / "references", args[1:]
        blends = [b for b in sorted((validation / "scenes").glob("*.blend")) if not args[1:] or b.stem in args[1:]]
    overrides = json.loads(args[0])
    figures = {blend.stem: compare(blend, overrides, run_study.ROOT / "build" / f"study_compare_{os.getpid()}", preset, references)  # runs side by side
               for blend in (blends if blends is not None else run_study.scenes(args[1:] or None))
               if (references / f"{blend.stem}.npz").exists()}  # the scenes with a reference
    print(json.dumps(figures))
