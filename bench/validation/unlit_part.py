"""An object's radiance spline over the part of it that no light reaches, where the exact radiance
is 0: the Mitsuba pairs cannot judge it (their eyes must be in open space, and an eye outside a
room sees the walls' backs), while the error estimate's checks, which count whatever a viewer
anywhere could see, do. open_box's GGX panel passes 14 cm through the left wall: 5% of it lies
outside the box, lit by nothing (the world is black, the walls' backs unlit).

    .venv/bin/python bench/validation/unlit_part.py SCENE OBJECT --outside XMIN XMAX YMIN YMAX ZMIN ZMAX [--overrides JSON]

Solves the validation scene at the final preset (with the overrides), evaluates the object's
splines on a 200 x 200 grid of each surface's parameters (area-weighted) in 8 cosine-distributed
directions a side, and prints a JSON line: per surface the fraction of its area outside the box
(where the caller says no light reaches), the RMS of the spline there over the surface's mean
radiance inside, that RMS's share of the whole surface's relative RMS error (the error the spline
has there, over the surface), and the solver's estimate with its parts.
"""
from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "study"))

GRID = 200
DIRECTIONS = 8


def cosine_directions(side: float) -> np.ndarray:
    """DIRECTIONS local directions on a side (+1 front, -1 back), cosine-distributed."""
    w = (np.arange(DIRECTIONS) + 0.5) / DIRECTIONS
    phi = 2 * np.pi * ((np.arange(DIRECTIONS) * 0.6180339887498949 + 0.3) % 1.0)
    return np.c_[np.sqrt(1 - w) * np.cos(phi), np.sqrt(1 - w) * np.sin(phi), side * np.sqrt(w)]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene")
    parser.add_argument("object")
    parser.add_argument("--outside", nargs=6, type=float, required=True, metavar=("XMIN", "XMAX", "YMIN", "YMAX", "ZMIN", "ZMAX"),
                        help="the box outside which no light reaches the object")
    parser.add_argument("--overrides", help="solver settings over the final preset's, as JSON")
    args = parser.parse_args(argv)

    import bsgi
    from solve_blend import open_and_export

    spec = {"preset": "final", "overrides": json.loads(args.overrides) if args.overrides else {}}
    export, settings = open_and_export(HERE / "scenes" / f"{args.scene}.blend", spec)
    solution = bsgi.solve(export.scene, settings)
    reports = {r["name"]: r for r in solution.reports}
    lo, hi = np.array(args.outside[0::2]), np.array(args.outside[1::2])
    g = (np.arange(GRID) + 0.5) / GRID
    uv = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    out = {}
    for i, spline in enumerate(solution.surfaces):
        name = export.scene.name(i)
        if spline is None or not name.startswith(args.object + ":"):
            continue
        geometry = export.scene.surface(i).evaluate(uv)
        area = np.asarray(geometry["jacobian"])
        position = np.asarray(geometry["position"])
        outside = np.any((position < lo) | (position > hi), axis=1)
        # Mean over RGB, per direction and point; both sides (a side the solver does not solve
        # evaluates to 0 and is left out).
        values = [spline.evaluate(uv, np.tile(d, (len(uv), 1))).mean(axis=1)
                  for side in (1.0, -1.0) for d in cosine_directions(side)]
        values = np.array([v for v in values if np.any(v != 0)])
        weight = np.broadcast_to(area, values.shape)
        inside_mean = float((values * weight)[:, ~outside].sum() / weight[:, ~outside].sum())
        outside_ms = float((values ** 2 * weight)[:, outside].sum() / max(weight[:, outside].sum(), 1e-300))
        fraction = float(area[outside].sum() / area.sum())
        report = reports[name]
        out[name] = {"outside_fraction": fraction,
                     "outside_rms_over_mean": np.sqrt(outside_ms) / inside_mean,
                     "outside_share": np.sqrt(outside_ms * fraction) / inside_mean,
                     "estimated_error": report["estimated_error"], "error_parts": report["error_parts"],
                     "shape": list(report["shape"])}
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
