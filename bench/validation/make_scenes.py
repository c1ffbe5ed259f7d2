"""Generates the validation scenes (issue 15) beside this file, scenes unlike the study's on which
the solver was never tuned. Run with the `bpy` module:

    .venv/bin/python bench/validation/make_scenes.py [--if-missing] [--out-dir DIR]

- open_box: a box with no front wall, a tilted GGX panel (alpha 0.3, a single plane reflecting on
  both sides) standing inside and a block resting on the floor, lit by a square area light;
- table_spheres: a diffuse and a GGX (alpha 0.3) sphere, exact NURBS, resting on a table plane
  (contact points) under a tilted rectangular light;
- ceiling_light: a closed room whose light hangs 5 cm below the ceiling facing down (the ceiling is
  lit only indirectly, and close to the light), a low block on the floor;
- thin_occluder: a single square plane reflecting on both sides over a floor (seen from above and
  below), a large wall beside a small one (the small wall's back sees the end of the large one).
- leaning_board (added 3 December, after the others' figures were known): a corner of two walls of
  very different sizes, a board (one plane, both sides seen) leaning on the large wall, a box turned
  30 degrees on the floor (oblique contact lines and shadow edges), under a tilted light.

Each scene's surfaces are separate objects, so the per-object errors are per surface. TWO_SIDED
names, per scene, the objects whose back side is lit and seen: the references render them with
Mitsuba's `twosided` (Cycles shades every surface's back; the other objects' backs see no light).
"""
from __future__ import annotations

import math
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(ROOT / "example_blends"))
sys.path.insert(0, str(ROOT / "bench" / "study" / "scenes"))

# The objects seen (and lit) from both sides, per scene: references.py samples pairs on both their
# sides and Mitsuba renders them two-sided.
TWO_SIDED = {"open_box": ["Panel"], "table_spheres": [], "ceiling_light": [], "thin_occluder": ["Occluder", "Small wall"],
             "leaning_board": ["Board", "Narrow wall"]}
# GGX alpha 0.3 (the "GGX >= 0.3"; Blender's roughness is sqrt(alpha)).
GGX_ROUGHNESS = math.sqrt(0.3)
# White metals: Cycles' Glossy BSDF is its colour times GGX with no Fresnel, the solver uses Schlick's
# Fresnel from f0 = colour and the study's Mitsuba converter a conductor of that f0 (k = 0): the
# three agree only at f0 = 1. With the colours first used (f0 0.95/0.85/0.7 and 0.9/0.75/0.5) the
# GGX panel and sphere were 2.3% and 3.1% brighter than Mitsuba, mostly the two Fresnel curves'
# difference (README, "Validation scenes").
WHITE_METAL = (1.0, 1.0, 1.0)


def _bpy_parts():
    from make_cornell_box_glossy import glossy_material  # the study's Glossy BSDF (GGX, not multiscatter)
    from scene_parts import area_light, box_quads, diffuse_material, empty_scene, quad_object, rectangle, render_settings

    return glossy_material, area_light, box_quads, diffuse_material, empty_scene, quad_object, rectangle, render_settings


def coloured_glossy(name, rgb, roughness):
    glossy_material = _bpy_parts()[0]
    m = glossy_material(name, roughness)
    bsdf = next(n for n in m.node_tree.nodes if n.type != "OUTPUT_MATERIAL")
    bsdf.inputs["Color"].default_value = (*rgb, 1.0)
    return m


