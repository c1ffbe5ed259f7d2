"""Generates the Cornell boxes beside this file: cornell_box.blend (the demo: quads with diffuse
coloured materials, two boxes, one rectangular area light, a camera) and cornell_box_glossy.blend
(the same box with the tall box in brushed copper, a Principled metal). Run with the `bpy` module:

    .venv/bin/python example_blends/make_cornell_box.py [--if-missing] [--out-dir DIR]
"""
from __future__ import annotations

import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # scene_parts, also under runpy
from scene_parts import (area_light, box_quads, camera, diffuse_material, empty_scene, main,  # noqa: E402
                         principled_material, quad_object, render_settings)

HERE = pathlib.Path(__file__).resolve().parent
OUT = HERE / "cornell_box.blend"


def build(glossy=False):
    scene = empty_scene()
    white = diffuse_material("White", (0.73, 0.73, 0.73))
    red = diffuse_material("Red", (0.63, 0.065, 0.05))
    green = diffuse_material("Green", (0.14, 0.45, 0.091))
    # Room: x, y in [-1, 1], z in [0, 2], open towards the camera at y = -1.
    room = [
        [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],  # floor, normal +z
        [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)],  # ceiling, normal -z
        [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)],  # back, normal -y
        [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)],  # left, normal +x
        [(1, 1, 0), (1, -1, 0), (1, -1, 2), (1, 1, 2)],  # right, normal -x
    ]
    quad_object("Room", room, [white, red, green], [0, 0, 0, 1, 2])
    # Copper: a metal (GGX reflection with the base colour as f0), rough enough for the
    # angular splines to resolve its lobe at the preview preset.
    tall = principled_material("Copper", (0.95, 0.64, 0.54), Metallic=1.0, Roughness=0.6) if glossy else white
    quad_object("TallBox", box_quads(-0.35, 0.35, 0.6, 0.6, 1.2, math.radians(-17)), [tall], [0] * 6)
    quad_object("ShortBox", box_quads(0.35, -0.35, 0.6, 0.6, 0.6, math.radians(17)), [white], [0] * 6)
    area_light("Light", (0, 0, 1.98), 30.0, size=0.5, size_y=0.4)  # emits along -z, just below the ceiling
    camera((0, -3.6, 1.0), (0, 0, 1.0), lens=45)
    return render_settings(scene)


# The .blend files this script writes, and the function building each scene.
BUILDERS = {"cornell_box.blend": build, "cornell_box_glossy.blend": lambda: build(glossy=True)}

if __name__ == "__main__":
    main(BUILDERS)
