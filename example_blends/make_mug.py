"""Generates mug.blend beside this file (the paper's figure 10): a mug of two NURBS surfaces, the
cup (a surface of revolution: outer wall, rim, inner wall and bottom in one spline) and the
handle (a tube swept along a C-shaped curve), in a closed white room lit by an area light that
faces the ceiling: almost all the light is indirect. Run with the `bpy` module:

    .venv/bin/python example_blends/make_mug.py [--if-missing] [--out-dir DIR]
"""
from __future__ import annotations

import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # scene_parts, also under runpy
from scene_parts import (area_light, camera, diffuse_material, empty_scene, main, quad_object,  # noqa: E402
                         render_settings, revolution_object, tube_object)

# The cup's profile, (radius, height), from the outer bottom's centre up the outside, over the
# rim and down the inside to the inner bottom's centre: an open quadratic NURBS curve, so the
# control polygon's corners are rounded. Upwards outside, downwards inside: normals face out of
# the mug's wall on both sides.
CUP_PROFILE = [(0.0, 0.0), (0.3, 0.0), (0.4, 0.0), (0.4, 0.1), (0.4, 0.5), (0.4, 0.9), (0.4, 0.95), (0.37, 0.95),
               (0.37, 0.9), (0.37, 0.5), (0.37, 0.1), (0.37, 0.05), (0.3, 0.05), (0.0, 0.05)]
# The handle's centre line in the (x, z) plane, ends sunk into the cup's wall.
HANDLE_PATH = [(0.36, 0, 0.75), (0.55, 0, 0.8), (0.68, 0, 0.7), (0.7, 0, 0.5), (0.66, 0, 0.32), (0.52, 0, 0.22),
               (0.36, 0, 0.26)]


def build():
    scene = empty_scene()
    white = diffuse_material("White", (0.8, 0.8, 0.8))
    floor = diffuse_material("Floor", (0.6, 0.5, 0.4))
    glaze = diffuse_material("Glaze", (0.2, 0.4, 0.75))
    # Room: x, y in [-2, 2], z in [0, 2.4], closed; every wall faces inwards.
    a, h = 2.0, 2.4
    room = [
        [(-a, -a, 0), (a, -a, 0), (a, a, 0), (-a, a, 0)],  # floor
        [(-a, -a, h), (-a, a, h), (a, a, h), (a, -a, h)],  # ceiling
        [(-a, a, 0), (a, a, 0), (a, a, h), (-a, a, h)],  # back
        [(-a, -a, 0), (-a, a, 0), (-a, a, h), (-a, -a, h)],  # left
        [(a, a, 0), (a, -a, 0), (a, -a, h), (a, a, h)],  # right
        [(a, -a, 0), (-a, -a, 0), (-a, -a, h), (a, -a, h)],  # front, behind the camera
    ]
    quad_object("Room", room, [white, floor], [1, 0, 0, 0, 0, 0])
    revolution_object("Cup", [(r, z, 1.0) for r, z in CUP_PROFILE], glaze, order=3, bezier=False)
    tube_object("Handle", HANDLE_PATH, 0.05, glaze)
    # Facing the ceiling (rotated half a turn: area lights emit along their local -z).
    area_light("Light", (-0.4, 0.6, 1.2), 60.0, size=0.6, rotation=(math.pi, 0.0, 0.0))
    camera((0.8, -1.85, 1.35), (0.1, 0.0, 0.45), lens=35)
    return render_settings(scene, (640, 480))


# The .blend files this script writes, and the function building each scene.
BUILDERS = {"mug.blend": build}

if __name__ == "__main__":
    main(BUILDERS)
