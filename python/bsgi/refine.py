"""Refinement driven by the per-surface error estimate (SolverSettings.refine_to_error).

After a solve, every receiving surface whose estimated error (reports[i]["estimated_error"]) is
over the target is refined where its estimate says its error is (error_parts): mostly its own
spline's fit (the part at least half the estimate), it gets refine_factor times its spatial
coefficients per direction (Scene.set_spatial_coeffs); mostly the final gather's integration, it
gets twice the integration nodes per axis there (Scene.set_integration_factor, four times that
surface's final-gather rays). Then the scene is solved again, until every surface meets the
target or a budget stops it: refine_passes solves beyond the first, the memory estimate of the
refined scene against memory_budget_mb, (if > 0) refine_seconds for all passes and (if > 0)
refine_cost, the rays of the passes after the first against the first's. The next pass's rays are
predicted from the last one's (predicted_rays: each surface's share grown by its coefficients'
growth, its final gathers' and estimate's share by four more with twice the integration nodes),
its time as the last one's in proportion. Where a pass refining every surface over the target
would overrun a budget, the surfaces with the highest estimates are refined, as many as the
budgets allow (the longest such prefix, found by bisection: each budget grows with each surface
added); where the worst one alone does not fit, the next ones are tried without it, and a surface left
out whose refinement is of both parts gets its larger part alone where that fits; only where
nothing fits does refinement stop. The rays and the memory
estimate are the same wherever the solve runs, so refinement under them is too (the time is
not). The other parts (the splines the gather read, the bounces' tail) do not fall with the
surface's own refinement (the first falls with its neighbours'). A surface whose estimate did not
fall by a tenth after its refinement is not refined again (the estimate's noise, or an error the
refinement cannot reach).

The loop is here, around a whole solve, so that it works wherever the solve runs (here or on a
Ray cluster): each pass is a solve from scratch; the scene's options are restored afterwards.
Which sides of each surface are solved does not change with its coefficients: they are probed
once, for every pass and every memory estimate.
The solution carries ``refinement``: the passes, why refinement stopped, the passes a budget
trimmed, each pass's rays and (after the first) their prediction, the rays and seconds of all
passes, and per receiving surface its final estimate, coefficients, integration factor and status.
"""
from __future__ import annotations

import math
import time
from typing import Callable, Optional

from . import _core

# Statuses of a receiving surface in solution.refinement["surfaces"]; "not its own": its estimate
# is mostly neither its fit nor its integration.
MET, OVER, NO_GAIN, NOT_OWN = "met", "over target", "no gain", "not its own"
GAIN = 0.9  # a refined surface's estimate must fall below GAIN times its previous one
INTEGRATION_STEP = 2  # a refinement's factor on the integration nodes per axis


def receivers(solution: _core.Solution) -> list:
    """Scene indices of the receiving surfaces, in the order of their reports (the first ones)."""
    return [i for i, r in enumerate(solution.radiance) if r is not None]


def coarse_coeffs(report: dict, settings: _core.SolverSettings) -> int:
    """Spatial coefficients per direction the surface iterated with (the larger of u and v): the
    final gather's are final_spatial_factor times more."""
    scale = settings.final_spatial_factor if settings.final_gather else 1
    return max(report["shape"][:2]) // scale


def own_part(report: dict, part: str) -> bool:
    """Whether refining the surface's `part` ("fit": its spline, "integration": its final
    gather's nodes) can lower its estimate: that part is at least half of it (the other parts
    added in quadrature are then at most 0.87 of it)."""
    return report["error_parts"][part] >= 0.5 * report["estimated_error"]


def refinements(scene: _core.Scene, index: int, report: dict, settings: _core.SolverSettings) -> dict:
    """What refining surface `index` changes: {"spatial_coeffs": n} where its fit is most of its
    estimate, {"integration_factor": f} where the final gather's integration is (and can grow)."""
    out = {}
    if own_part(report, "fit"):
        coarse = coarse_coeffs(report, settings)
        out["spatial_coeffs"] = max(math.ceil(coarse * settings.refine_factor), coarse + 1)
    factor = scene.integration_factor(index) * INTEGRATION_STEP
    if settings.final_gather and own_part(report, "integration") and factor <= _core.Scene.MAX_INTEGRATION_FACTOR:
        out["integration_factor"] = factor
    return out


def coefficient_count(report: dict) -> int:
    return math.prod(report["shape"])


def spatial_growth(change: dict, report: dict, settings: _core.SolverSettings) -> float:
    """A refined surface's coefficients (and nodes) against its last pass's."""
    return max(change.get("spatial_coeffs", 0) / coarse_coeffs(report, settings), 1.0) ** 2


