"""Export -> solve -> bake, in the three steps the operators need: the solve alone runs off the
main thread, Blender's data is read and written only on it."""
from __future__ import annotations

import math
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass

import bpy

import bsgi

from . import bake, error_view, preferences
from .export import Export, export_scene


@dataclass
class Job:
    export: Export
    settings: bsgi.SolverSettings
    progress: bsgi.Progress
    executor: bsgi.RayExecutor | None = None  # None: solve on this machine


# One solve at a time per Blender process: two would bake into the same scene data at once.
_running = threading.Lock()
BUSY_MESSAGE = ("B-spline GI: another solve is running in this Blender session; wait for it to finish or cancel "
                "it (Esc) first")


def claim() -> None:
    """Take the process's one solve slot, or raise RuntimeError saying another solve runs."""
    if not _running.acquire(blocking=False):
        raise RuntimeError(BUSY_MESSAGE)


def release() -> None:
    _running.release()


@contextmanager
def one_solve():
    claim()
    try:
        yield
    finally:
        release()


def executor_for(address: str, threads_per_worker: int = 1) -> bsgi.RayExecutor | None:
    """Where the solve runs: a Ray cluster at `address` ('auto': the one this machine joined),
    with workers of `threads_per_worker` CPUs each, or here (''). ImportError saying so when Ray
    is not installed."""
    if not address:
        return None
    bsgi.ray_executor.import_ray()
    return bsgi.RayExecutor(address, threads_per_worker=threads_per_worker)


def prepare(context, progress: bsgi.Progress | None = None, ray_address: str | None = None,
            ray_threads_per_worker: int | None = None) -> Job:
    """Main thread: read the scene. Raises ExportError naming the object on bad input.
    ray_address, ray_threads_per_worker: the Ray cluster to solve on and its workers' threads
    (None: the add-on's preferences say)."""
    address, threads = preferences.ray_cluster(context)
    executor = executor_for(address if ray_address is None else ray_address,
                            threads if ray_threads_per_worker is None else ray_threads_per_worker)
    depsgraph = context.evaluated_depsgraph_get()
    # Objects that cannot be baked (curves, texts, metaballs; meshes whose modifiers carry no
    # chart) are solved but left out of export.objects, with a warning each.
    export = export_scene(depsgraph)
    return Job(export, context.scene.bsgi.solver_settings(), progress or bsgi.Progress(), executor)


def run(job: Job) -> bsgi.Solution:
    """Any thread: the solve itself (the core releases the GIL)."""
    return bsgi.solve(job.export.scene, job.settings, job.progress, executor=job.executor)


def finish(context, job: Job, solution: bsgi.Solution) -> None:
    """Main thread: bake the solution into the scene; the bake's warnings join the export's.
    job.progress cancels the bake too (bsgi.SolveCancelled); a cancelled or failed bake is undone,
    so the scene is as it was before the solve."""
    warnings = job.export.warnings
    with bake.transaction(job.progress) as baking:
        for exported in job.export.objects:
            obj = bpy.data.objects[exported.name]
            baking.touch(obj)
            warnings += bake.bake_object(obj, bake.face_splines(exported, solution.surfaces), exported.chart_uvs)
    job.export.warnings = list(dict.fromkeys(warnings))
    for name, error in error_view.object_errors(job.export, solution).items():
        obj = bpy.data.objects[name]
        if math.isfinite(error):
            obj[error_view.PROP_ERROR] = error
        elif error_view.PROP_ERROR in obj:
            del obj[error_view.PROP_ERROR]
    context.scene.bsgi.show_baked = True
    error_view.refresh(context.scene)


def solve_and_bake(context, on_progress=None, progress: bsgi.Progress | None = None, ray_address: str | None = None,
                   ray_threads_per_worker: int | None = None) -> dict:
    """The whole job on the calling thread; returns a report of what was done. progress.cancel()
    from another thread stops the solve or the bake (bsgi.SolveCancelled), leaving the scene as
    it was; a second solve while one runs raises RuntimeError (BUSY_MESSAGE). ray_address,
    ray_threads_per_worker: as for prepare()."""
    with one_solve():
        t0 = time.perf_counter()
        job = prepare(context, progress, ray_address, ray_threads_per_worker)
        solution = bsgi.solve(job.export.scene, job.settings, job.progress, on_progress=on_progress, executor=job.executor)
        t1 = time.perf_counter()
        finish(context, job, solution)
        return report(job, solution, solve_seconds=t1 - t0, bake_seconds=time.perf_counter() - t1)


