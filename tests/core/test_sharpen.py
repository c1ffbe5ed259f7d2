"""Sharpening Schoenberg's fit from its own samples (sharpen.h): quadratics reproduced, the
measured order raised from 2 to 3 on smooth functions, no ringing across a step, non-negative
samples keep non-negative coefficients, tensor products, refusals."""
import numpy as np
import pytest

import bsgi
from test_fitting import knots, max_error, smooth


def sharpened(k, f, nodes=None):
    s = bsgi.TensorSpline([k], 1)
    bsgi.fit(s, lambda x: f(x[:, 0]), "schoenberg")
    bsgi.sharpen_samples(s, 0, [] if nodes is None else nodes)
    return s


def schoenberg(k, f):
    s = bsgi.TensorSpline([k], 1)
    return bsgi.fit(s, lambda x: f(x[:, 0]), "schoenberg")


@pytest.mark.parametrize("degree", [2, 3, 4, 5])
@pytest.mark.parametrize("kind", ["uniform", "random", "repeated", "graded"])
def test_reproduces_quadratics(degree, kind):
    rng = np.random.default_rng(degree * 11 + len(kind))
    p = np.polynomial.Polynomial([0.7, -1.3, 2.1])  # >= 0.5 on [0, 1]: no clamping at 0
    for n in (max(6, degree + 2), degree + 5, degree + 10):  # 6: the fewest with stencils clear of the ends
        k = knots(kind if n > degree + 4 else "uniform", n, degree, rng)
        assert max_error(sharpened(k, p), p) <= 1e-12, n
        assert max_error(schoenberg(k, p), p) > 1e-4  # Schoenberg alone does not
    # and not cubics
    q = np.polynomial.Polynomial([1.0, 0, 0, 1.0])
    assert max_error(sharpened(knots(kind, degree + 10, degree, rng), q), q) > 1e-6


def test_periodic_axis_converges_at_order_three_across_the_seam():
    f = lambda x: 2 + np.cos(2 * np.pi * x)  # noqa: E731
    errs = []
    for m in (8, 16, 32, 64):
        k = bsgi.KnotVector.periodic(np.linspace(0, 1, m + 1), 2)
        x = np.linspace(0, 1, 3001)
        errs.append([np.abs(s.evaluate(x[:, None])[:, 0] - f(x)).max() for s in (schoenberg(k, f), sharpened(k, f))])
    errs = np.array(errs)
    orders = np.log2(errs[:-1] / errs[1:])
    print("periodic orders, Schoenberg / sharpened:", orders.round(2).tolist())
    assert np.all(np.abs(orders[1:, 0] - 2) <= 0.2)
    assert np.all(orders[:, 1] >= 2.8)  # measured 3.63, 3.34, 3.11


@pytest.mark.parametrize("degree", [2, 3])
@pytest.mark.parametrize("kind", ["uniform", "graded"])
def test_convergence_order_three(degree, kind):
    h, err, err0 = [], [], []
    for n in (16, 32, 64, 128):
        k = knots(kind, n, degree)
        h.append(1 / (n - degree))
        err.append(max_error(sharpened(k, smooth), smooth))
        err0.append(max_error(schoenberg(k, smooth), smooth))
    slope = np.polyfit(np.log(h), np.log(err), 1)[0]
    slope0 = np.polyfit(np.log(h), np.log(err0), 1)[0]
    print(f"degree {degree} {kind}: order {slope0:.2f} -> {slope:.2f}, error at 128 {err0[-1]:.2e} -> {err[-1]:.2e}")
    assert slope >= 2.7 and abs(slope0 - 2) <= 0.3  # measured 2.94-3.85 (graded knots: superconvergent)
    assert err[-1] < err0[-1] / 10


@pytest.mark.parametrize("degree", [2, 3])
def test_a_step_does_not_ring(degree):
    # A shadow's edge: a jump anywhere between the nodes, and ramps (penumbrae) of widths from a
    # tenth to three knot spans. The sharpened spline stays within the two levels; a ramp of
    # three spans, smooth to the rule but for its two kinks, overshoots by 0.31% of its height
    # (degree 2; 0.79% degree 3; the correction alone: 6.9% for a jump, 2.3% for that ramp).
    rng = np.random.default_rng(degree)
    k = bsgi.KnotVector.clamped_uniform(16, degree, 0.0, 1.0)
    h = 1 / (16 - degree)
    x = np.linspace(0, 1, 4001)[:, None]
    for edge in rng.uniform(0.2, 0.8, 20):
        for width in (0, 0.1 * h, h, 3 * h):
            f = (lambda e, w: lambda t: np.clip((t - e) / w + 0.5, 0, 1) if w else (t > e).astype(float))(edge, width)
            v = sharpened(k, f).evaluate(x)[:, 0]
            allowed = 0.015 if width > h else 1e-12
            assert v.min() >= -allowed and v.max() <= 1 + allowed, (edge, width, v.min(), v.max())


def test_non_negative_samples_keep_non_negative_coefficients():
    # A dip to 0 (the light at the foot of a wall): the quadratic correction would take the
    # coefficient below 0; it stops at 0.
    k = bsgi.KnotVector.clamped_uniform(12, 2, 0.0, 1.0)
    f = lambda t: (t - 0.45) ** 2  # noqa: E731
    s = sharpened(k, f)
    assert s.coefficients.min() >= 0
    assert max_error(s, f) < max_error(schoenberg(k, f), f)


