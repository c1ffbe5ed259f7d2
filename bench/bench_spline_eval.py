"""Evaluation speed of the 4D radiance spline L(u, v, alpha, beta) against scipy's NdBSpline.

The spline: degree 2 in all four variables, 16 coefficients per variable (section 5.1), RGB;
spatial knots (19) on [eps, 1 - eps], angular knots (24) on [-R, R]. Inputs: 1,000,000 random
surface parameters (u, v) and random local directions on the upper hemisphere. bsgi evaluates
L(u, v, direction) including the inverse hemisphere map; scipy evaluates the same spline at the
same points with (alpha, beta) mapped beforehand in numpy (scipy has no such map), so only its
spline evaluation is timed, which favours scipy slightly.

Figures: evaluations per second with one thread and with all threads, for float64 coefficients
(the default: agrees with scipy to rounding) and float32 coefficients (half the memory, float
arithmetic, error bound (D (d + 2) + 1) 2^-24 max|a| = 17 * 2^-24 * max|a| here), the same inputs
ordered by (u, v) cell (coherent queries), and the arithmetic limits of the kernel.
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


def best_time(fn, repeats: int = REPEATS, clock=time.thread_time) -> float:
    """Best of `repeats` runs. One-thread figures (scipy's and ours, both in the calling thread)
    use the thread's CPU time: on a shared machine wall time also counts the time spent waiting
    for a core, which says nothing about either evaluator. All-thread figures need wall time
    (clock=time.perf_counter) and are only meaningful on an otherwise idle machine."""
    best = float("inf")
    for _ in range(repeats):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
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
    tall = best_time(lambda: spline.evaluate_directions(uv, dirs, hemisphere, threads=0), clock=time.perf_counter)
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

    # The same inputs ordered by their (u, v) knot cell: what coherent queries (a surface seen
    # pixel by pixel) get from the caches. Not the headline figure.
    cell = np.floor(np.clip(uv, 0, 1 - 1e-12) * (COEFFS - DEGREE)).astype(int) @ [COEFFS, 1]
    order = np.argsort(cell, kind="stable")
    uv_s, dirs_s = np.ascontiguousarray(uv[order]), np.ascontiguousarray(dirs[order])
    s1 = N / best_time(lambda: spline.evaluate_directions(uv_s, dirs_s, hemisphere, threads=1))
    s32 = N / best_time(lambda: spline32.evaluate_directions(uv_s, dirs_s, hemisphere, threads=1))

    # Arithmetic limits of the contraction, from the measured peak of 256-bit FMAs on one thread:
    # - useful work: 3^4 coefficients x 3 channels = 243 multiply-adds per evaluation, at 4
    #   (float64) or 8 (float32) per 256-bit FMA;
    # - issued work: the vector multiply-adds the kernel actually issues (rows of 9 values in
    #   whole registers, the nested sums (18), the final products), in 256-bit equivalents:
    #   float64 81 + 27 + 9 = 117 (a row of 9 values: two 256-bit operations and a scalar one,
    #   counted as a whole); float32 with AVX-512 27 + 9 + 3 + 3 = 42 512-bit operations
    #   = 84 (a 512-bit operation takes both 256-bit halves here), with AVX2 54 + 18 + 6 = 78.
    fma = bsgi._core._fma_peak_per_second()
    isa = bsgi._core._kernel_isa()
    issued_f32 = 84 if isa == "x86-64-v4" else 78
    print(f"  (kernels: {isa}; limits count only the contraction's multiply-adds)")
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
        "eval_per_s_1t_sorted_uv": s1,
        "eval_f32_per_s_1t_sorted_uv": s32,
        "eval_fma256_per_s_1t": fma,
        "eval_limit_useful_per_s_1t": fma * 4 / 243,
        "eval_limit_useful_f32_per_s_1t": fma * 8 / 243,
        "eval_limit_issued_per_s_1t": fma / 117,
        "eval_limit_issued_f32_per_s_1t": fma / issued_f32,
        "eval_fraction_of_issued_limit_1t": r1 / (fma / 117),
        "eval_f32_fraction_of_issued_limit_1t": f1 / (fma / issued_f32),
    }


if __name__ == "__main__":
    for k, v in run().items():
        print(k, v)