def build_open_box():
    _, area_light, box_quads, diffuse, empty_scene, quad_object, _, render_settings = _bpy_parts()
    scene = empty_scene()
    white, red, green = (diffuse("White", (0.7, 0.7, 0.7)), diffuse("Red", (0.6, 0.2, 0.15)),
                         diffuse("Green", (0.2, 0.5, 0.25)))
    # x, y in [-1, 1], z in [0, 2]; no wall at y = -1. Each wall an object, normals inwards.
    quad_object("Floor", [[(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]], [white], [0])
    quad_object("Ceiling", [[(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)]], [white], [0])
    quad_object("Back", [[(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)]], [white], [0])
    quad_object("Left", [[(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)]], [red], [0])
    quad_object("Right", [[(1, 1, 0), (1, -1, 0), (1, -1, 2), (1, 1, 2)]], [green], [0])
    # The panel: 0.8 m wide, 1.1 m long, its lower edge on the floor, leaning back 30 degrees from
    # upright and turned 35 degrees about z towards the box's middle.
    turn, lean, w, h = math.radians(35), math.radians(30), 0.8, 1.1
    centre = (-0.5, 0.35)
    ex = (math.cos(turn), math.sin(turn), 0.0)  # along the lower edge
    up = (-math.sin(turn) * math.sin(lean), math.cos(turn) * math.sin(lean), math.cos(lean))  # leaning back (+y)
    p0 = (centre[0] - ex[0] * w / 2, centre[1] - ex[1] * w / 2, 0.0)
    p1 = (centre[0] + ex[0] * w / 2, centre[1] + ex[1] * w / 2, 0.0)
    panel = [p0, p1, tuple(p1[i] + up[i] * h for i in range(3)), tuple(p0[i] + up[i] * h for i in range(3))]
    quad_object("Panel", [panel], [coloured_glossy("Panel GGX", WHITE_METAL, GGX_ROUGHNESS)], [0])
    quad_object("Block", box_quads(0.35, -0.1, 0.45, 0.45, 0.6, math.radians(20)),
                [diffuse("Block", (0.6, 0.6, 0.65))], [0] * 6)
    area_light("Light", (0.1, 0.0, 1.9), 45.0, shape="SQUARE", size=0.45)
    return render_settings(scene)


def build_table_spheres():
    from make_glossy_spheres import sphere_profile
    from scene_parts import revolution_object

    _, area_light, _, diffuse, empty_scene, quad_object, rectangle, render_settings = _bpy_parts()
    scene = empty_scene()
    quad_object("Table", [rectangle(0, 0, 0, 3.0, 2.0)], [diffuse("Table", (0.55, 0.5, 0.45))], [0])
    radius = 0.3
    revolution_object("Diffuse sphere", sphere_profile(radius), diffuse("Plaster", (0.75, 0.75, 0.75)),
                      centre=(-0.45, 0.0, radius))
    revolution_object("GGX sphere", sphere_profile(radius), coloured_glossy("Sphere GGX", WHITE_METAL, GGX_ROUGHNESS),
                      centre=(0.45, 0.0, radius))
    # Tilted 40 degrees about x, in front of and above the spheres, facing them.
    area_light("Light", (0.3, -1.0, 1.3), 60.0, size=0.8, size_y=0.5, rotation=(math.radians(40), 0.0, 0.0))
    return render_settings(scene)


def build_ceiling_light():
    _, area_light, box_quads, diffuse, empty_scene, quad_object, _, render_settings = _bpy_parts()
    scene = empty_scene()
    white, wall = diffuse("White", (0.75, 0.75, 0.75)), diffuse("Wall", (0.6, 0.55, 0.5))
    # x in [-1.5, 1.5], y in [-1.5, 1.5], z in [0, 2.5], closed, normals inwards.
    quad_object("Floor", [[(-1.5, -1.5, 0), (1.5, -1.5, 0), (1.5, 1.5, 0), (-1.5, 1.5, 0)]], [wall], [0])
    quad_object("Ceiling", [[(-1.5, -1.5, 2.5), (-1.5, 1.5, 2.5), (1.5, 1.5, 2.5), (1.5, -1.5, 2.5)]], [white], [0])
    quad_object("Walls", [[(-1.5, 1.5, 0), (1.5, 1.5, 0), (1.5, 1.5, 2.5), (-1.5, 1.5, 2.5)],
                          [(1.5, -1.5, 0), (-1.5, -1.5, 0), (-1.5, -1.5, 2.5), (1.5, -1.5, 2.5)],
                          [(-1.5, -1.5, 0), (-1.5, 1.5, 0), (-1.5, 1.5, 2.5), (-1.5, -1.5, 2.5)],
                          [(1.5, 1.5, 0), (1.5, -1.5, 0), (1.5, -1.5, 2.5), (1.5, 1.5, 2.5)]], [white], [0] * 4)
    quad_object("Block", box_quads(-0.5, 0.4, 0.7, 0.5, 0.4, math.radians(10)), [diffuse("Block", (0.5, 0.55, 0.6))],
                [0] * 6)
    area_light("Light", (0.3, -0.2, 2.45), 80.0, size=0.6, size_y=0.6)  # 5 cm below the ceiling, facing down
    return render_settings(scene)


def build_thin_occluder():
    _, area_light, _, diffuse, empty_scene, quad_object, rectangle, render_settings = _bpy_parts()
    scene = empty_scene()
    quad_object("Floor", [rectangle(0, 0, 0, 4.0, 4.0)], [diffuse("Floor", (0.7, 0.7, 0.7))], [0])
    # A single plane (no thickness) 0.8 m square, 0.6 m above the floor, turned 15 degrees.
    c, s, a = math.cos(math.radians(15)), math.sin(math.radians(15)), 0.4
    occluder = [(0.2 + c * x - s * y, 0.1 + s * x + c * y, 0.6) for x, y in ((-a, -a), (a, -a), (a, a), (-a, a))]
    quad_object("Occluder", [occluder], [diffuse("Occluder", (0.8, 0.75, 0.7))], [0])
    # A large wall (4 x 2.5 m) along the back and a small one (0.6 x 0.5 m) beside its right end.
    quad_object("Large wall", [[(-2, 2, 0), (2, 2, 0), (2, 2, 2.5), (-2, 2, 2.5)]], [diffuse("Large", (0.6, 0.6, 0.7))], [0])
    quad_object("Small wall", [[(1.7, 2.0, 0), (1.7, 1.4, 0), (1.7, 1.4, 0.5), (1.7, 2.0, 0.5)]],
                [diffuse("Small", (0.7, 0.6, 0.5))], [0])
    area_light("Light", (0.0, 0.0, 1.8), 40.0, shape="SQUARE", size=0.5)
    return render_settings(scene)


def build_leaning_board():
    _, area_light, box_quads, diffuse, empty_scene, quad_object, _, render_settings = _bpy_parts()
    scene = empty_scene()
    quad_object("Floor", [[(-2, -1.5, 0), (2, -1.5, 0), (2, 1.5, 0), (-2, 1.5, 0)]], [diffuse("Floor", (0.7, 0.68, 0.65))], [0])
    # A large wall (4 x 2.5 m) along the back, and across its left end a narrow one (0.8 x 0.9 m)
    # facing the room, its back lit by the floor behind it.
    quad_object("Large wall", [[(-2, 1.5, 0), (2, 1.5, 0), (2, 1.5, 2.5), (-2, 1.5, 2.5)]],
                [diffuse("Large", (0.65, 0.65, 0.7))], [0])
    quad_object("Narrow wall", [[(-1.6, 0.7, 0), (-1.6, 1.5, 0), (-1.6, 1.5, 0.9), (-1.6, 0.7, 0.9)]],
                [diffuse("Narrow", (0.7, 0.55, 0.45))], [0])
    # A board 1.3 m wide and 1 m long, its foot on the floor 0.5 m out, its top edge against the
    # large wall: its front faces the room, its back the wedge behind it.
    top = math.sqrt(1.0 - 0.5 ** 2)
    quad_object("Board", [[(-0.2, 1.0, 0), (1.1, 1.0, 0), (1.1, 1.499, top), (-0.2, 1.499, top)]],
                [diffuse("Board", (0.75, 0.7, 0.6))], [0])
    quad_object("Box", box_quads(-0.7, -0.3, 0.5, 0.5, 0.45, math.radians(30)), [diffuse("Box", (0.55, 0.6, 0.5))],
                [0] * 6)
    # 0.6 x 0.4 m, tilted 25 degrees about x towards the back wall.
    area_light("Light", (0.4, -0.6, 2.2), 60.0, size=0.6, size_y=0.4, rotation=(math.radians(25), 0.0, 0.0))
    return render_settings(scene)


BUILDERS = {"open_box.blend": build_open_box, "table_spheres.blend": build_table_spheres,
            "ceiling_light.blend": build_ceiling_light, "thin_occluder.blend": build_thin_occluder,
            "leaning_board.blend": build_leaning_board}

if __name__ == "__main__":
    from scene_parts import main

    argv = sys.argv[1:]
    main(BUILDERS, argv if "--out-dir" in argv else argv + ["--out-dir", str(HERE / "scenes")])
