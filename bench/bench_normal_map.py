"""The cost of a normal map: a washboard-bumped floor and back wall (tests/blender/test_normal_maps.py's
ridges of +-35 degrees, a Diffuse BSDF under a tangent-space Normal Map) under a sun and a grey
world, solved by the add-on at each preset with 4 bounces, against the same scene with the Normal
Map unlinked (flat: 2D splines), in a fresh bpy process each. A bumped surface's radiance is 4D
over its bumped normal (bsgi.BumpedLambert): the figures are what that costs.

Figures per preset: seconds and coefficients, bumped and flat, and their ratios; the bumped
floor's angular coefficients."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from blender_process import run_script  # noqa: E402

SCRIPT = """
import json, math, os, sys, time
sys.path[:0] = [sys.argv[1], sys.argv[2], os.path.dirname(sys.argv[2])]  # the add-on, the tests' scenes
import cli
cli.load_addon().register()
import bpy
from bsgi_addon import pipeline
from test_normal_maps import bumped_material, floor_under_sun, washboard
from test_textures import add_uv_quad

bpy.ops.wm.read_factory_settings(use_empty=True)
context = bpy.context
material = bumped_material("Washboard", washboard)
floor_under_sun(context, material)
add_uv_quad("Wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], material)
if sys.argv[4] == "flat":
    tree = material.node_tree
    for link in list(tree.links):
        if link.to_socket.name == "Normal":
            tree.links.remove(link)
world = bpy.data.worlds.new("Grey")
if world.node_tree is None:
    world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.3, 0.3, 1)
context.scene.world = world
context.scene.bsgi.preset = sys.argv[3]
start = time.perf_counter()
job = pipeline.prepare(context)
solution = pipeline.run(job)
seconds = time.perf_counter() - start
shape = [r["shape"] for r in solution.reports if r["shape"]]
print(json.dumps({"seconds": seconds, "coefficients": int(solution.stats["coefficients"]), "shapes": shape}))
"""


def in_blender(preset: str, variant: str) -> dict:
    return run_script(SCRIPT, preset, variant)


def run() -> dict:
    figures = {}
    for preset in ("DRAFT", "PREVIEW", "FINAL"):
        key = f"normal_map_{preset.lower()}"
        bumped, flat = in_blender(preset, "bumped"), in_blender(preset, "flat")
        figures[f"{key}_seconds"] = round(bumped["seconds"], 2)
        figures[f"{key}_flat_seconds"] = round(flat["seconds"], 2)
        figures[f"{key}_seconds_ratio"] = round(bumped["seconds"] / flat["seconds"], 2)
        figures[f"{key}_coefficients"] = bumped["coefficients"]
        figures[f"{key}_flat_coefficients"] = flat["coefficients"]
        figures[f"{key}_angular"] = max(s[2] for s in bumped["shapes"] if len(s) == 4)
    return figures


if __name__ == "__main__":
    for key, value in run().items():
        print(f"{key}: {value}")
