"""The cost of textured materials (addon/textures.py): the Cycles bake of a Checker-driven base
colour over a grid of 16 x 16 faces, solved per face (a tile of Texture Texels per face) and as
one UV chart, at the default Texture Texels (in a fresh bpy process each)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import json, sys
import bpy
sys.path.insert(0, sys.argv[1])
import cli
cli.load_addon().register()
from bsgi_addon import export
bpy.ops.wm.read_factory_settings(use_empty=True)
m = bpy.data.materials.new("Checker")
tree = m.node_tree
bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
checker = tree.nodes.new("ShaderNodeTexChecker")
tree.links.new(tree.nodes.new("ShaderNodeTexCoord").outputs["UV"], checker.inputs["Vector"])
tree.links.new(checker.outputs["Color"], bsdf.inputs["Base Color"])
bpy.ops.mesh.primitive_grid_add(x_subdivisions=16, y_subdivisions=16, size=2)
grid = bpy.context.active_object
grid.data.materials.append(m)
grid.bsgi.mesh_surfaces = sys.argv[2]
light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "AREA"))
light.location = (0, 0, 2)
bpy.context.scene.collection.objects.link(light)
result = export.export_scene(bpy.context.evaluated_depsgraph_get())
print(json.dumps({"faces": len(grid.data.polygons), "seconds": result.textures["seconds"],
                  "texels": result.textures["texels"]}))
"""


def bake(mesh_surfaces: str) -> dict:
    with tempfile.TemporaryDirectory(prefix="bsgi-bench-home-") as home:
        out = subprocess.run([sys.executable, "-c", SCRIPT, str(ROOT / "addon"), mesh_surfaces], cwd=ROOT,
                             env={**os.environ, "HOME": home}, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def run() -> dict:
    faces, chart = bake("FACES"), bake("CHART")
    assert faces["faces"] == chart["faces"] == 256
    return {"texture_bake_256_faces_seconds": round(faces["seconds"], 3),
            "texture_bake_256_faces_texels": faces["texels"],
            "texture_bake_chart_seconds": round(chart["seconds"], 3),
            "texture_bake_chart_texels": chart["texels"]}


if __name__ == "__main__":
    for key, value in run().items():
        print(f"{key}: {value}")
