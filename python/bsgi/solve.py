"""Running a solve with progress reports and cancellation."""
from __future__ import annotations

import threading
from typing import Callable, Optional

from . import _core

ProgressCallback = Callable[[float, str], Optional[bool]]


def solve(
    scene: _core.Scene,
    settings: Optional[_core.SolverSettings] = None,
    progress: Optional[_core.Progress] = None,
    on_progress: Optional[ProgressCallback] = None,
    poll_seconds: float = 0.1,
) -> _core.Solution:
    """Solve the scene's light transport (paper Algorithm 1).

    The core releases the GIL and uses all threads. ``progress`` can be polled and cancelled from
    another thread. ``on_progress(fraction, stage)`` is called on this thread while the solve runs;
    returning False cancels it. A cancelled solve raises :class:`bsgi.SolveCancelled`.
    """
    settings = settings if settings is not None else _core.SolverSettings()
    progress = progress if progress is not None else _core.Progress()
    if on_progress is None:
        return _core.solve(scene, settings, progress)

    result: dict = {}

    def run() -> None:
        try:
            result["solution"] = _core.solve(scene, settings, progress)
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
