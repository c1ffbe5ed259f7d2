"""Headless solve and bake, for farms, scripts and users of the `bpy` module.

    python -m addon scene.blend --out solved.blend [--render image.png]         (bpy module)
    python addon/cli.py scene.blend --out solved.blend [--render image.png]     (the same)
    blender --background scene.blend --python addon/cli.py -- --out solved.blend (Blender)

Prints progress as lines; exits with status 1 and a message naming the problem on failure."""
from __future__ import annotations

import argparse
import importlib.util
import pathlib
import sys
import time

PACKAGE = "bsgi_addon"


def load_addon():
    """The add-on as a package, whether this file runs as a script or inside the package
    (`python -m addon`: then it is the package already imported, not a second copy)."""
    if __package__:
        return sys.modules[__package__]
    if PACKAGE in sys.modules:
        return sys.modules[PACKAGE]
    here = pathlib.Path(__file__).resolve().parent
    spec = importlib.util.spec_from_file_location(PACKAGE, here / "__init__.py", submodule_search_locations=[str(here)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = module
    spec.loader.exec_module(module)
    return module


def render_view(scene, path: str, resolution=(512, 512), samples=16) -> None:
    """Cycles render of the camera view of a baked scene. Baked materials are pure emission, so
    no bounces are needed: the samples only anti-alias."""
    import bpy

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.filepath = str(pathlib.Path(path).resolve())
    scene.render.image_settings.file_format = "PNG" if path.endswith(".png") else "OPEN_EXR"
    if path.endswith(".exr"):
        scene.render.image_settings.color_depth = "32"
    bpy.ops.render.render(write_still=True)


def main(argv=None) -> int:
    argv = sys.argv[sys.argv.index("--") + 1:] if argv is None and "--" in sys.argv else (argv or sys.argv[1:])
    parser = argparse.ArgumentParser(description="Solve B-spline GI headless and bake it into the scene.")
    parser.add_argument("blend", nargs="?", help="scene to open (omit inside `blender scene.blend --background`)")
    parser.add_argument("--out", help="where to save the solved scene (default: overwrite the opened file)")
    parser.add_argument("--render", help="also render the camera view of the baked scene to this image")
    parser.add_argument("--resolution", type=int, nargs=2, default=(512, 512))
    parser.add_argument("--preset", choices=["draft", "preview", "final", "reference", "custom"],
                        help="quality preset (default: the scene's setting)")
    parser.add_argument("--refine-to-error", type=float, metavar="ERROR",
                        help="refine surfaces whose estimated relative error is above ERROR (e.g. 0.02) and solve "
                             "again (0: off; default: the scene's setting, at first the preset's: final refines to "
                             "0.01 within a budget of 5)")
    parser.add_argument("--refine-passes", type=int, metavar="N", help="at most N solves after the first when refining")
    parser.add_argument("--refine-budget", type=float, metavar="FACTOR",
                        help="the solves after the first trace at most FACTOR times the first's rays, the surfaces "
                        "with the highest estimates refined first (0: no limit)")
    parser.add_argument("--adaptive-coefficients", type=float, metavar="TOLERANCE",
                        help="spatial coefficients from each surface's size and its light's detail, within TOLERANCE "
                        "of its brightest light (e.g. 0.005; 0: off, the preset's everywhere; default: the scene's "
                        "setting, at first the preset's: preview adapts at 0.005)")
    parser.add_argument("--coats", choices=["quality", "all", "folded"],
                        help="Principled BSDF glossy coats: solved where the quality says (default), all of them, or "
                        "folded into the diffuse colour (the scene's Glossy Coats)")
    parser.add_argument("--bumps", choices=["solved", "flat"],
                        help="normal maps and bumps on diffuse surfaces: solved over the bumped normal (default) or the "
                        "surfaces solved flat (the scene's Bumps)")
    parser.add_argument("--ray-address", metavar="ADDRESS",
                        help="solve on a Ray cluster: 'auto' (the cluster this machine joined with `ray start`), "
                             "'ray://host:10001' or host:port (needs `pip install ray`, and bsgi on every node)")
    parser.add_argument("--ray-threads-per-worker", type=int, default=1, metavar="N",
                        help="with --ray-address: CPUs each Ray worker reserves and gathers on (default 1; a "
                             "machine's cores: one worker a machine, faster where the machines are alike)")
    args = parser.parse_args(argv)
    if args.ray_threads_per_worker < 1:
        parser.error("--ray-threads-per-worker must be at least 1")

    import bpy

    addon = load_addon()
    try:
        addon.register()
    except ValueError:
        pass  # already registered in this session
    pipeline = importlib.import_module(f"{addon.__name__}.pipeline")
    ExportError = importlib.import_module(f"{addon.__name__}.errors").ExportError

    if args.blend:
        try:
            bpy.ops.wm.open_mainfile(filepath=str(pathlib.Path(args.blend).resolve()))
        except RuntimeError as error:
            print(f"bsgi: error: cannot open '{args.blend}': {error}", file=sys.stderr)
            return 1
    context = bpy.context
    if args.preset:
        context.scene.bsgi.preset = args.preset.upper()
    if args.refine_to_error is not None:
        context.scene.bsgi.refinement = "TO_ERROR" if args.refine_to_error > 0 else "OFF"
        context.scene.bsgi.refine_to_error = args.refine_to_error
    if args.refine_passes is not None or args.refine_budget is not None:
        if context.scene.bsgi.refinement != "TO_ERROR":
            parser.error("--refine-passes and --refine-budget need --refine-to-error (or the scene's Refinement "
                         "To Error)")
    if args.refine_passes is not None:
        context.scene.bsgi.refine_passes = args.refine_passes
    if args.refine_budget is not None:
        context.scene.bsgi.refine_cost = args.refine_budget
    if args.coats:
        context.scene.bsgi.coats = args.coats.upper()
    if args.bumps:
        context.scene.bsgi.bumps = args.bumps.upper()
    if args.adaptive_coefficients is not None:
        context.scene.bsgi.adaptive_coefficients = "TOLERANCE" if args.adaptive_coefficients > 0 else "OFF"
        context.scene.bsgi.detail_tolerance = args.adaptive_coefficients

    def on_progress(fraction, stage):
        print(f"bsgi: {fraction * 100:5.1f}% {stage}", flush=True)

    try:
        rep = pipeline.solve_and_bake(context, on_progress=on_progress, ray_address=args.ray_address or "",
                                     ray_threads_per_worker=args.ray_threads_per_worker)
    except (ExportError, ValueError, RuntimeError, MemoryError, ImportError) as error:
        print(f"bsgi: error: {error}", file=sys.stderr)
        return 1
    for line in pipeline.report_lines(rep):
        print(f"bsgi: warning: {line}")
    print(f"bsgi: solved {rep['surfaces']} surfaces, {rep['coefficients']} coefficients, {rep['bounces']} bounces "
          f"in {rep['solve_seconds']:.2f} s (bake {rep['bake_seconds']:.2f} s); {pipeline.summary_text(rep)}")
    out = pathlib.Path(args.out).resolve() if args.out else None
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
        bpy.ops.wm.save_as_mainfile(filepath=str(out), copy=False)
    else:
        bpy.ops.wm.save_mainfile()
    print(f"bsgi: saved {out or bpy.data.filepath}")
    if args.render:
        t0 = time.perf_counter()
        pathlib.Path(args.render).parent.mkdir(parents=True, exist_ok=True)
        render_view(context.scene, args.render, tuple(args.resolution))
        print(f"bsgi: rendered {pathlib.Path(args.render).resolve()} in {time.perf_counter() - t0:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
