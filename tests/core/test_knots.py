"""Knot vectors (19), (24), user knots, periodic extension, and the B-spline basis on them.

References are independent of bsgi: scipy's BSpline.design_matrix for basis values, closed
formulas for the knots, numerical quadrature for (11).
"""
import numpy as np
import pytest
from scipy.interpolate import BSpline

import bsgi


def random_knots(rng, degree, n, repeated=False):
    """Clamped knots on [0, 1] with random inner knots (clustered when repeated)."""
    inner = np.sort(rng.uniform(0, 1, n - degree - 1))
    if repeated and len(inner) >= 3 and degree >= 1:
        inner[1 : 1 + degree] = inner[1]  # one knot of multiplicity `degree` (still continuous)
    return np.r_[[0.0] * (degree + 1), inner, [1.0] * (degree + 1)]


def reference_basis(knots, degree, x):
    """Dense matrix of all basis functions at x, by scipy (right end: last interval)."""
    return BSpline.design_matrix(x, knots, degree, extrapolate=False).toarray()


# ---- construction and validation -------------------------------------------------------------


def test_clamped_uniform_is_formula_19():
    k = bsgi.KnotVector.clamped_uniform(7, 2, 0.1, 0.9)
    h = 0.8 / 5
    np.testing.assert_allclose(k.knots, [0.1] * 3 + [0.1 + i * h for i in range(1, 5)] + [0.9] * 3, rtol=0, atol=1e-15)
    assert k.degree == 2 and k.num_coeffs == 7 and k.domain == (0.1, 0.9)
    assert k.clamped and not k.is_periodic


