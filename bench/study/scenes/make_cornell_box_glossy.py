"""Generates cornell_box_glossy.blend beside this file: example_blends/cornell_box.blend with a rough
metal back wall (Glossy BSDF, GGX, white, roughness sqrt(0.3): alpha = 0.3, the glossy case of
tests/reference/scene_spec.py), so the study has a glossy scene. Run with the `bpy` module:

    .venv/bin/python bench/study/scenes/make_cornell_box_glossy.py [--if-missing]
"""
from __future__ import annotations

import math
import pathlib
import sys

import bpy

HERE = pathlib.Path(__file__).resolve().parent
SOURCE = HERE.parents[2] / "example_blends" / "cornell_box.blend"
OUT = HERE / "cornell_box_glossy.blend"
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


def build():
    bpy.ops.wm.open_mainfile(filepath=str(SOURCE))
    room = bpy.data.objects["Room"]
    room.data.materials.append(glossy_material("Glossy back", math.sqrt(0.3)))
    room.data.polygons[BACK_FACE].material_index = len(room.data.materials) - 1


if __name__ == "__main__":
    if "--if-missing" in sys.argv and OUT.exists():
        sys.exit(0)
    build()
    bpy.ops.wm.save_as_mainfile(filepath=str(OUT))
    print(f"wrote {OUT}")
