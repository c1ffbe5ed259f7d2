"""Curved emitters: what a point light's sphere costs against a flat light of its size.

A room (floor, wall, a box) lit by three point lights, solved as exact NURBS spheres of radius
5 cm (their cells checked against their quarters: gather.cpp), and the same room with each
sphere replaced by a square of the sphere's cross-section facing down (flat: its cells are not
checked). Rays and seconds at the preview and final presets, and the ratio of the spheres' rays to
the squares' in this run. (Their accuracy against closed forms: tests/core/test_solver_direct.py.)
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import bsgi

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "core"))
from nurbs_reference import SPHERE_FLAGS, blender_sphere_points  # noqa: E402

RADIUS = 0.05
LIGHTS = [(-1.5, 0.0, 2.0), (1.5, 1.0, 1.2), (0.5, -2.0, 0.5)]


def room(spheres: bool) -> bsgi.Scene:
    scene = bsgi.Scene()
    quad = lambda name, q, **kw: scene.add_bilinear_patch(name, np.array(q, float), **kw)  # noqa: E731
    quad("floor", [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], albedo=[0.5] * 3, emission=[0] * 3)
    quad("wall", [[-3, 3, 0], [-3, 3, 3], [3, 3, 3], [3, 3, 0]], albedo=[0.5] * 3, emission=[0] * 3)
    x0, y0, x1, y1, z1 = -0.5, -0.5, 0.5, 0.5, 0.8
    for name, q in {"top": [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
                    "px": [[x1, y0, 0], [x1, y1, 0], [x1, y1, z1], [x1, y0, z1]],
                    "nx": [[x0, y0, 0], [x0, y0, z1], [x0, y1, z1], [x0, y1, 0]],
                    "py": [[x0, y1, 0], [x0, y1, z1], [x1, y1, z1], [x1, y1, 0]],
                    "ny": [[x0, y0, 0], [x1, y0, 0], [x1, y0, z1], [x0, y0, z1]]}.items():
        quad(f"box {name}", q, albedo=[0.6] * 3, emission=[0] * 3)
    for i, c in enumerate(LIGHTS):
        if spheres:
            points = blender_sphere_points(RADIUS)
            points[:, :3] += c
            scene.add_surface(bsgi.NurbsSurface(f"light {i}", points, front="blender", **SPHERE_FLAGS), albedo=[0] * 3,
                              emission=[1000] * 3, receiver=False)
        else:
            h = 0.5 * np.sqrt(np.pi) * RADIUS  # a square of the sphere's cross-section, facing down
            x, y, z = c
            quad(f"light {i}", [[x - h, y - h, z], [x - h, y + h, z], [x + h, y + h, z], [x + h, y - h, z]],
                 albedo=[0] * 3, emission=[1000] * 3, receiver=False)
    return scene


def run() -> dict:
    out = {}
    for preset in ("preview", "final"):
        rays = {}
        for spheres in (True, False):
            s = bsgi.SolverSettings.preset(preset)
            s.threads = 2
            t = time.perf_counter()
            sol = bsgi.solve(room(spheres), s)
            kind = "spheres" if spheres else "squares"
            out[f"curved_emitters_{kind}_{preset}_seconds"] = time.perf_counter() - t
            out[f"curved_emitters_{kind}_{preset}_rays"] = rays[kind] = sol.stats["rays"]
        out[f"curved_emitters_{preset}_rays_ratio"] = rays["spheres"] / rays["squares"]
    return out
