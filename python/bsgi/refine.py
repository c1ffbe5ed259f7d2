"""Refinement driven by the per-surface error estimate (SolverSettings.refine_to_error).

After a solve, every receiving surface whose estimated error (reports[i]["estimated_error"]) is
over the target gets refine_factor times its spatial coefficients per direction (the scene's
per-surface option, as Scene.set_spatial_coeffs sets it) and the scene is solved again, until
every surface meets the target or a budget stops it: refine_passes solves beyond the first, the
memory estimate of the refined scene against memory_budget_mb, and (if > 0) refine_seconds for
all passes, the next pass's time predicted from the last one's and the growth of the
coefficients. Only surfaces whose estimate is mostly their own spline's fit (error_parts["fit"] at
least half the estimate) are refined: the other parts (the splines the gather read, integration,
the bounces' tail) do not fall with the surface's own knots (the first falls with its neighbours'
refinement). A surface whose estimate did not fall by a tenth after its refinement is not refined
again (the estimate's noise, or a fit error the knots cannot reach).

The loop is here, around a whole solve, so that it works wherever the solve runs (here or on a
Ray cluster): each pass is a solve from scratch; the scene's options are restored afterwards.
Which sides of each surface are solved does not change with its coefficients: they are probed
once, for every pass and every memory estimate.
The solution carries ``refinement``: the passes, why refinement stopped, the rays and seconds of
all passes, and per receiving surface its final estimate, coefficients and status.
"""
from __future__ import annotations

import math
import time
from typing import Callable, Optional

from . import _core

# Statuses of a receiving surface in solution.refinement["surfaces"].
MET, OVER, NO_GAIN, NOT_FIT = "met", "over target", "no gain", "not its fit"
GAIN = 0.9  # a refined surface's estimate must fall below GAIN times its previous one


def receivers(solution: _core.Solution) -> list:
    """Scene indices of the receiving surfaces, in the order of their reports (the first ones)."""
    return [i for i, r in enumerate(solution.radiance) if r is not None]


def coarse_coeffs(report: dict, settings: _core.SolverSettings) -> int:
    """Spatial coefficients per direction the surface iterated with (the larger of u and v): the
    final gather's are final_spatial_factor times more."""
    scale = settings.final_spatial_factor if settings.final_gather else 1
    return max(report["shape"][:2]) // scale


def own_fit(report: dict) -> bool:
    """Whether refining the surface's own spline can lower its estimate: its fit is at least
    half of it (the other parts added in quadrature are then at most 0.87 of it)."""
    return report["error_parts"]["fit"] >= 0.5 * report["estimated_error"]


def coefficient_count(report: dict) -> int:
    return math.prod(report["shape"])


def refined_solve(scene: _core.Scene, settings: _core.SolverSettings,
                  solve_once: Callable[[list], _core.Solution], sides: Optional[list] = None) -> _core.Solution:
    """Solves with solve_once(sides) and again with refined surfaces, as the module says (``sides``
    probed here if not given)."""
    if not settings.estimate_error:
        raise ValueError("solver settings: refine_to_error needs estimate_error")
    target = settings.refine_to_error
    own = {i: scene.spatial_coeffs(i) for i in range(len(scene))}
    start = time.perf_counter()
    rays = estimate_rays = 0
    refined: dict = {}  # scene index -> times refined
    no_gain: set = set()
    stopped = None
    try:
        pass_start = time.perf_counter()
        if sides is None:
            sides = _core.probe_sides(scene, settings)[0]
        solution = solve_once(sides)
        passes = 0
        while True:
            last_seconds = time.perf_counter() - pass_start
            rays += solution.stats["rays"]
            estimate_rays += solution.stats["estimate_rays"]
            index = receivers(solution)
            reports = solution.reports[:len(index)]
            over = [(i, r) for i, r in zip(index, reports)
                    if r["estimated_error"] > target and i not in no_gain and own_fit(r)]
            if not over:
                break
            if passes >= settings.refine_passes:
                stopped = "passes"
                break
            counts = {i: max(math.ceil(coarse_coeffs(r, settings) * settings.refine_factor),
                             coarse_coeffs(r, settings) + 1) for i, r in over}
            before = {i: scene.spatial_coeffs(i) for i in counts}
            for i, n in counts.items():
                scene.set_spatial_coeffs(i, n)
            if _core.estimate_solve_bytes(scene, settings, sides) > settings.memory_budget_mb * 1024 * 1024:
                stopped = "memory"
            elif settings.refine_seconds > 0:
                old = sum(coefficient_count(r) for r in reports)
                growth = {i: (counts[i] / coarse_coeffs(r, settings)) ** 2 for i, r in over}
                new = sum(coefficient_count(r) * growth.get(i, 1.0) for i, r in zip(index, reports))
                if time.perf_counter() - start + last_seconds * new / old > settings.refine_seconds:
                    stopped = "time"
            if stopped:
                for i, n in before.items():
                    scene.set_spatial_coeffs(i, n)
                break
            previous = {i: r["estimated_error"] for i, r in over}
            pass_start = time.perf_counter()
            solution = solve_once(sides)
            passes += 1
            errors = {i: r["estimated_error"] for i, r in zip(receivers(solution), solution.reports)}
            for i in counts:
                refined[i] = refined.get(i, 0) + 1
                if not errors[i] < GAIN * previous[i]:
                    no_gain.add(i)
    finally:
        for i, n in own.items():
            if scene.spatial_coeffs(i) != n:
                scene.set_spatial_coeffs(i, n)
    surfaces = []
    for i, r in zip(receivers(solution), solution.reports):
        error = r["estimated_error"]
        status = MET if error <= target else (NO_GAIN if i in no_gain else OVER if own_fit(r) else NOT_FIT)
        surfaces.append({"name": r["name"], "index": i, "estimated_error": error, "shape": list(r["shape"]),
                         "error_parts": dict(r["error_parts"]), "refined": refined.get(i, 0), "status": status})
    solution.refinement = {"target": target, "passes": passes, "stopped": stopped, "rays": rays,
                           "estimate_rays": estimate_rays, "seconds": time.perf_counter() - start,
                           "surfaces": surfaces}
    return solution
