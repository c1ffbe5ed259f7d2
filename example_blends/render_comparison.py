"""Renders an example scene twice from its camera: Cycles path tracing of the scene as the user made
it, and Cycles showing the bsgi bake (emission only, no bounces), and prints how far apart they are.
The README's side-by-side images of textured_interior.blend come from this script:

    .venv/bin/python example_blends/render_comparison.py example_blends/textured_interior.blend \\
        --preset preview --samples 512 --out-dir example_blends/renders
"""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

import bpy
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "addon"))
import cli  # noqa: E402  (loads the add-on package)


def render(scene, path: pathlib.Path, samples: int, bounces: int) -> np.ndarray:
    """A Cycles render of the scene camera to path (PNG, the view transform's display values) and
    its linear radiance (rows from the top, RGB)."""
    scene.render.engine = "CYCLES"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = bounces
    for kind in ("diffuse", "glossy", "transmission", "volume"):
        setattr(scene.cycles, f"{kind}_bounces", bounces)
    scene.cycles.sample_clamp_direct = scene.cycles.sample_clamp_indirect = 0
    scene.render.filepath = str(path)
    scene.render.image_settings.file_format = "PNG"
    bpy.ops.render.render(write_still=True)
    result = bpy.data.images["Render Result"]
    # The render result's pixels are not readable: read the float image back from an EXR copy.
    exr = path.with_suffix(".exr")
    result.save_render(filepath=str(exr), scene=scene)
    image = bpy.data.images.load(str(exr))
    w, h = image.size
    pixels = np.array(image.pixels[:], np.float32).reshape(h, w, 4)[::-1, :, :3]
    bpy.data.images.remove(image)
    exr.unlink()
    return pixels


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("blend")
    parser.add_argument("--preset", default="preview", choices=["draft", "preview", "final"])
    parser.add_argument("--samples", type=int, default=512, help="Cycles samples of the reference")
    parser.add_argument("--out-dir", default="out")
    parser.add_argument("--resolution", type=int, nargs=2, default=None, help="width height (default: the scene's)")
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = pathlib.Path(args.blend).stem
    addon = cli.load_addon()
    try:
        addon.register()
    except ValueError:
        pass
    import importlib

    pipeline = importlib.import_module(f"{addon.__name__}.pipeline")
    bpy.ops.wm.open_mainfile(filepath=str(pathlib.Path(args.blend).resolve()))
    scene = bpy.context.scene
    if args.resolution:
        scene.render.resolution_x, scene.render.resolution_y = args.resolution
    t0 = time.perf_counter()
    reference = render(scene, out / f"{stem}_cycles.png", args.samples, 32)
    cycles_seconds = time.perf_counter() - t0
    scene.bsgi.preset = args.preset.upper()
    report = pipeline.solve_and_bake(bpy.context)
    baked = render(scene, out / f"{stem}_bsgi.png", 16, 0)
    lum_ref, lum_baked = reference.mean(axis=2), baked.mean(axis=2)
    # Blocks of 8 x 8 pixels: the reference's noise averages out over a block, not over a pixel.
    h, w = (s // 8 * 8 for s in lum_ref.shape)
    blocks = [lum[:h, :w].reshape(h // 8, 8, w // 8, 8).mean(axis=(1, 3)) for lum in (lum_ref, lum_baked)]
    rel = np.abs(blocks[1] / np.maximum(blocks[0], 1e-6) - 1)[blocks[0] > 0.02 * blocks[0].max()]
    print(f"{stem}: bsgi {args.preset} solve {report['solve_seconds']:.1f} s + bake {report['bake_seconds']:.1f} s; "
          f"Cycles {args.samples} samples {cycles_seconds:.1f} s; mean radiance ratio {lum_baked.mean() / lum_ref.mean():.4f}, "
          f"8 x 8 pixel blocks: median relative difference {np.median(rel):.4f}, 90th percentile {np.percentile(rel, 90):.4f}")
    for line in pipeline.report_lines(report):
        print(f"  {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