def test_symmetric_is_formula_24_and_exactly_symmetric():
    R = 0.97
    k = bsgi.KnotVector.symmetric(16, 2, R)
    t = k.knots
    h = 2 * R / 14
    np.testing.assert_allclose(t, [-R] * 3 + [-R + i * h for i in range(1, 14)] + [R] * 3, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(t, -t[::-1])  # bitwise mirror images
    assert k.domain == (-R, R)


@pytest.mark.parametrize(
    "knots, degree, message",
    [
        ([0, 0, 1, 0.5, 1, 1], 1, "non-decreasing"),
        ([0, 0, 0, 0, 1, 1, 1], 2, "repeated 4 times"),
        ([0, 0, 1, 1], 2, "needs at least 3 coefficients"),
        ([0, 0, 0, 1, 1, 1], 6, "degree must be in 0..5"),
        ([0, 0, np.nan, 1, 1], 1, "finite"),
        ([0, 0, np.inf, 1, 1], 1, "finite"),
        ([0, 0, 1, 1], -1, "degree must be in 0..5"),
    ],
)
def test_invalid_knots_are_refused_with_the_reason(knots, degree, message):
    with pytest.raises(ValueError, match=message):
        bsgi.KnotVector(knots, degree)


def test_degree_larger_than_coefficients_is_a_clear_error():
    with pytest.raises(ValueError, match="degree 3 needs at least 4 coefficients, got 2"):
        bsgi.KnotVector.clamped_uniform(2, 3, 0, 1)
    with pytest.raises(ValueError, match="degree 2 needs at least 3 coefficients"):
        bsgi.KnotVector.symmetric(2, 2, 0.9)


def test_bad_domains_are_refused():
    with pytest.raises(ValueError, match="a < b"):
        bsgi.KnotVector.clamped_uniform(4, 1, 1.0, 1.0)
    with pytest.raises(ValueError, match="R > 0"):
        bsgi.KnotVector.symmetric(4, 1, 0.0)
    with pytest.raises(ValueError, match="b_m > b_0"):
        bsgi.KnotVector.periodic([1.0, 1.0], 1)


def test_epsilon_to_zero():
    for eps in (1e-3, 1e-9, 1e-300, 0.0):
        k = bsgi.KnotVector.clamped_uniform(16, 2, eps, 1 - eps)
        assert k.domain == (eps, 1 - eps)
        b = k.basis_matrix(np.array([eps, 0.5, 1 - eps]))
        np.testing.assert_allclose(b.sum(axis=1), 1, atol=1e-14)
        assert b[0, 0] == 1 and b[-1, -1] == 1  # clamped: interpolates at both ends


# ---- the basis -------------------------------------------------------------------------------


@pytest.mark.parametrize("degree", range(6))
@pytest.mark.parametrize("kind", ["uniform", "random", "repeated"])
def test_basis_partition_of_unity_nonnegative_local_support_against_scipy(degree, kind):
    rng = np.random.default_rng(degree * 10 + len(kind))
    n = degree + 9
    if kind == "uniform":
        knots = bsgi.KnotVector.clamped_uniform(n, degree, 0, 1).knots
    else:
        knots = random_knots(rng, degree, n, repeated=kind == "repeated")
    k = bsgi.KnotVector(knots, degree)
    x = np.r_[rng.uniform(0, 1, 2000), knots]  # including every knot and both ends
    B = k.basis_matrix(x)
    np.testing.assert_allclose(B.sum(axis=1), 1, atol=1e-13)  # partition of unity
    assert B.min() >= -1e-15  # non-negative
    # Local support: B_i vanishes outside [t_i, t_{i+d+1}].
    t = knots
    for i in range(n):
        outside = (x < t[i]) | (x > t[i + degree + 1])
        assert np.all(B[outside, i] == 0)
    np.testing.assert_allclose(B, reference_basis(t, degree, x), atol=1e-13)


def test_find_span_on_knots_and_ends():
    t = [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1]
    k = bsgi.KnotVector(t, 2)
    # Inner knots belong to the span on their right; the right end to the last non-empty span.
    assert k.find_span(0.0) == 2
    assert k.find_span(0.25) == 3
    assert k.find_span(0.5) == 5  # the double knot: span [t_5, t_6)
    assert k.find_span(0.49999) == 3
    assert k.find_span(1.0) == 6
    assert k.find_span(7.0) == 6 and k.find_span(-3.0) == 2  # clamped


def test_discontinuous_knot_is_right_continuous_like_scipy():
    t = [0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1]  # full multiplicity inside: a jump at 0.5
    k = bsgi.KnotVector(t, 2)
    x = np.array([0.5, 0.5 - 1e-12, 1.0])
    np.testing.assert_allclose(k.basis_matrix(x), reference_basis(np.array(t, float), 2, x), atol=1e-9)
    assert k.basis_matrix(np.array([0.5]))[0, 3] == 1  # the right piece starts at its first coefficient


def test_schoenberg_nodes_are_knot_averages_12():
    t = np.array([0, 0, 0, 0.1, 0.4, 0.45, 1, 1, 1])
    k = bsgi.KnotVector(t, 2)
    np.testing.assert_allclose(k.schoenberg_nodes(), [(t[i + 1] + t[i + 2]) / 2 for i in range(6)], atol=1e-15)
    k0 = bsgi.KnotVector([0, 0.3, 1], 0)
    np.testing.assert_allclose(k0.schoenberg_nodes(), [0.15, 0.65])


def gauss_integral_of_basis(k, a, b, points_per_span=8):
    """Numerical quadrature of every basis function over [a, b]: Gauss-Legendre on each knot span
    (exact for the polynomial pieces, but computed from evaluated values, not from (11))."""
    x, w = np.polynomial.legendre.leggauss(points_per_span)
    cuts = np.unique(np.clip(np.r_[a, k.knots, b], a, b))
    total = np.zeros(k.num_coeffs)
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        if hi > lo:
            xs = lo + (hi - lo) * (x + 1) / 2
            total += (hi - lo) / 2 * (w @ k.basis_matrix(xs))
    return total


@pytest.mark.parametrize("degree", range(6))
def test_basis_integrals_11_against_quadrature(degree):
    rng = np.random.default_rng(degree)
    k = bsgi.KnotVector(random_knots(rng, degree, degree + 7), degree)
    np.testing.assert_allclose(k.basis_integrals(), gauss_integral_of_basis(k, 0, 1), atol=1e-14)
    np.testing.assert_allclose(k.basis_integrals_over(0, 1), k.basis_integrals(), atol=1e-14)
    a, b = 0.13, 0.71
    np.testing.assert_allclose(k.basis_integrals_over(a, b), gauss_integral_of_basis(k, a, b), atol=1e-14)
    with pytest.raises(ValueError, match="inside the domain"):
        k.basis_integrals_over(-0.1, 0.5)


def test_unclamped_knots_domain_integrals_differ_from_11():
    k = bsgi.KnotVector(np.arange(8.0), 2)  # uniform, not clamped: domain [2, 5]
    assert k.domain == (2.0, 5.0) and not k.clamped
    dom = k.basis_integrals_over(2, 5)
    np.testing.assert_allclose(dom, gauss_integral_of_basis(k, 2, 5), atol=1e-14)
    np.testing.assert_allclose(k.basis_integrals(), [1.0] * 5)  # (11): whole support
    assert dom[0] < 1.0


# ---- periodic extension ----------------------------------------------------------------------


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_periodic_basis_wraps(degree):
    rng = np.random.default_rng(7 + degree)
    b = np.r_[0.0, np.sort(rng.uniform(0, 2 * np.pi, 6)), 2 * np.pi]
    k = bsgi.KnotVector.periodic(b, degree)
    m = len(b) - 1
    assert k.num_coeffs == m and k.is_periodic and k.domain == (0.0, 2 * np.pi)
    x = rng.uniform(0, 2 * np.pi, 500)
    B = k.basis_matrix(x)
    np.testing.assert_allclose(B.sum(axis=1), 1, atol=1e-13)
    assert B.min() >= -1e-15
    np.testing.assert_allclose(k.basis_matrix(x + 2 * np.pi), B, atol=1e-12)
    np.testing.assert_allclose(k.basis_matrix(x - 6 * np.pi), B, atol=1e-12)
    # The same functions as the open B-splines on the extended knots with wrapped indices.
    ext = k.knots
    ref = reference_basis(ext, degree, x)
    wrapped = np.zeros_like(B)
    for j in range(ref.shape[1]):
        wrapped[:, j % m] += ref[:, j]
    np.testing.assert_allclose(B, wrapped, atol=1e-13)
    if degree >= 1:  # continuous across the seam
        np.testing.assert_allclose(k.basis_matrix(np.array([2 * np.pi - 1e-12])), k.basis_matrix(np.array([0.0])), atol=1e-9)
    # Over one period each basis function integrates to its full B-spline integral (11).
    np.testing.assert_allclose(k.basis_integrals_over(0, 2 * np.pi), k.basis_integrals(), atol=1e-13)
