"""Light through a glass object: a smooth rough-glass ball (Glass BSDF, roughness 0.5, Multiscatter
GGX) on a grey floor under a sun and a grey sky (tests/blender/test_smooth_meshes.py's scene). Its
shadow on the floor holds a focus (the ball is a lens); the floor solved at each preset against
Cycles' render of the floor seen from above (the ball hidden from the camera, 1,024 samples, 12
bounces, Filter Glossy off), in a fresh bpy process.

Figures: the floor's relative RMS difference per pixel (64 x 64 over 4 x 4 m) and over the 4 x 4
pixel blocks of the shadow, the floor's mean against Cycles', the solve's seconds; and Cycles'
own noise (two seeds' RMS difference over sqrt 2)."""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from blender_process import run_script  # noqa: E402

SCRIPT = """
import json, os, sys, time
import numpy as np
sys.path[:0] = [sys.argv[1], sys.argv[2], os.path.dirname(sys.argv[2])]  # the add-on, the tests' scenes
import cli
cli.load_addon().register()
import bpy
from bsgi_addon import pipeline
from test_export import shader_material
from test_pipeline import render_exr
from test_smooth_meshes import sphere_on_floor

N = 64
bpy.ops.wm.read_factory_settings(use_empty=True)
context = bpy.context
ball, _ = sphere_on_floor(context)
ball.data.materials.clear()
ball.data.materials.append(shader_material("Frosted", "ShaderNodeBsdfGlass", Roughness=0.5, IOR=1.5)[0])
top = bpy.data.objects.new("Top", bpy.data.cameras.new("Top"))
top.data.type, top.data.ortho_scale = "ORTHO", 4.0  # the whole 4 x 4 m floor
top.location = (0, 0, 5)
context.scene.collection.objects.link(top)
context.scene.camera = top
ball.visible_camera = False
context.scene.cycles.blur_glossy = 0.0
if sys.argv[3] == "CYCLES":
    images = []
    for seed in (1, 2):
        images.append(render_exr(context.scene, sys.argv[4] + f"/top{seed}.exr", samples=1024, bounces=12, seed=seed))
    np.save(sys.argv[4] + "/cycles.npy", np.stack(images))
    print(json.dumps({}))
else:
    context.scene.bsgi.preset = sys.argv[3]
    start = time.perf_counter()
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    seconds = time.perf_counter() - start
    floor = next(o for o in job.export.objects if o.name == "Floor")
    x = (np.arange(N) + 0.5) / N
    u, v = np.meshgrid(x, 1 - x)  # image rows run downwards, +y up
    uv = np.column_stack([u.ravel(), v.ravel()])
    radiance = solution.surfaces[floor.patches[0][1]].evaluate(uv, np.tile([0.0, 0.0, 1.0], (len(uv), 1)))
    np.save(sys.argv[4] + f"/{sys.argv[3]}.npy", radiance.reshape(N, N, 3))
    print(json.dumps({"seconds": seconds}))
"""


def in_blender(what: str, folder: str) -> dict:
    return run_script(SCRIPT, what, folder)


def blocks(image, k: int):
    """Means over k x k pixel blocks."""
    rows, cols = image.shape[0] // k, image.shape[1] // k
    return image[:rows * k, :cols * k].reshape(rows, k, cols, k, -1).mean(axis=(1, 3))


def to_64(image):
    """Cycles' 96 x 96 render as 64 x 64 by area (each pixel split in 2 x 2, then 3 x 3 blocks)."""
    return blocks(np.repeat(np.repeat(image, 2, axis=0), 2, axis=1), 3)


def run() -> dict:
    figures = {}
    with tempfile.TemporaryDirectory(prefix="bsgi-glass-ball-") as folder:
        in_blender("CYCLES", folder)
        seeds = np.load(f"{folder}/cycles.npy")
        first, second = (to_64(s) for s in seeds)
        cycles = (first + second) / 2
        # The mean of two seeds' noise: their difference's RMS over 2.
        figures["glass_ball_cycles_noise_rel_rms"] = round(float(np.sqrt(np.mean(((first - second) / cycles) ** 2)) / 2), 4)
        shadow = (slice(6 * 4, 12 * 4), slice(2 * 4, 10 * 4))  # around the ball's shadow and focus
        for preset in ("PREVIEW", "FINAL"):
            seconds = in_blender(preset, folder)["seconds"]
            solved = np.load(f"{folder}/{preset}.npy")
            key = f"glass_ball_{preset.lower()}"
            figures[f"{key}_seconds"] = round(seconds, 1)
            figures[f"{key}_floor_rel_rmse"] = round(float(np.sqrt(np.mean((solved / cycles - 1) ** 2))), 4)
            got, reference = (blocks(image[shadow], 4) for image in (solved, cycles))
            figures[f"{key}_shadow_blocks_rel_rmse"] = round(float(np.sqrt(np.mean((got / reference - 1) ** 2))), 4)
            figures[f"{key}_floor_mean_ratio"] = round(float(solved.mean() / cycles.mean()), 4)
    return figures


if __name__ == "__main__":
    for key, value in run().items():
        print(f"{key}: {value}")
