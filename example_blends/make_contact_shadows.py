"""Generates contact_shadows.blend beside this file (the paper's figure 8): a box standing on a
floor, turned so its shadow edges run diagonal to the floor's knot lines, under a small square
area light: sharp shadow edges and contact lines, where tensor-product splines blur most. Run
with the `bpy` module:

    .venv/bin/python example_blends/make_contact_shadows.py [--if-missing] [--out-dir DIR]
"""
from __future__ import annotations

import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # scene_parts, also under runpy
from scene_parts import (area_light, box_quads, camera, diffuse_material, empty_scene, main,  # noqa: E402
                         quad_object, rectangle, render_settings)


def build():
    scene = empty_scene()
    grey = diffuse_material("Floor", (0.7, 0.7, 0.7))
    wall = diffuse_material("Wall", (0.55, 0.6, 0.7))
    clay = diffuse_material("Clay", (0.7, 0.45, 0.3))
    quad_object("Floor", [rectangle(0, 0.5, 0, 5.0, 4.0)], [grey], [0])
    quad_object("Wall", [[(-2.5, 2.5, 0), (2.5, 2.5, 0), (2.5, 2.5, 2.0), (-2.5, 2.5, 2.0)]], [wall], [0])
    quad_object("Box", box_quads(-0.1, 0.1, 0.6, 0.6, 0.7, math.radians(30)), [clay], [0] * 6)
    # A small light, high and to the side: a long shadow with a narrow penumbra.
    area_light("Light", (0.9, -0.6, 1.8), 20.0, shape="SQUARE", size=0.12)
    camera((0.3, -3.4, 2.4), (0.0, 0.1, 0.3), lens=40)
    return render_settings(scene, (640, 480))


# The .blend files this script writes, and the function building each scene.
BUILDERS = {"contact_shadows.blend": build}

if __name__ == "__main__":
    main(BUILDERS)
