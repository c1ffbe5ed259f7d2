"""Fitting a tensor-product spline to a vectorised Python function."""
from __future__ import annotations

from typing import Callable, Sequence, Union

import numpy as np

from . import _core

Method = Union[str, Sequence[str]]


def fit(
    spline: _core.TensorSpline,
    f: Callable[[np.ndarray], np.ndarray],
    method: Method = "schoenberg",
    vectorized: bool = True,
) -> _core.TensorSpline:
    """Sets the coefficients of ``spline`` from ``f`` by a local rule, one dimension at a time.

    ``method`` is ``"schoenberg"`` (values at the knot averages (12), (25)), ``"quadratic"``
    (the quasi-interpolant of section 2.2.1, degree 2) or ``"cubic"`` (Lee-Lyche-Morken, degree
    3), or one of them per dimension. ``f`` receives every node of the tensor grid at once as an
    array of shape (N, dims) and returns (N, channels) (or (N,) for one channel). With
    ``vectorized=False`` it receives one point (dims,) at a time and returns (channels,) (the
    core's callback fit: no grid of points is built in Python). Returns the spline. Raises
    ValueError if ``f`` returns the wrong shape, MemoryBudgetError if the grid of nodes is over
    the memory budget.
    """
    if not vectorized:
        _core._fit_pointwise(spline, f, method)
        return spline
    nodes = _core.fitting_nodes(spline, method)
    shape = tuple(len(n) for n in nodes)
    # The grid (points and values) is checked against the budget before it is built.
    points = int(np.prod(shape, dtype=np.int64))
    need = points * (spline.dims + spline.channels) * 8
    if need > _core.memory_budget():
        raise _core.MemoryBudgetError(
            f"fitting grid: {' x '.join(map(str, shape))} nodes x ({spline.dims} parameters + "
            f"{spline.channels} channels) x 8 bytes = {need} bytes exceeds the memory budget of "
            f"{_core.memory_budget()} bytes (bsgi.set_memory_budget raises it)"
        )
    grid = np.stack(np.meshgrid(*nodes, indexing="ij"), axis=-1).reshape(-1, spline.dims)
    values = np.asarray(f(grid), dtype=np.float64)
    if values.ndim == 1 and spline.channels == 1:
        values = values[:, None]
    if values.shape != (grid.shape[0], spline.channels):
        raise ValueError(
            f"fit: f returned shape {values.shape}, expected ({grid.shape[0]}, {spline.channels})"
        )
    _core.fit_from_samples(spline, values.reshape(shape + (spline.channels,)), method)
    return spline
