"""EEVEE renders headless through Mesa's software EGL (the packages `make test` installs).

Run in a child process: without a working EGL driver Blender aborts instead of raising."""
import pytest

from subprocess_render import run_bpy

RENDER_LIT_PLANE = """\
import os, sys
import bpy
import numpy as np

bpy.ops.wm.read_factory_settings(use_empty=True)  # no world: the background is black
scene = bpy.context.scene
engines = scene.render.bl_rna.properties["engine"].enum_items.keys()
scene.render.engine = "BLENDER_EEVEE" if "BLENDER_EEVEE" in engines else "BLENDER_EEVEE_NEXT"  # 5.x / 4.x
scene.render.resolution_x = scene.render.resolution_y = 32
scene.render.resolution_percentage = 100
# Four samples, not the default 64 (each about 0.8 s on llvmpipe): one left an eighth of the
# frame dark (lit 0.88, against 0.997 at four and at 64).
scene.eevee.taa_render_samples = 4

bpy.ops.mesh.primitive_plane_add(size=2)
bpy.ops.object.light_add(type="SUN", location=(0, 0, 3))
bpy.context.object.data.energy = 3.0
bpy.ops.object.camera_add(location=(0, 0, 3))  # looks down -Z at the plane, which fills the view
scene.camera = bpy.context.object

scene.render.filepath = os.path.join(sys.argv[3], "frame.png")
bpy.ops.render.render(write_still=True)
pixels = np.array(bpy.data.images.load(scene.render.filepath).pixels[:]).reshape(-1, 4)[:, :3]
result = {"engine": scene.render.engine, "mean": float(pixels.mean()), "lit": float((pixels.max(axis=1) > 0.05).mean())}
"""


@pytest.mark.slow
def test_eevee_renders_a_lit_plane_in_a_subprocess(tmp_path):
    run = run_bpy(RENDER_LIT_PLANE, args=[str(tmp_path)])
    assert run.ok, run.log
    print(f"EEVEE 32x32 frame: {run.result}")
    assert run.result["engine"].startswith("BLENDER_EEVEE")
    # A white plane under a sun fills the frame: most pixels lit, not merely a stray one.
    assert run.result["lit"] > 0.9, run.result
    assert run.result["mean"] > 0.1, run.result
