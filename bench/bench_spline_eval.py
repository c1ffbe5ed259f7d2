"""Evaluation speed of the 4D radiance spline L(u, v, alpha, beta) against scipy's NdBSpline.

The spline: degree 2 in all four variables, 16 coefficients per variable (section 5.1), RGB;
spatial knots (19) on [eps, 1 - eps], angular knots (24) on [-R, R]. Inputs: 1,000,000 random
surface parameters (u, v) and random local directions on the upper hemisphere. bsgi evaluates
L(u, v, direction) including the inverse hemisphere map; scipy evaluates the same spline at the
same points with (alpha, beta) mapped beforehand in numpy (scipy has no such map), so only its
spline evaluation is timed, which favours scipy slightly.

Figures: evaluations per second with one thread and with all threads, for float64 coefficients
(the default: agrees with scipy to rounding) and float32 coefficients (half the memory, float
arithmetic, error bound 18 * 2^-24 * max|a|), and the arithmetic limit of the kernel.
"""
from __future__ import annotations

import os
import time

import numpy as np
from scipy.interpolate import NdBSpline

import bsgi

N = 1_000_000
COEFFS = 16
DEGREE = 2
EPS = 1e-3
DELTA = 0.05  # largest polar angle pi/2 - DELTA
REPEATS = 5


def best_time(fn, repeats: int = REPEATS) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def disc_from_directions(d: np.ndarray, R: float) -> np.ndarray:
    """Inverse of (20)-(22) with the pull-in, written independently of bsgi: for a unit
    direction r^2 = 1 - z and (alpha, beta) = (x, y) / sqrt(1 + z)."""
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    ab = d[:, :2] / np.sqrt(1 + d[:, 2:3])
    r = np.linalg.norm(ab, axis=1, keepdims=True)
    return np.where(r > R, ab * (R / r), ab)


def make_inputs(rng: np.random.Generator):
    uv = rng.uniform(0, 1, (N, 2))
    z = rng.uniform(0, 1, N)  # uniform on the hemisphere
    phi = rng.uniform(-np.pi, np.pi, N)
    s = np.sqrt(1 - z * z)
    dirs = np.column_stack([s * np.cos(phi), s * np.sin(phi), z])
    return uv, dirs


def measure(spline, hemisphere, uv, dirs, reference, scipy_rate):
    out = spline.evaluate_directions(uv, dirs, hemisphere, threads=1)
    rel = float(np.max(np.abs(out - reference) / np.abs(reference)))
    t1 = best_time(lambda: spline.evaluate_directions(uv, dirs, hemisphere, threads=1))
    tall = best_time(lambda: spline.evaluate_directions(uv, dirs, hemisphere, threads=0))
    return N / t1, N / tall, rel


def run() -> dict:
    rng = np.random.default_rng(20020501)
    hemisphere = bsgi.HemisphereMap.for_max_angle(DELTA)
    R = hemisphere.radius
    spatial = bsgi.KnotVector.clamped_uniform(COEFFS, DEGREE, EPS, 1 - EPS)
    angular = bsgi.KnotVector.symmetric(COEFFS, DEGREE, R)
    spline = bsgi.TensorSpline([spatial, spatial, angular, angular], channels=3)
    spline.coefficients = rng.uniform(0.5, 1.5, spline.shape)  # radiance is positive
    spline32 = spline.with_precision("float32")
    uv, dirs = make_inputs(rng)

    # scipy on the same spline and points: (u, v) clamped to the domain as bsgi does, directions
    # mapped to the disc in numpy (not timed).
    peer = NdBSpline(tuple(a.knots for a in spline.axes), np.array(spline.coefficients), DEGREE)
    x = np.column_stack([np.clip(uv, EPS, 1 - EPS), disc_from_directions(dirs, R)])
    t_scipy = best_time(lambda: peer(x), repeats=2)
    reference = peer(x)
    scipy_rate = N / t_scipy

    r1, rall, rel = measure(spline, hemisphere, uv, dirs, reference, scipy_rate)
    f1, fall, frel = measure(spline32, hemisphere, uv, dirs, reference, scipy_rate)

    # Arithmetic limit: the contraction of 3^4 coefficients x 3 channels is 243 multiply-adds
    # per evaluation (81 AVX2 double / 27 AVX-512 float vector FMAs as the kernel issues them;
    # 2 FMA pipes, a 512-bit one takes both). Measured here against a pure FMA loop.
    fma_per_s = fma_peak()
    return {
        "eval_per_s_1t": r1,
        "eval_per_s_all": rall,
        "eval_scipy_per_s_1t": scipy_rate,
        "eval_speedup_vs_scipy_1t": r1 / scipy_rate,
        "eval_max_rel_diff_vs_scipy": rel,
        "eval_thread_scaling": rall / r1,
        "eval_threads": os.cpu_count() or 1,
        "eval_f32_per_s_1t": f1,
        "eval_f32_per_s_all": fall,
        "eval_f32_speedup_vs_scipy_1t": f1 / scipy_rate,
        "eval_f32_max_rel_diff_vs_scipy": frel,
        "eval_f32_thread_scaling": fall / f1,
        "eval_fma_ymm_per_s_1t": fma_per_s,
        "eval_limit_f64_per_s_1t": fma_per_s / 81,
        "eval_limit_f32_per_s_1t": fma_per_s / 2 / 27,
    }


def fma_peak() -> float:
    """256-bit FMAs per second on one thread, from numpy's dot product of long vectors resident
    in L1 is not a pure FMA stream; the core's figure is measured by bsgi itself."""
    return bsgi._core._fma_peak_per_second() if hasattr(bsgi._core, "_fma_peak_per_second") else float("nan")


if __name__ == "__main__":
    for k, v in run().items():
        print(k, v)
