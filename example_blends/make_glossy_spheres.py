"""Generates glossy_spheres.blend beside this file (the paper's figures 9 and 11): an isotropic
and an anisotropic metal sphere, exact NURBS surfaces, on a table under a light bulb, an emissive
NURBS surface of revolution. The add-on solves the brushed gold as anisotropic GGX with its
tangent along each surface's u direction (ds/du). Run with the `bpy` module:

    .venv/bin/python example_blends/make_glossy_spheres.py [--if-missing] [--out-dir DIR]
"""
from __future__ import annotations

import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # scene_parts, also under runpy
from scene_parts import (arc_profile, camera, diffuse_material, emission_material, empty_scene, main,  # noqa: E402
                         principled_material, quad_object, rectangle, render_settings, revolution_object)

RADIUS = 0.35
BULB_RADIUS = 0.15


def sphere_profile(radius):
    """Bottom pole to top pole: half a circle in two quarters (as Blender's NURBS sphere)."""
    return arc_profile(0.0, radius, math.pi, 0.0, 2)


def bulb_profile():
    """A hanging bulb, bottom to top: a globe of BULB_RADIUS up to 40 degrees from its top, a
    conical neck to the cap, the cap closing on the axis. Quadratic Bézier pieces throughout."""
    rows = arc_profile(0.0, BULB_RADIUS, math.pi, math.radians(40), 3)
    r0, z0, _ = rows[-1]
    neck = (0.055, 0.26)
    rows.append(((r0 + neck[0]) / 2, (z0 + neck[1]) / 2, 1.0))
    rows.append((*neck, 1.0))
    rows.append((neck[0] / 2, neck[1], 1.0))
    rows.append((0.0, neck[1], 1.0))
    return rows


def build():
    scene = empty_scene()
    wood = diffuse_material("Table", (0.45, 0.32, 0.22))
    wall = diffuse_material("Wall", (0.6, 0.6, 0.6))
    quad_object("Table", [rectangle(0, 0, 0, 4.0, 2.0)], [wood], [0])
    quad_object("Backdrop", [[(-2.0, 1.0, 0), (2.0, 1.0, 0), (2.0, 1.0, 2.5), (-2.0, 1.0, 2.5)]], [wall], [0])
    # Metals (GGX reflection, f0 = base colour); the same roughness, one brushed (Anisotropic).
    silver = principled_material("Silver", (0.9, 0.9, 0.92), Metallic=1.0, Roughness=0.6)
    gold = principled_material("Brushed gold", (1.0, 0.76, 0.33), Metallic=1.0, Roughness=0.6, Anisotropic=0.8)
    revolution_object("Isotropic sphere", sphere_profile(RADIUS), silver, centre=(-0.5, 0.1, RADIUS))
    revolution_object("Anisotropic sphere", sphere_profile(RADIUS), gold, centre=(0.5, 0.1, RADIUS))
    # Emission shader strength is the radiance: about 6 W/m^2 of irradiance on the table below.
    bulb = emission_material("Bulb", (1.0, 0.85, 0.65), 80.0)
    revolution_object("Bulb", bulb_profile(), bulb, centre=(0.0, -0.3, 1.0))
    camera((0.0, -3.4, 1.2), (0.0, 0.0, 0.6), lens=45)
    return render_settings(scene, (640, 480))


# The .blend files this script writes, and the function building each scene.
BUILDERS = {"glossy_spheres.blend": build}

if __name__ == "__main__":
    main(BUILDERS)