def test_peaks_are_no_longer_low():
    # Schoenberg's spline is low under a peak by about h^2 |f''| / 8; the sharpened one is not.
    k = bsgi.KnotVector.clamped_uniform(16, 2, 0.0, 1.0)
    f = lambda t: np.exp(-((t - 0.5) / 0.15) ** 2)  # noqa: E731
    x = np.linspace(0, 1, 2001)
    mean = lambda s: s.evaluate(x[:, None])[:, 0].mean() / f(x).mean()  # noqa: E731
    peak0, peak1 = (s.evaluate(np.array([[0.5]]))[0, 0] for s in (schoenberg(k, f), sharpened(k, f)))
    print(f"peak {peak0:.4f} -> {peak1:.4f}, mean {mean(schoenberg(k, f)):.4f} -> {mean(sharpened(k, f)):.4f}")
    assert 1 - peak0 > 0.02 and abs(1 - peak1) < (1 - peak0) / 2.5  # measured 5.5% -> 1.2%


def test_tensor_product_reproduces_biquadratics_axis_by_axis():
    rng = np.random.default_rng(5)
    ku, kv = knots("random", 9, 2, rng), knots("graded", 7, 2)
    f = lambda x: 1 + (x[:, 0] - 0.3) ** 2 * (2 + x[:, 1]) + x[:, 1] ** 2  # noqa: E731
    s = bsgi.fit(bsgi.TensorSpline([ku, kv], 3), lambda x: np.stack([f(x), 2 * f(x), x[:, 0] + 1], -1), "schoenberg")
    bsgi.sharpen_samples(s, 0)
    bsgi.sharpen_samples(s, 1)
    xs = rng.uniform(0, 1, (500, 2))
    got = s.evaluate(xs)
    np.testing.assert_allclose(got[:, 0], f(xs), atol=1e-12)
    np.testing.assert_allclose(got[:, 1], 2 * f(xs), atol=1e-12)
    np.testing.assert_allclose(got[:, 2], xs[:, 0] + 1, atol=1e-12)


def test_degree_one_and_given_nodes():
    k1 = bsgi.KnotVector.clamped_uniform(8, 1, 0.0, 1.0)
    s = schoenberg(k1, np.cos)
    before = s.coefficients.copy()
    bsgi.sharpen_samples(s, 0)
    np.testing.assert_array_equal(s.coefficients, before)  # already interpolates: nothing to do
    # Nodes given: where the samples were actually taken (the solver's nodes beside jumps).
    k = bsgi.KnotVector.clamped_uniform(10, 2, 0.0, 1.0)
    p = np.polynomial.Polynomial([1.0, 0.5, 1.5])
    nodes = np.array(k.schoenberg_nodes())
    assert max_error(sharpened(k, p, nodes), p) <= 1e-12


def test_refusals():
    k = bsgi.KnotVector.clamped_uniform(6, 2, 0.0, 1.0)
    s = bsgi.TensorSpline([k, k], 1)
    with pytest.raises(ValueError, match="axis 2 of a 2-dimensional"):
        bsgi.sharpen_samples(s, 2)
    with pytest.raises(ValueError, match="5 nodes for 6 coefficients"):
        bsgi.sharpen_samples(s, 0, [0.1, 0.2, 0.3, 0.4, 0.5])
    f32 = bsgi.TensorSpline([k], 1, precision="float32")
    with pytest.raises(ValueError, match="Float64"):
        bsgi.sharpen_samples(f32, 0)


def test_unclamped_knots_correct_their_end_coefficients_from_inside():
    # Unclamped knots: the end coefficients do not interpolate (beta != 0) and have no sample
    # beyond them; they take the curvature the stencils inward share, exact on a quadratic.
    k = bsgi.KnotVector(np.linspace(-0.3, 1.3, 12), 2)
    lo, hi = k.domain
    p = np.polynomial.Polynomial([0.9, -0.4, 1.1])
    assert max_error(sharpened(k, p), p, lo, hi) <= 1e-12
    assert max_error(schoenberg(k, p), p, lo, hi) > 1e-3


def test_kept_samples_stay_and_the_rest_sharpen_as_without():
    # Marked nodes (a sun's light as a mean over a node's support, SolverSettings.distant_support_means)
    # keep their samples as coefficients; along the axis every other coefficient is what it is
    # without marks (a correction reads the samples, not its neighbours' corrections). One mark
    # per spatial node of the first two axes, u slowest; its channels share it.
    ku = bsgi.KnotVector.clamped_uniform(9, 2, 0.0, 1.0)
    kv = bsgi.KnotVector.clamped_uniform(8, 2, 0.0, 1.0)
    s = bsgi.TensorSpline([ku, kv], 3)
    bsgi.fit(s, lambda x: np.stack([1 + x[:, 0] ** 2 * x[:, 1], 2 - x[:, 1] ** 2, np.exp(x[:, 0])], axis=1), "schoenberg")
    samples = np.array(s.coefficients).copy()
    keep = np.zeros(9 * 8, np.uint8)
    keep[[4 * 8 + 3, 4 * 8 + 4, 6 * 8 + 2]] = 1
    kept = keep.reshape(9, 8).astype(bool)
    for axis in (0, 1):
        plain = bsgi.TensorSpline([ku, kv], 3)
        plain.coefficients = samples
        marked = bsgi.TensorSpline([ku, kv], 3)
        marked.coefficients = samples
        bsgi.sharpen_samples(plain, axis)
        bsgi.sharpen_samples(marked, axis, [], keep)
        a, b = np.array(plain.coefficients), np.array(marked.coefficients)
        np.testing.assert_array_equal(b[kept], samples[kept])
        assert np.abs(a[kept] - samples[kept]).max() > 1e-4  # sharpening moves them
        np.testing.assert_array_equal(a[~kept], b[~kept])
    with pytest.raises(ValueError, match="marks for 72 spatial nodes"):
        bsgi.sharpen_samples(marked, 0, [], np.zeros(5, np.uint8))
