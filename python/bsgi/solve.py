"""Running a solve with progress reports and cancellation."""
from __future__ import annotations

import threading
from typing import Callable, Optional, Protocol

from . import _core
from .refine import refined_solve
from .split import split_scene

ProgressCallback = Callable[[float, str], Optional[bool]]


class Executor(Protocol):
    """Runs a solve's gathers elsewhere (bsgi.RayExecutor): solve() as _core.solve does (``sides``:
    probed already, as _core.probe_sides returns them first, or None), and the sides probe alone
    (as _core.probe_sides(...)[0])."""

    def solve(self, scene: _core.Scene, settings: _core.SolverSettings, progress: _core.Progress,
              sides: Optional[list] = None) -> _core.Solution: ...

    def probe_sides(self, scene: _core.Scene, settings: _core.SolverSettings, progress: _core.Progress) -> list: ...


def solve(
    scene: _core.Scene,
    settings: Optional[_core.SolverSettings] = None,
    progress: Optional[_core.Progress] = None,
    on_progress: Optional[ProgressCallback] = None,
    poll_seconds: float = 0.1,
    executor: Optional[Executor] = None,
    sides: Optional[list] = None,
) -> _core.Solution:
    """Solve the scene's light transport (paper Algorithm 1).

    The core releases the GIL and uses all threads. ``progress`` can be polled and cancelled from
    another thread. ``on_progress(fraction, stage)`` is called on this thread while the solve runs;
    returning False cancels it. A cancelled solve raises :class:`bsgi.SolveCancelled`.
    ``executor``: where the gathers run, e.g. :class:`bsgi.RayExecutor` (a Ray cluster); None: here.
    With ``settings.refine_to_error`` > 0 the surfaces whose estimated error is over it are refined
    and the scene solved again, under a budget (bsgi.refine); ``solution.refinement`` reports it.
    ``sides``: which sides of each surface are solved, probed already (``bsgi.probe_sides(scene,
    settings)[0]``, e.g. for bsgi.estimate_solve_bytes beforehand): not probed again.
    With ``settings.split_crossings`` the diffuse NURBS surfaces other surfaces pass through are
    solved in pieces split along those lines (bsgi.split); the solution still answers per surface
    of ``scene`` (``solution.split``: surface index -> its number of pieces).
    """
    settings = settings if settings is not None else _core.SolverSettings()
    progress = progress if progress is not None else _core.Progress()
    split = split_scene(scene) if settings.split_crossings else None
    if split is not None:
        scene, sides = split.scene, split.sides(sides)

    def solve_once(probed: Optional[list]) -> _core.Solution:
        if executor is None:
            return _core.solve(scene, settings, progress, probed)
        return executor.solve(scene, settings, progress, probed)

    def solve_here() -> _core.Solution:
        if settings.refine_to_error > 0:
            probe = None if executor is None else (lambda: executor.probe_sides(scene, settings, progress))
            solution = refined_solve(scene, settings, solve_once, sides, progress, probe)
        else:
            solution = solve_once(sides)
        return solution if split is None else split.solution(solution)

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