def predicted_rays(scene: _core.Scene, stats: dict, reports: dict, chosen: dict, settings: _core.SolverSettings) -> float:
    """The next pass's rays (the error estimate's with them) refining `chosen` (scene index ->
    change) among the receiving surfaces' `reports` (scene index -> report), from the last pass's
    `stats`: the final gathers' rays and the estimate's shared among the surfaces by coefficients
    times integration nodes (a surface's integration factor squared), the others (direct light,
    bounces, the coarse correction) by coefficients; a surface's shares grown by its coefficients'
    growth, and its final gathers' and estimate's by four more where its integration nodes per
    axis double."""
    final = stats["final_rays"] + stats["estimate_rays"]
    other = stats["rays"] - stats["final_rays"]
    count = {i: coefficient_count(r) for i, r in reports.items()}
    weight = {i: count[i] * scene.integration_factor(i) ** 2 for i in reports}
    total_count, total_weight = sum(count.values()), sum(weight.values())
    rays = 0.0
    for i, r in reports.items():
        change = chosen.get(i, {})
        grow = spatial_growth(change, r, settings)
        integration = INTEGRATION_STEP ** 2 if "integration_factor" in change else 1
        rays += other * count[i] / total_count * grow + final * weight[i] / total_weight * grow * integration
    return rays


def longest_fitting_prefix(order: list, overrun: Callable[[list], Optional[str]]) -> tuple:
    """The surfaces of `order` (worst first) a pass refines: the longest prefix whose refinement
    `overrun` finds within every budget (bisection: each budget grows with each surface added).
    Where not even the first one fits alone, it is passed over for the next ones (a 4D surface
    whose spatial refinement alone overruns the cost budget leaves the cheaper refinements of
    the surfaces after it possible), until one fits or none is left. Returns (the surfaces
    chosen, the budget that cut the rest or None)."""
    budget = None
    for start in range(len(order)):
        candidates = order[start:]
        overruns = {0: None, len(candidates): overrun(candidates)}  # prefix length -> the budget it overruns
        fitting, lacking = 0, len(candidates)  # the longest prefix that fits, the shortest that does not
        if overruns[lacking] is None:
            return candidates, budget
        while lacking - fitting > 1:
            middle = (fitting + lacking) // 2
            overruns[middle] = overrun(candidates[:middle])
            fitting, lacking = (middle, lacking) if overruns[middle] is None else (fitting, middle)
        budget = overruns[lacking]
        if fitting:
            return candidates[:fitting], budget
    return [], budget


def larger_part(change: dict, report: dict) -> dict:
    """Of a refinement of both parts (spatial coefficients and integration nodes), the one whose
    part of the estimate is larger; {} for a refinement of one part."""
    if len(change) < 2:
        return {}
    parts = report["error_parts"]
    key = "spatial_coeffs" if parts["fit"] >= parts["integration"] else "integration_factor"
    return {key: change[key]}


def with_lesser_refinements(chosen: dict, left_out: list, lesser: dict,
                            overrun: Callable[[dict], Optional[str]]) -> dict:
    """`chosen` (scene index -> change) and, worst first, each surface of `left_out` with its
    lesser refinement (`lesser`: one part of two) where the pass still fits every budget with it."""
    for i in left_out:
        if lesser.get(i) and overrun({**chosen, i: lesser[i]}) is None:
            chosen = {**chosen, i: lesser[i]}
    return chosen


