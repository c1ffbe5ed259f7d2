"""Generates bezier_patches.blend beside this file: NURBS surface objects in Bézier mode
(use_bezier_u/v, order 4, so each 4 x 4 block of points is a bicubic Bézier patch): a vase, one
object of four patches (the Utah teapot's body is made the same way), a cove backdrop sweeping
from floor to wall, and a wavy metal sheet of two patches in one spline. Run with the `bpy`
module:

    .venv/bin/python example_blends/make_bezier_patches.py [--if-missing] [--out-dir DIR]
"""
from __future__ import annotations

import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # scene_parts, also under runpy
from scene_parts import (area_light, camera, diffuse_material, empty_scene, join, main,  # noqa: E402
                         nurbs_object, principled_material, render_settings)

# A cubic Bézier quarter circle: inner control points at this fraction of the radius along the tangents.
QUARTER = 4 / 3 * math.tan(math.pi / 8)
# The vase's profile, (radius, height), bottom to top: one cubic Bézier segment.
VASE_PROFILE = [(0.25, 0.0), (0.62, 0.25), (0.05, 0.8), (0.22, 1.0)]


def bezier_patch(name, points, material):
    """points: (count_v, count_u, 3), counts 3k + 1; Blender's face normal is -(s_u x s_v)."""
    rows = [[(*p, 1.0) for p in row] for row in points]
    return nurbs_object(name, rows, 4, 4, material, endpoint=(True, True), bezier=(True, True))


def vase_quarter(k, centre):
    """Quarter k of the vase, counter-clockwise from angle 90 k degrees: u up the profile, v
    around, so the normals face outwards."""
    cx, cy = centre
    a0, a1 = k * math.pi / 2, (k + 1) * math.pi / 2
    # The quarter arc of the unit circle as (x, y) control points.
    p0 = (math.cos(a0), math.sin(a0))
    p3 = (math.cos(a1), math.sin(a1))
    p1 = (p0[0] - QUARTER * p0[1], p0[1] + QUARTER * p0[0])
    p2 = (p3[0] + QUARTER * p3[1], p3[1] - QUARTER * p3[0])
    return [[(cx + r * x, cy + r * y, z) for r, z in VASE_PROFILE] for x, y in (p0, p1, p2, p3)]


def cove():
    """Floor to wall in one bicubic patch: u from +x to -x, v from the front up the wall, facing the room."""
    sweep = [(-1.4, 0.0), (0.7, 0.0), (1.4, 0.3), (1.4, 1.8)]  # (y, z)
    xs = [2.7, 0.9, -0.9, -2.7]
    return [[(x, y, z) for x in xs] for y, z in sweep]


def wave():
    """Two bicubic patches side by side (7 x 4 points), a sheet standing on the floor and leaning
    back, waving along x; u from +x to -x, v up, so it faces the camera (-y)."""
    rows = []
    for j in range(4):
        z = 0.8 * j / 3
        rows.append([(1.35 - 0.9 * i / 6, 0.1 + 0.25 * z + 0.12 * math.sin(2 * math.pi * i / 6), z) for i in range(7)])
    return rows


def build():
    scene = empty_scene()
    plaster = diffuse_material("Plaster", (0.7, 0.7, 0.68))
    terracotta = diffuse_material("Terracotta", (0.75, 0.38, 0.22))
    steel = principled_material("Steel", (0.8, 0.83, 0.87), Metallic=1.0, Roughness=0.6)
    bezier_patch("Cove", cove(), plaster)
    # One object of four splines, as the Utah teapot's body is one set of patches.
    join("Vase", [bezier_patch(f"Vase {k + 1}", vase_quarter(k, (-0.45, 0.1)), terracotta) for k in range(4)])
    bezier_patch("Wave", wave(), steel)
    area_light("Light", (-0.6, -0.8, 2.0), 60.0, size=0.6, size_y=0.4, rotation=(math.radians(-20), 0.0, 0.0))
    camera((0.2, -3.4, 1.5), (0.2, 0.1, 0.45), lens=42)
    return render_settings(scene, (640, 480))


# The .blend files this script writes, and the function building each scene.
BUILDERS = {"bezier_patches.blend": build}

if __name__ == "__main__":
    main(BUILDERS)
