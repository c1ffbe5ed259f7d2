"""Export -> solve -> bake, in the three steps the operators need: the solve alone runs off the
main thread, Blender's data is read and written only on it."""
from __future__ import annotations

import time
from dataclasses import dataclass

import bpy

import bsgi

from . import bake
from .export import Export, ExportError, export_scene


@dataclass
class Job:
    export: Export
    settings: bsgi.SolverSettings
    progress: bsgi.Progress


def prepare(context) -> Job:
    """Main thread: read the scene. Raises ExportError naming the object on bad input."""
    depsgraph = context.evaluated_depsgraph_get()
    export = export_scene(depsgraph)
    for exported in export.objects:
        obj = bpy.data.objects[exported.name]
        if obj.type != "MESH":
            raise ExportError(f"object '{obj.name}': only mesh objects can be baked yet ({obj.type.lower()} given)")
        if len(obj.data.polygons) != exported.polygon_count:
            raise ExportError(f"object '{obj.name}': its modifiers change its faces; apply them before solving")
    return Job(export, context.scene.bsgi.solver_settings(), bsgi.Progress())


def run(job: Job) -> bsgi.Solution:
    """Any thread: the solve itself (the core releases the GIL)."""
    return bsgi.solve(job.export.scene, job.settings, job.progress)


def finish(context, job: Job, solution: bsgi.Solution) -> None:
    """Main thread: bake the solution into the scene."""
    for exported in job.export.objects:
        bake.bake_object(bpy.data.objects[exported.name], bake.face_splines(exported, solution.radiance))
    context.scene.bsgi.show_baked = True


def solve_and_bake(context, on_progress=None) -> dict:
    """The whole job on the calling thread; returns a report of what was done."""
    t0 = time.perf_counter()
    job = prepare(context)
    solution = bsgi.solve(job.export.scene, job.settings, job.progress, on_progress=on_progress)
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
        "warnings": job.export.warnings,
    }
