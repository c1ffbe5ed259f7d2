"""Faults injected into a solve and a bake of a small scene: cancels at random moments, and
solve/cancel cycles for memory growth. Used by tests/blender/test_faults.py (in-process) and, as a
script printing JSON, by the leak test and bench/bench_faults.py (a fresh process each):

    python tests/blender/fault_runs.py cancel --moments 100 --phase solve
    python tests/blender/fault_runs.py leak --cycles 100
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import pathlib
import random
import sys
import tempfile
import threading
import time

import blend_file

HERE = pathlib.Path(__file__).resolve().parent


def start_blender():
    """The bpy module with the add-on registered (as tests/blender/conftest.py does)."""
    if "HOME" not in os.environ:  # the tests give one; a bare environment gets its own, gone at exit
        from subprocess_render import session_folder

        os.environ["HOME"] = session_folder("bsgi-home-")
    import bpy  # noqa: F401

    sys.path.insert(0, str(HERE.parents[1] / "addon"))
    sys.path.insert(0, str(HERE))
    import cli

    addon = cli.load_addon()
    try:
        addon.register()
    except ValueError:
        pass  # already registered
    return addon


def pipeline():
    return sys.modules["bsgi_addon.pipeline"]


def build_scene():
    """A floor, a wall and a box under an area light, Draft preset: several objects to bake, a
    solve of a few tenths of a second."""
    import bpy

    import scenes

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scenes.floor_under_lamp()
    grey = bpy.data.materials["Grey"]
    scenes.add_quad("Wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 1.5), (-1, 1, 1.5)], grey)
    bpy.ops.mesh.primitive_cube_add(size=0.4, location=(0.2, 0.1, 0.2))
    bpy.context.object.name = "Box"
    bpy.context.object.data.materials.append(grey)
    bpy.context.scene.bsgi.preset = "DRAFT"


def saved_bytes(path) -> bytes:
    """The scene as Blender saves it (uncompressed), always to the same path: the file records
    its own path."""
    import bpy

    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=False, copy=True)
    return pathlib.Path(path).read_bytes()


def attempt(delay: float, phase: str, solve_seconds: list | None = None):
    """One solve and bake of the current scene, cancelled `delay` seconds after the solve starts
    (phase "solve") or after the bake starts ("bake"). Returns "solve" or "bake" (the part the
    cancel stopped), or None if it finished first. If the solve finished, its seconds are
    appended to `solve_seconds`."""
    import bpy

    import bsgi

    progress = bsgi.Progress()
    timer = threading.Timer(delay, progress.cancel)
    started = time.perf_counter()

    def on_progress(fraction, stage):
        if stage == "done":  # the solve is over, the bake starts
            if solve_seconds is not None:
                solve_seconds.append(time.perf_counter() - started)
            if phase == "bake" and not timer.is_alive() and not timer.finished.is_set():
                timer.start()

    if phase == "solve":
        timer.start()
    try:
        pipeline().solve_and_bake(bpy.context, on_progress=on_progress, progress=progress)
    except bsgi.SolveCancelled as error:
        return "bake" if "bake" in str(error) else "solve"
    finally:
        timer.cancel()
        timer.join()
    return None


def timings() -> tuple:
    """(solve seconds, bake seconds) of an uncancelled run on the current scene (which it bakes)."""
    import bpy

    rep = pipeline().solve_and_bake(bpy.context)
    return rep["solve_seconds"], rep["bake_seconds"]


def cancel_moments(moments: int, phase: str, seed: int, path) -> dict:
    """Cancels the solve (or the bake) of build_scene() at `moments` uniformly random moments of
    its duration; after each, the saved .blend must hold the same data as the one saved just
    before the attempt: byte-identical, or equal but for the runtime fields and pointer numbers
    that blend_file.canonical() sets aside (a bake undone leaves the depsgraph's update tags).
    Attempts that finish before their moment do not count; they shrink the span the moments are
    drawn from by 5%, or for the solve to that attempt's own solve time if shorter (a machine whose
    load fell after the timing), as does a cancel of a solve that lands in the bake. After those
    (and after a change) the scene is read back from the file saved before them."""
    import bpy

    build_scene()
    saved_bytes(path)
    solve_s, bake_s = timings()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    span = solve_s if phase == "solve" else bake_s
    rng = random.Random(seed)
    stopped = {"solve": 0, "bake": 0}
    changed, finished, identical = [], 0, {"solve": 0, "bake": 0}
    while sum(stopped.values()) < moments and finished < 3 * moments:
        delay = rng.uniform(0, span)
        before = saved_bytes(path)
        solve_seconds = []
        where = attempt(delay, phase, solve_seconds)
        restore = where is None
        if where is None:  # the phase ran faster than the first one timed: draw from less
            finished += 1
            span = min(0.95 * span, solve_seconds[0]) if phase == "solve" else 0.95 * span
        else:
            stopped[where] += 1
            if where != phase:  # the solve ran faster than timed (the machine's load fell): draw
                span = min(0.95 * span, solve_seconds[0])  # from the solve as long as this one
            after = saved_bytes(path)
            identical[where] += after == before
            differences = [] if after == before else blend_file.differences(before, after, 3)
            if differences:
                changed.append((where, round(delay, 4), differences))
                restore = True
        if restore:
            pathlib.Path(path).write_bytes(before)
            bpy.ops.wm.open_mainfile(filepath=str(path))
    return {"phase": phase, "solve_seconds": solve_s, "bake_seconds": bake_s, "stopped": stopped,
            "finished": finished, "byte_identical": identical, "changed": changed}


def rss_mb() -> float:
    with open("/proc/self/status") as status:
        kb = next(int(line.split()[1]) for line in status if line.startswith("VmRSS:"))
    return kb / 1024


def leak(cycles: int, warmup: int, seed: int) -> dict:
    """Resident memory before and after `cycles` solve/cancel cycles (cancelled at a random
    moment of the solve or of the bake, or finishing, in turn), after `warmup` cycles that fill
    the caches. The moments are drawn within the durations of a run timed after the warmup (a cold
    first run, or one on a busy machine, is slower: moments drawn from it missed the solve)."""
    build_scene()
    solve_s, bake_s = timings()
    rng = random.Random(seed)
    outcomes = {"solve": 0, "bake": 0, None: 0}
    turn = iter(range(10**9))

    def cycle():
        kind = next(turn) % 3
        if kind == 0:
            outcomes[attempt(rng.uniform(0, 0.9 * solve_s), "solve")] += 1
        elif kind == 1:
            # (the bake's last part, writing its images, checks no cancel: about half its time)
            outcomes[attempt(rng.uniform(0, 0.4 * bake_s), "bake")] += 1
        else:
            outcomes[attempt(1.1 * (solve_s + bake_s), "solve")] += 1

    for _ in range(warmup):
        cycle()
    solve_s, bake_s = timings()
    gc.collect()
    before = rss_mb()
    for _ in range(cycles):
        cycle()
    gc.collect()
    after = rss_mb()
    return {"cycles": cycles, "rss_before_mb": before, "rss_after_mb": after, "leak_mb": after - before,
            "cancelled_in_solve": outcomes["solve"], "cancelled_in_bake": outcomes["bake"],
            "finished": outcomes[None]}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("cancel")
    c.add_argument("--moments", type=int, default=100)
    c.add_argument("--phase", choices=["solve", "bake"], default="solve")
    c.add_argument("--seed", type=int, default=17)
    m = sub.add_parser("leak")
    m.add_argument("--cycles", type=int, default=100)
    m.add_argument("--warmup", type=int, default=10)
    m.add_argument("--seed", type=int, default=17)
    args = parser.parse_args(argv)
    start_blender()
    if args.command == "cancel":
        with tempfile.TemporaryDirectory() as tmp:
            result = cancel_moments(args.moments, args.phase, args.seed, pathlib.Path(tmp) / "scene.blend")
    else:
        result = leak(args.cycles, args.warmup, args.seed)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
