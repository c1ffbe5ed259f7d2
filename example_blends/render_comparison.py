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


def written_render(scene, exr: pathlib.Path, color_mode: str, png: pathlib.Path | None = None) -> np.ndarray:
    """Renders the scene camera to `exr` and reads it back: (rows from the top, columns, channels of
    `color_mode`), scene-linear (the render result's own save_render applies the view transform
    even to an EXR). With `png`, also saves there what the view transform displays. The EXR is
    removed."""
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = "OPEN_EXR", "32", color_mode
    scene.render.filepath = str(exr)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(exr))
    try:
        w, h = image.size
        pixels = np.array(image.pixels[:], np.float32).reshape(h, w, image.channels)[::-1]
        if png is not None:
            settings.file_format, settings.color_depth, settings.color_mode = "PNG", "8", "RGB"
            image.save_render(filepath=str(png), scene=scene)
    finally:
        bpy.data.images.remove(image)
        exr.unlink()
    return pixels


def render(scene, path: pathlib.Path, samples: int, bounces: int) -> np.ndarray:
    """A Cycles render of the scene camera: its linear radiance (rows from the top, RGB), and a PNG
    at path of what the view transform displays."""
    scene.render.engine = "CYCLES"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = bounces
    for kind in ("diffuse", "glossy", "transmission", "volume"):
        setattr(scene.cycles, f"{kind}_bounces", bounces)
    scene.cycles.sample_clamp_direct = scene.cycles.sample_clamp_indirect = 0
    # Filter Glossy (on by default) roughens glossy surfaces after a diffuse bounce to cut noise:
    # it biases the light a metal ball reflects onto the room (the textured interior 3% brighter
    # with it). The reference is the unbiased, converged path tracing of the scene.
    scene.cycles.blur_glossy = 0.0
    return written_render(scene, path.with_suffix(".exr"), "RGB", png=path)[:, :, :3]


def object_masks(scene, folder: pathlib.Path) -> dict:
    """Per mesh object, the pixels it covers in the camera view: its alpha in a render where every
    other mesh object is a holdout (they still hide what lies behind them). The scene's holdouts,
    transparency, bounces and samples are put back."""
    meshes = [o for o in scene.objects if o.type == "MESH"]
    holdouts = [o.is_holdout for o in meshes]
    transparent, bounces, samples = scene.render.film_transparent, scene.cycles.max_bounces, scene.cycles.samples
    scene.render.film_transparent, scene.cycles.max_bounces, scene.cycles.samples = True, 0, 4
    masks = {}
    try:
        for obj in meshes:
            for other in meshes:
                other.is_holdout = other is not obj
            masks[obj.name] = written_render(scene, folder / "mask.exr", "RGBA")[:, :, 3] > 0.99
    finally:
        for obj, holdout in zip(meshes, holdouts):
            obj.is_holdout = holdout
        scene.render.film_transparent, scene.cycles.max_bounces, scene.cycles.samples = transparent, bounces, samples
    return masks


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
    masks = object_masks(scene, out)
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
    # Per object, its mean radiance over the pixels it covers against Cycles': where a bias sits.
    for name, mask in masks.items():
        if mask.sum() >= 100:
            print(f"  {name}: {mask.mean():.1%} of the frame, mean radiance ratio {lum_baked[mask].mean() / lum_ref[mask].mean():.4f}")
    for line in pipeline.report_lines(report):
        print(f"  {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
