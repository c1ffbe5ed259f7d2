"""bsgi: global illumination with tensor-product B-spline radiance.

The numpy-level API of the compiled core (no Blender needed)::

    import bsgi
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", corners, albedo=(0.8, 0.8, 0.8), emission=(0, 0, 0))
    scene.add_bilinear_patch("lamp", lamp_corners, albedo=(0, 0, 0), emission=(10, 10, 10),
                             receiver=False, occluder=False)
    solution = bsgi.solve(scene, bsgi.SolverSettings.preset("preview"))
    radiance = solution.radiance[0].evaluate(uv)     # (N, 3) outgoing radiance at (u, v)

Splines on their own (paper sections 2 and 3)::

    hemi = bsgi.HemisphereMap.for_max_angle(0.05)              # (20)-(22), R = sqrt(1 - sin 0.05)
    s = bsgi.KnotVector.clamped_uniform(16, 2, 1e-3, 1 - 1e-3)  # (19) on [eps, 1 - eps]
    a = bsgi.KnotVector.symmetric(16, 2, hemi.radius)           # (24) on [-R, R]
    L = bsgi.TensorSpline([s, s, a, a], channels=3)
    bsgi.fit(L, lambda x: f(x), method="quadratic")             # x: (N, 4) nodes -> (N, 3)
    rgb = L.evaluate_directions(uv, directions, hemi)           # (N, 2), (N, 3) -> (N, 3)

Geometry and materials: ``NurbsSurface`` (Blender's NURBS, exact), ``MeshChart`` (a mesh with a
UV map), ``BilinearPatch``/``TrianglePatch``, all with ``evaluate(uv)`` giving points and the
local frame (1)-(3); ``RayCaster(surfaces)`` for batched Embree hits returning (surface, u, v),
point and frame; BSDFs ``Lambert``, ``NormalizedPhong``, ``AshikhminShirley``, ``GgxReflection``,
``DiffuseGgx``, ``SmoothDielectric``, ``RoughDielectric`` and ``Emission`` with eval/pdf/sample.

Errors are Python exceptions: ValueError for invalid input (knots, shapes, degrees, geometry,
naming the surface), bsgi.MemoryBudgetError (a MemoryError) for splines over the memory budget,
RuntimeError for a solve over its memory budget, bsgi.SolveCancelled for a cancelled solve.

Surfaces that others pass through are solved split along those lines (bsgi.split, paper section
5.1; ``settings.split_crossings``): a solution answers for the scene it was given.

Refinement where the per-surface error estimate is high: ``settings.refine_to_error = 0.02`` before
``bsgi.solve`` (bsgi.refine; ``solution.refinement`` reports it).

On a Ray cluster: ``bsgi.solve(scene, settings, executor=bsgi.RayExecutor("auto"))`` (Ray is
optional, imported then); scenes pickle, for its workers.
"""
from __future__ import annotations

from ._core import (
    Bsdf,
    BumpedLambert,
    Emission,
    FitRule,
    HemisphereMap,
    KnotVector,
    MemoryBudgetError,
    Progress,
    RayCaster,
    SidesProbe,
    SolveCancelled,
    SolveSteps,
    Solution,
    SolverSettings,
    Surface,
    SurfaceRadiance,
    TensorSpline,
    blender_knots,
    blender_nurbs_problem,
    estimate_solve_bytes,
    fit_from_samples,
    fitting_nodes,
    sharpen_samples,
    memory_budget,
    probe_sides,
    set_memory_budget,
)
from .fitting import fit
from .ray_executor import RayExecutor
from .rebuildable import (  # the compiled classes, keeping what they were built from (a scene pickles)
    AshikhminShirley,
    BilinearPatch,
    DiffuseGgx,
    GgxReflection,
    Lambert,
    MeshChart,
    NormalizedPhong,
    NurbsSurface,
    RoughDielectric,
    Scene,
    SmoothDielectric,
    SplitPiece,
    TrianglePatch,
)
from .solution_io import StoredSolution, load_solution, save_solution, spline_from_arrays, spline_to_arrays
from .solve import solve

__all__ = [
    "AshikhminShirley",
    "BilinearPatch",
    "Bsdf",
    "BumpedLambert",
    "DiffuseGgx",
    "Emission",
    "FitRule",
    "GgxReflection",
    "HemisphereMap",
    "KnotVector",
    "Lambert",
    "MemoryBudgetError",
    "MeshChart",
    "NormalizedPhong",
    "NurbsSurface",
    "Progress",
    "RayCaster",
    "RayExecutor",
    "RoughDielectric",
    "Scene",
    "SmoothDielectric",
    "SidesProbe",
    "SplitPiece",
    "SolveCancelled",
    "SolveSteps",
    "Solution",
    "SolverSettings",
    "StoredSolution",
    "Surface",
    "SurfaceRadiance",
    "TensorSpline",
    "TrianglePatch",
    "blender_knots",
    "blender_nurbs_problem",
    "estimate_solve_bytes",
    "fit",
    "fit_from_samples",
    "fitting_nodes",
    "sharpen_samples",
    "load_solution",
    "memory_budget",
    "probe_sides",
    "save_solution",
    "set_memory_budget",
    "solve",
    "spline_from_arrays",
    "spline_to_arrays",
]
__version__ = "0.1.0"
