"""Operators: solve (modal with a worker thread in the UI, direct in scripts), clear."""
from __future__ import annotations

import threading
import time

import bpy

import bsgi

from bpy_extras.io_utils import ExportHelper, ImportHelper

from . import bake, error_view, pipeline, solution_file
from .errors import ExportError


class BSGI_OT_solve(bpy.types.Operator):
    """Solve the scene's global illumination as B-spline radiance and bake it onto the objects"""

    bl_idname = "bsgi.solve"
    bl_label = "Solve B-spline GI"
    bl_options = {"REGISTER"}

    _timer = None
    _thread = None
    _job = None
    _result = None
    _t0 = 0.0

    def execute(self, context):
        # Scripts and `blender --background`: run to the end here, progress as lines.
        def on_progress(fraction, stage):
            print(f"bsgi: {fraction * 100:5.1f}% {stage}", flush=True)

        try:
            rep = pipeline.solve_and_bake(context, on_progress=on_progress)
        except (ExportError, ValueError, RuntimeError, MemoryError, ImportError) as error:  # MemoryError: bsgi.MemoryBudgetError
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self._report_done(rep)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background:
            return self.execute(context)
        try:
            pipeline.claim()  # released when the modal solve ends
        except RuntimeError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        try:
            self._job = pipeline.prepare(context)
        except (ExportError, ValueError, MemoryError, ImportError) as error:
            pipeline.release()
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self._result = {}
        self._t0 = time.perf_counter()

        def work():
            try:
                self._result["solution"] = pipeline.run(self._job)
            except BaseException as error:  # carried to the main thread
                self._result["error"] = error

        self._thread = threading.Thread(target=work, name="bsgi-solve", daemon=True)
        self._thread.start()
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._job.progress.cancel()
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        wm = context.window_manager
        progress = self._job.progress
        wm.progress_update(int(progress.fraction * 100))
        context.workspace.status_text_set(f"B-spline GI: {progress.stage} {progress.fraction * 100:.0f}% (Esc cancels)")
        if self._thread.is_alive():
            return {"RUNNING_MODAL"}
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)
        try:
            return self._finish(context)
        finally:
            pipeline.release()

    def _finish(self, context):
        error = self._result.get("error")
        t1 = time.perf_counter()
        if error is None:
            try:
                pipeline.finish(context, self._job, self._result["solution"])
            except (bsgi.SolveCancelled, ValueError, RuntimeError, MemoryError) as bake_error:
                error = bake_error
        if isinstance(error, bsgi.SolveCancelled):
            self.report({"WARNING"}, "B-spline GI: solve cancelled; the scene is unchanged")
            return {"CANCELLED"}
        if error is not None:
            self.report({"ERROR"}, f"B-spline GI: {error}")
            return {"CANCELLED"}
        self._report_done(pipeline.report(self._job, self._result["solution"], t1 - self._t0, time.perf_counter() - t1))
        return {"FINISHED"}

    def _report_done(self, rep):
        for line in pipeline.report_lines(rep):
            self.report({"WARNING"}, line)
        self.report({"INFO"}, f"B-spline GI: solved {rep['surfaces']} surfaces ({rep['coefficients']} coefficients, "
                    f"{rep['bounces']} bounces) in {rep['solve_seconds']:.2f} s, baked in {rep['bake_seconds']:.2f} s; "
                    f"{pipeline.summary_text(rep)}")


class BSGI_OT_clear(bpy.types.Operator):
    """Remove the baked radiance and show the objects' own materials"""

    bl_idname = "bsgi.clear"
    bl_label = "Clear B-spline GI"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        for obj in context.scene.objects:
            bake.clear_bake(obj)
        return {"FINISHED"}


class BSGI_OT_rebake(bpy.types.Operator):
    """Regenerate the baked images from the splines stored in the scene, without solving"""

    bl_idname = "bsgi.rebake"
    bl_label = "Re-bake B-spline GI"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        objects = [o for o in context.scene.objects if bake.PROP_RADIANCE in o]
        if not objects:
            self.report({"ERROR"}, "B-spline GI: nothing to re-bake; solve first")
            return {"CANCELLED"}
        for obj in objects:
            for warning in bake.rebake(obj):
                self.report({"WARNING"}, warning)
        context.scene.bsgi.show_baked = True
        error_view.refresh(context.scene)
        return {"FINISHED"}


class BSGI_OT_export_solution(bpy.types.Operator, ExportHelper):
    """Write the solved splines to a solution file (bsgi.load_solution reads it)"""

    bl_idname = "bsgi.export_solution"
    bl_label = "Export B-spline Solution"
    filename_ext = ".npz"

    def execute(self, context):
        try:
            count = solution_file.export_solution(context.scene, self.filepath)
        except ValueError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"B-spline GI: wrote {count} surfaces to {self.filepath}")
        return {"FINISHED"}


class BSGI_OT_import_solution(bpy.types.Operator, ImportHelper):
    """Bake the splines of a solution file onto the objects it names"""

    bl_idname = "bsgi.import_solution"
    bl_label = "Import B-spline Solution"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".npz"

    def execute(self, context):
        try:
            objects = solution_file.import_solution(context.scene, self.filepath)
        except (ValueError, OSError) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        context.scene.bsgi.show_baked = True
        self.report({"INFO"}, f"B-spline GI: baked {len(objects)} objects from {self.filepath}")
        return {"FINISHED"}


classes = (BSGI_OT_solve, BSGI_OT_clear, BSGI_OT_rebake, BSGI_OT_export_solution, BSGI_OT_import_solution)

register, unregister = bpy.utils.register_classes_factory(classes)
