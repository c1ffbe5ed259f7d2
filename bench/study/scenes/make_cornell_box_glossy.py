"""Generates the study's glossy scenes beside this file: example_blends/cornell_box.blend with a
metal back wall (Glossy BSDF, GGX, white): cornell_box_glossy_wall.blend with roughness sqrt(0.3)
(alpha = 0.3, the glossy case of tests/reference/scene_spec.py) and cornell_box_mirror_wall.blend
with roughness 0.1 (alpha = 0.01: below what the add-on solves, 0.2, so it shows that limit).
Run with the `bpy` module:

    .venv/bin/python bench/study/scenes/make_cornell_box_glossy.py [--if-missing]
"""
from __future__ import annotations

import math
import pathlib
import sys

import bpy

HERE = pathlib.Path(__file__).resolve().parent
SOURCE = HERE.parents[2] / "example_blends" / "cornell_box.blend"
ROUGHNESS = {"cornell_box_glossy_wall.blend": math.sqrt(0.3), "cornell_box_mirror_wall.blend": 0.1}
BACK_FACE = 2  # the Room's back wall in make_cornell_box.py


def glossy_material(name, roughness):
    m = bpy.data.materials.new(name)
    nodes = m.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfAnisotropic")  # the Glossy BSDF
    bsdf.distribution = "GGX"  # not Multiscatter GGX: the single-scattering lobe Mitsuba and the solver use
    bsdf.inputs["Color"].default_value = (1, 1, 1, 1)
    bsdf.inputs["Roughness"].default_value = roughness
    m.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return m


def build(roughness):
    bpy.ops.wm.open_mainfile(filepath=str(SOURCE))
    room = bpy.data.objects["Room"]
    room.data.materials.append(glossy_material("Glossy back", roughness))
    room.data.polygons[BACK_FACE].material_index = len(room.data.materials) - 1


if __name__ == "__main__":
    for name, roughness in ROUGHNESS.items():
        out = HERE / name
        if "--if-missing" in sys.argv and out.exists():
            continue
        build(roughness)
        bpy.ops.wm.save_as_mainfile(filepath=str(out))
        print(f"wrote {out}")