def report(job: Job, solution: bsgi.Solution, solve_seconds: float, bake_seconds: float) -> dict:
    stats = solution.stats
    return {
        "solve_seconds": solve_seconds,
        "bake_seconds": bake_seconds,
        "surfaces": len(job.export.scene),
        "objects": len(job.export.objects),
        "coefficients": stats["coefficients"],
        "bounces": stats["bounces"],
        "rays": stats["rays"],
        "representations": representation_summary(solution.reports),
        # Per baked object: the root mean square of its surfaces' estimated relative errors.
        "estimated_errors": error_view.object_errors(job.export, solution),
        "refinement": refinement_summary(solution),
        "warnings": job.export.warnings,
        # Per material, light, object and the world: what is approximated and how.
        "approximations": [{"owner": a.owner, "objects": a.objects, "notes": a.notes, "text": a.text()}
                           for a in job.export.approximations()],
    }


def refinement_summary(solution: bsgi.Solution):
    """With refinement (bsgi.refine: Final's, or Refinement To Error): the passes, why they
    stopped, the surfaces refined and those still over the target; None without it."""
    r = getattr(solution, "refinement", None)
    if r is None:
        return None
    return {"passes": r["passes"], "stopped": r["stopped"], "trimmed": [t["budget"] for t in r["trimmed"]], "rays": r["rays"],
            "refined": sum(s["refined"] > 0 for s in r["surfaces"]),
            "over_target": [s["name"] for s in r["surfaces"] if s["status"] != "met"]}


def report_lines(rep: dict) -> list:
    """The report's warnings as a user reads them: one line per material, light, object or world
    naming all it approximates (and a material's objects), then the other warnings."""
    grouped = [a["text"] for a in rep["approximations"]]
    owned = {f"{a['owner']}: {note}" for a in rep["approximations"] for note in a["notes"]}
    return grouped + [w for w in rep["warnings"] if w not in owned]


def representation_summary(reports) -> dict:
    """What the solver chose per surface (paper: "model only what a scene requires"): counts of
    diffuse (2D) and glossy (4D) surfaces and the largest spline, by coefficients."""
    counts: dict = {}
    largest = None
    for r in reports:
        # "diffuse 2D", "glossy 4D + transmission", "diffuse 2D, both sides", "emitter", "thin glass" (a pane)
        kind = "pane" if r["representation"] == "thin glass" else r["representation"].split()[0].rstrip(",")
        counts[kind] = counts.get(kind, 0) + 1
        if r["shape"]:
            sides = 2 if any(s in r["representation"] for s in ("transmission", "both sides")) else 1
            coefficients = math.prod(r["shape"]) * sides
            if largest is None or coefficients > largest["coefficients"]:
                largest = {"name": r["name"], "shape": list(r["shape"]), "coefficients": coefficients,
                           "reason": r["reason"]}
    return {"counts": counts, "largest": largest}


def summary_text(rep: dict) -> str:
    """One line for the status bar: "2 diffuse, 1 glossy, 1 emitter; largest 'Floor: face 0' 12x12x10x10 (14400 coefficients)"."""
    kinds = rep["representations"]
    order = {"diffuse": 0, "glossy": 1}
    text = ", ".join(f"{n} {kind}" for kind, n in sorted(kinds["counts"].items(), key=lambda c: (order.get(c[0], 2), c[0])))
    largest = kinds["largest"]
    if largest:
        text += (f"; largest '{largest['name']}' {'x'.join(map(str, largest['shape']))} "
                 f"({largest['coefficients']} coefficients)")
    worst = error_view.worst_text(rep.get("estimated_errors", {}))
    if worst:
        text += f"; {worst}"
    refinement = rep.get("refinement")
    if refinement:
        text += f"; refinement: {refinement['refined']} surfaces refined in {refinement['passes']} more solves"
        if refinement["over_target"]:
            why = (f", stopped by the {refinement['stopped']} budget" if refinement["stopped"] else
                   f", the worst refined first within the {refinement['trimmed'][-1]} budget" if refinement["trimmed"] else "")
            text += f" ({len(refinement['over_target'])} still over the target{why})"
    approximated = rep.get("approximations", [])
    if approximated:
        notes = sum(len(a["notes"]) for a in approximated)
        text += (f"; {notes} approximation{'s' if notes > 1 else ''} in {len(approximated)} "
                 f"{'item' if len(approximated) == 1 else 'items'} (see the warnings)")
    return text