def refined_solve(scene: _core.Scene, settings: _core.SolverSettings,
                  solve_once: Callable[[list], _core.Solution], sides: Optional[list] = None,
                  progress: Optional[_core.Progress] = None,
                  probe_sides: Optional[Callable[[], list]] = None) -> _core.Solution:
    """Solves with solve_once(sides) and again with refined surfaces, as the module says (``sides``
    probed first if not given: by probe_sides(), or here). ``progress`` (the one solve_once advances) names each pass after
    the first in its stage ("refinement 1 of at most 2: ..."): its fraction starts again at 0."""
    target = settings.refine_to_error
    if not settings.estimate_error:
        raise ValueError(f"solver settings: refine_to_error ({target:g}; the final preset's is 0.01) needs "
                         "estimate_error: set refine_to_error = 0 to solve once without the estimate")
    own = {i: (scene.spatial_coeffs(i), scene.integration_factor(i)) for i in range(len(scene))}
    start = time.perf_counter()
    rays = estimate_rays = 0
    refined: dict = {}  # scene index -> times refined
    no_gain: set = set()
    stopped = None

    def apply(changes: dict):
        for i, change in changes.items():
            if "spatial_coeffs" in change:
                scene.set_spatial_coeffs(i, change["spatial_coeffs"])
            if "integration_factor" in change:
                scene.set_integration_factor(i, change["integration_factor"])

    def overrun(chosen: dict, reports: dict, last_seconds: float, stats: dict) -> Optional[str]:
        """The budget a pass refining `chosen` would overrun, or None."""
        expected = predicted_rays(scene, stats, reports, chosen, settings)
        if settings.refine_cost > 0 and rays + estimate_rays - first_rays + expected > settings.refine_cost * first_rays:
            return "cost"
        seconds = last_seconds * expected / (stats["rays"] + stats["estimate_rays"])
        if settings.refine_seconds > 0 and time.perf_counter() - start + seconds > settings.refine_seconds:
            return "time"
        before = {i: {"spatial_coeffs": scene.spatial_coeffs(i), "integration_factor": scene.integration_factor(i)}
                  for i in chosen}
        apply(chosen)
        try:
            if _core.estimate_solve_bytes(scene, settings, sides) > settings.memory_budget_mb * 1024 * 1024:
                return "memory"
        finally:
            apply(before)
        return None

    trimmed = []  # per pass a budget trimmed: its number, the budget, the surfaces it left out, those refined in part
    traced, predicted = [], []  # per pass its rays (the estimate's with them); per pass after the first, as predicted
    try:
        pass_start = time.perf_counter()
        if sides is None:
            sides = probe_sides() if probe_sides is not None else _core.probe_sides(scene, settings)[0]
        solution = solve_once(sides)
        passes = 0
        first_rays = solution.stats["rays"] + solution.stats["estimate_rays"]
        while True:
            last_seconds = time.perf_counter() - pass_start
            rays += solution.stats["rays"]
            estimate_rays += solution.stats["estimate_rays"]
            traced.append(solution.stats["rays"] + solution.stats["estimate_rays"])
            reports = dict(zip(receivers(solution), solution.reports))
            over = {i: r for i, r in reports.items() if r["estimated_error"] > target and i not in no_gain}
            changes = {i: c for i, r in over.items() if (c := refinements(scene, i, r, settings))}
            if not changes:
                break
            if passes >= settings.refine_passes:
                stopped = "passes"
                break
            # The worst first (ties by scene index, so that every run chooses alike).
            order = sorted(changes, key=lambda i: (-over[i]["estimated_error"], i))
            fitting, budget = longest_fitting_prefix(
                order, lambda prefix: overrun({i: changes[i] for i in prefix}, reports, last_seconds, solution.stats))
            # A surface left out whose refinement is of both parts may fit with its larger part alone
            # (a 4D surface's spatial coefficients without its integration nodes' four times the rays).
            left_out = [i for i in order if i not in fitting]
            chosen = with_lesser_refinements(
                {i: changes[i] for i in fitting}, left_out, {i: larger_part(changes[i], over[i]) for i in left_out},
                lambda trial: overrun(trial, reports, last_seconds, solution.stats))
            if not chosen:
                stopped = budget
                break
            if len(fitting) < len(order):
                trimmed.append({"pass": passes + 1, "budget": budget, "left_out": len(order) - len(chosen),
                                "in_part": len(chosen) - len(fitting)})
            changes = chosen
            predicted.append(predicted_rays(scene, solution.stats, reports, changes, settings))
            apply(changes)
            previous = {i: over[i]["estimated_error"] for i in changes}
            pass_start = time.perf_counter()
            if progress is not None:
                progress.begin_pass(f"refinement {passes + 1} of at most {settings.refine_passes}")
            solution = solve_once(sides)
            passes += 1
            errors = {i: r["estimated_error"] for i, r in zip(receivers(solution), solution.reports)}
            for i in changes:
                refined[i] = refined.get(i, 0) + 1
                if not errors[i] < GAIN * previous[i]:
                    no_gain.add(i)
        # What the last solve used, and which surfaces could still be refined, before the
        # scene's options are restored.
        last_factor = {i: scene.integration_factor(i) for i in receivers(solution)}
        refinable = {i for i, r in zip(receivers(solution), solution.reports) if refinements(scene, i, r, settings)}
    finally:
        if progress is not None:
            progress.begin_pass("")
        for i, (n, f) in own.items():
            if scene.spatial_coeffs(i) != n:
                scene.set_spatial_coeffs(i, n)
            if scene.integration_factor(i) != f:
                scene.set_integration_factor(i, f)
    surfaces = []
    for i, r in zip(receivers(solution), solution.reports):
        error = r["estimated_error"]
        status = MET if error <= target else (NO_GAIN if i in no_gain else OVER if i in refinable else NOT_OWN)
        surfaces.append({"name": r["name"], "index": i, "estimated_error": error, "shape": list(r["shape"]),
                         "integration_factor": last_factor[i], "error_parts": dict(r["error_parts"]),
                         "refined": refined.get(i, 0), "status": status})
    solution.refinement = {"target": target, "passes": passes, "stopped": stopped, "trimmed": trimmed,
                           "pass_rays": traced, "predicted_rays": predicted, "rays": rays,
                           "estimate_rays": estimate_rays, "seconds": time.perf_counter() - start,
                           "surfaces": surfaces}
    return solution
