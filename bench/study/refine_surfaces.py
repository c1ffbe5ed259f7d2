"""Does refinement (SolverSettings.refine_to_error, bsgi.refine) lower the error where the estimate
was high? Per surface of the study's scenes, against their committed Mitsuba 3 references: the
estimate and the measured relative RMSE (over the pairs that see the surface) of the preview
preset, and of the preview preset with the given settings. Prints one line per surface whose
preview estimate is over the target or that was refined (seen by at least 40 pairs, or the
number given by `--pairs`), and a JSON line. Settings without refine_to_error: every surface
whose measured error the change moved.

    python bench/study/refine_surfaces.py '{"refine_to_error": 0.02}' [scene ...]
    python bench/study/refine_surfaces.py --pairs 20 '{"coeffs_from_size": true, "detail_tolerance": 0.005}' cornell_box
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

from compare_preview import HERE, describe, run_study

MIN_PAIRS = 40  # as tests/core/test_error_estimate.py: fewer pairs measure too little


def solve(blend, spec: dict, work, pairs) -> dict:
    (work / "settings.json").write_text(json.dumps(spec))
    subprocess.run([sys.executable, str(HERE / "solve_blend.py"), str(blend), str(work / "settings.json"), str(pairs),
                    str(work / "solve.npz")], capture_output=True, text=True, check=True)
    return dict(np.load(work / "solve.npz"))


def per_surface(blend, overrides: dict, work, min_pairs: int = MIN_PAIRS) -> list:
    data = dict(np.load(HERE / "references" / f"{blend.stem}.npz", allow_pickle=False))
    work.mkdir(parents=True, exist_ok=True)
    pairs = work / "pairs.npz"
    np.savez(pairs, **{k: data[k] for k in ("object", "polygon", "point", "eye")})
    valid = ~np.isin(data["object"], run_study.emitting_objects(describe(blend)))
    before = solve(blend, {"preset": "preview"}, work, pairs)
    after = solve(blend, {"preset": "preview", "overrides": overrides}, work, pairs)
    target = overrides.get("refine_to_error")
    rows = []
    for k, index in enumerate(before["receivers"]):
        measured = []
        for s in (before, after):
            seen = valid & (s["surface"] == index) & np.isfinite(s["radiance"]).all(axis=1)
            measured.append((run_study.rel_rmse(s["radiance"], data["reference"], seen), int(seen.sum())))
        e0, e1 = float(before["estimated_error"][k]), float(after["estimated_error"][k])
        changed = (e0 > target or e1 != e0) if target is not None else measured[1][0] != measured[0][0]
        if measured[0][1] < min_pairs or not changed:
            continue
        rows.append({"scene": blend.stem, "surface": str(before["names"][k]), "pairs": measured[0][1],
                     "estimate": [e0, e1], "measured": [measured[0][0], measured[1][0]]})
        print(f"{blend.stem}: {rows[-1]['surface']}: estimate {e0:.4f} -> {e1:.4f}, measured {measured[0][0]:.4f} -> "
              f"{measured[1][0]:.4f} ({measured[0][1]} pairs)", flush=True)
    return rows


if __name__ == "__main__":
    args = sys.argv[1:]
    min_pairs = MIN_PAIRS
    if args[:1] == ["--pairs"]:
        min_pairs, args = int(args[1]), args[2:]
    overrides = json.loads(args[0])
    rows = [row for blend in run_study.scenes(args[1:] or None) if (HERE / "references" / f"{blend.stem}.npz").exists()
            for row in per_surface(blend, overrides, run_study.ROOT / "build" / f"study_refine_{os.getpid()}", min_pairs)]
    print(json.dumps(rows))
