"""Rays per small surface with refinement (SolverSettings.refine_to_error) on the boxes of
tests/core/test_solver_effort.py at the preview preset: (rays with the boxes - rays of the floor
alone) / box faces, over all passes; and the surfaces refined. Prints one line per setting.

    python bench/refine_boxes.py
"""
import pathlib
import sys
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests" / "core"))
import bsgi
from test_solver_effort import scene_of, BOX, CENTRES, UNIFORM, ADAPTIVE
boxes = [(x, y, BOX, BOX) for x, y in CENTRES]
faces = 5 * len(boxes)
def rays(sol):
    return getattr(sol, "refinement", sol.stats)["rays"]
def solve(scene, **o):
    s = bsgi.SolverSettings.preset("preview")
    for k, v in o.items(): setattr(s, k, v)
    return bsgi.solve(scene, s)
for name, o in (("uniform", UNIFORM), ("adaptive", ADAPTIVE),
                ("D: 8+adaptive+refine0.03x1", dict(ADAPTIVE, spatial_coeffs=8, refine_to_error=0.03, refine_passes=1)),
                ("adaptive+refine0.05", dict(ADAPTIVE, refine_to_error=0.05)),
                ("adaptive+refine0.02", dict(ADAPTIVE, refine_to_error=0.02)),
                ("adaptive+refine0.03x1", dict(ADAPTIVE, refine_to_error=0.03, refine_passes=1))):
    alone = solve(scene_of([]), **o)
    sol = solve(scene_of(boxes), **o)
    ref = getattr(sol, "refinement", None)
    print(name, "rays per box face", (rays(sol) - rays(alone)) / faces,
          "alone passes", getattr(alone, "refinement", {}).get("passes"),
          "passes", ref and ref["passes"], "refined", ref and [(s["name"], s["shape"], round(s["estimated_error"], 4)) for s in ref["surfaces"] if s["refined"]],
          "max est", max(r["estimated_error"] for r in sol.reports if r["estimated_error"] == r["estimated_error"]), flush=True)
