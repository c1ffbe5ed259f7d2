"""Running a solve with progress reports and cancellation."""
from __future__ import annotations

import threading
from typing import Callable, Optional, Protocol

from . import _core
from .refine import refined_solve

ProgressCallback = Callable[[float, str], Optional[bool]]


class Executor(Protocol):
    """Runs a solve's gathers elsewhere (bsgi.RayExecutor): solve() as _core.solve does."""

    def solve(self, scene: _core.Scene, settings: _core.SolverSettings, progress: _core.Progress) -> _core.Solution: ...


def solve(
    scene: _core.Scene,
    settings: Optional[_core.SolverSettings] = None,
    progress: Optional[_core.Progress] = None,
    on_progress: Optional[ProgressCallback] = None,
    poll_seconds: float = 0.1,
    executor: Optional[Executor] = None,
) -> _core.Solution:
    """Solve the scene's light transport (paper Algorithm 1).

    The core releases the GIL and uses all threads. ``progress`` can be polled and cancelled from
    another thread. ``on_progress(fraction, stage)`` is called on this thread while the solve runs;
    returning False cancels it. A cancelled solve raises :class:`bsgi.SolveCancelled`.
    ``executor``: where the gathers run, e.g. :class:`bsgi.RayExecutor` (a Ray cluster); None: here.
    With ``settings.refine_to_error`` > 0 the surfaces whose estimated error is over it are refined
    and the scene solved again, under a budget (bsgi.refine); ``solution.refinement`` reports it.
    """
    settings = settings if settings is not None else _core.SolverSettings()
    progress = progress if progress is not None else _core.Progress()

    def solve_once() -> _core.Solution:
        if executor is None:
            return _core.solve(scene, settings, progress)
        return executor.solve(scene, settings, progress)

    def solve_here() -> _core.Solution:
        if settings.refine_to_error > 0:
            return refined_solve(scene, settings, solve_once)
        return solve_once()

    if on_progress is None:
        return solve_here()

    result: dict = {}

    def run() -> None:
        try:
            result["solution"] = solve_here()
        except BaseException as error:  # carried to the calling thread
            result["error"] = error

    worker = threading.Thread(target=run, name="bsgi-solve", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(poll_seconds)
        if on_progress(progress.fraction, progress.stage) is False:
            progress.cancel()
    if "error" in result:
        raise result["error"]
    on_progress(1.0, "done")
    return result["solution"]
