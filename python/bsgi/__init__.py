"""bsgi: global illumination with tensor-product B-spline radiance.

The numpy-level API of the compiled core (no Blender needed)::

    import bsgi
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", corners, albedo=(0.8, 0.8, 0.8), emission=(0, 0, 0))
    scene.add_bilinear_patch("lamp", lamp_corners, albedo=(0, 0, 0), emission=(10, 10, 10),
                             receiver=False, occluder=False)
    solution = bsgi.solve(scene, bsgi.SolverSettings())
    radiance = solution.radiance[0].evaluate(uv)     # (N, 3) outgoing radiance at (u, v)

Geometry and materials: ``NurbsSurface`` (Blender's NURBS, exact), ``MeshChart`` (a mesh with a
UV map), ``BilinearPatch``/``TrianglePatch``, all with ``evaluate(uv)`` giving points and the
local frame (1)-(3); ``RayCaster(surfaces)`` for batched Embree hits returning (surface, u, v),
point and frame; BSDFs ``Lambert``, ``NormalizedPhong``, ``AshikhminShirley``, ``GgxReflection``,
``SmoothDielectric``, ``RoughDielectric`` and ``Emission`` with eval/pdf/sample.
"""
from __future__ import annotations

from ._core import (
    AshikhminShirley,
    BilinearPatch,
    Bsdf,
    Emission,
    DiffuseGgx,
    GgxReflection,
    KnotVector,
    Lambert,
    MeshChart,
    NormalizedPhong,
    NurbsSurface,
    Progress,
    RayCaster,
    RoughDielectric,
    Scene,
    SmoothDielectric,
    SolveCancelled,
    Solution,
    SurfaceRadiance,
    SolverSettings,
    Surface,
    TensorSpline,
    TrianglePatch,
    blender_knots,
    blender_nurbs_problem,
    estimate_solve_bytes,
)
from .solution_io import StoredSolution, load_solution, save_solution, spline_from_arrays, spline_to_arrays
from .solve import solve

__all__ = [
    "AshikhminShirley",
    "BilinearPatch",
    "Bsdf",
    "Emission",
    "DiffuseGgx",
    "GgxReflection",
    "KnotVector",
    "Lambert",
    "MeshChart",
    "NormalizedPhong",
    "NurbsSurface",
    "Progress",
    "RayCaster",
    "RoughDielectric",
    "Scene",
    "SmoothDielectric",
    "SolveCancelled",
    "Solution",
    "SurfaceRadiance",
    "SolverSettings",
    "Surface",
    "TensorSpline",
    "TrianglePatch",
    "blender_knots",
    "blender_nurbs_problem",
    "estimate_solve_bytes",
    "load_solution",
    "save_solution",
    "solve",
    "spline_from_arrays",
    "spline_to_arrays",
    "StoredSolution",
]
__version__ = "0.1.0"
