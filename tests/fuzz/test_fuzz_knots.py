"""Fuzzing knot vectors (issue 17, item 1): any knots, degree and parameters either give a valid
B-spline space (basis functions >= 0 summing to 1 inside the domain, nodes inside the domain,
quadrature weights summing to the domain's length) or a ValueError naming the knot vector."""
import numpy as np
from hypothesis import given, settings, strategies as st

import bsgi
from fuzz_support import any_float, case, examples, finite, refused

KNOTS = st.one_of(
    st.lists(any_float, max_size=14),
    st.lists(st.floats(-5, 5), max_size=14).map(sorted),
    st.lists(st.sampled_from([0.0, 0.5, 1.0]), max_size=14).map(sorted),  # repeated knots
    st.lists(st.floats(0, 1e-9), min_size=2, max_size=10).map(sorted),      # spans near the resolution
    st.lists(st.floats(1e8, 1e8 + 1), min_size=2, max_size=10).map(sorted),  # far from 0
)
DEGREE = st.integers(-2, 7)
PARAMETERS = st.lists(st.one_of(any_float, st.floats(-6, 6)), max_size=12)


def check_space(k: bsgi.KnotVector, xs):
    """What every valid knot vector must satisfy (the properties of (9)-(11), independent of the code)."""
    a, b = finite(k.domain, "domain")
    assert a < b or (a == b and k.num_coeffs >= 1)
    n = k.num_coeffs
    # A periodic space may have fewer coefficients than degree + 1 (basis functions wrap onto themselves).
    assert n >= (1 if k.is_periodic else k.degree + 1) and len(k.knots) >= n + k.degree + 1
    x = np.array([v for v in xs if np.isfinite(v)] + [a, b, 0.5 * (a + b)])
    B = k.basis_matrix(x)
    assert B.shape == (len(x), n)
    finite(B, "basis")
    assert B.min() >= -1e-9 and np.allclose(B.sum(axis=1), 1, atol=1e-9), (B.min(), B.sum(axis=1))
    nan_row = k.basis_matrix(np.array([np.nan]))
    assert nan_row.shape == (1, n) and np.isnan(nan_row).all()
    for v in x:
        span = k.find_span(float(v))
        assert 0 <= span < len(k.knots)
    nodes = finite(k.schoenberg_nodes(), "Schoenberg nodes")
    # Knot averages (12) lie between the second and the second-to-last knot (in the domain when clamped).
    lo, hi = (a, b) if k.clamped or k.is_periodic else (k.knots[min(1, len(k.knots) - 1)], k.knots[-2])
    assert len(nodes) == n and (nodes >= lo - 1e-9 * abs(lo) - 1e-12).all() and (nodes <= hi + 1e-9 * abs(hi) + 1e-12).all()
    w = finite(k.basis_integrals(), "basis integrals")
    assert len(w) == n and w.min() >= -1e-12
    if not k.is_periodic and k.clamped:
        # As fractions of the domain: over [0, DBL_MAX] the widths' own sum overflows.
        assert np.isclose(np.sum(w / (b - a)), 1.0, rtol=1e-9), (w, a, b)


@settings(max_examples=examples(1500))
@given(knots=KNOTS, degree=DEGREE, xs=PARAMETERS)
def test_knot_vectors_from_any_knots(knots, degree, xs):
    case(knots=knots, degree=degree, xs=xs)
    try:
        k = bsgi.KnotVector(knots, degree)
    except ValueError as e:
        refused(e, "knot vector")
        return
    check_space(k, xs)


@settings(max_examples=examples(600))
@given(n=st.integers(-2, 40), degree=DEGREE, a=any_float, b=any_float, xs=PARAMETERS)
def test_clamped_uniform(n, degree, a, b, xs):
    case(n=n, degree=degree, a=a, b=b, xs=xs)
    try:
        k = bsgi.KnotVector.clamped_uniform(n, degree, a, b)
    except ValueError as e:
        refused(e, "knot vector")
        return
    assert k.num_coeffs == n and k.degree == degree and k.clamped
    check_space(k, xs)


@settings(max_examples=examples(400))
@given(n=st.integers(-2, 40), degree=DEGREE, R=any_float, xs=PARAMETERS)
def test_symmetric(n, degree, R, xs):
    case(n=n, degree=degree, R=R, xs=xs)
    try:
        k = bsgi.KnotVector.symmetric(n, degree, R)
    except ValueError as e:
        refused(e, "knot vector")
        return
    assert k.num_coeffs == n
    np.testing.assert_array_equal(k.knots, -k.knots[::-1])
    check_space(k, xs)


@settings(max_examples=examples(600))
@given(breakpoints=KNOTS, degree=DEGREE, xs=PARAMETERS)
def test_periodic(breakpoints, degree, xs):
    case(breakpoints=breakpoints, degree=degree, xs=xs)
    try:
        k = bsgi.KnotVector.periodic(breakpoints, degree)
    except ValueError as e:
        refused(e, "knot vector")
        return
    assert k.is_periodic and k.num_coeffs == len(breakpoints) - 1
    check_space(k, xs)


@settings(max_examples=examples(500))
@given(knots=KNOTS, degree=DEGREE, a=any_float, b=any_float,
       method=st.sampled_from(["schoenberg", "quadratic", "cubic", "spline", ""]))
def test_integrals_over_and_fit_rules(knots, degree, a, b, method):
    case(knots=knots, degree=degree, a=a, b=b, method=method)
    try:
        k = bsgi.KnotVector(knots, degree)
    except ValueError as e:
        refused(e, "knot vector")
        return
    try:
        w = k.basis_integrals_over(a, b)
    except ValueError as e:
        refused(e, "knot vector", "integral")
    else:
        assert len(w) == k.num_coeffs
        if np.isfinite([a, b]).all():
            finite(w, "basis integrals over [a, b]")
    try:
        rule = bsgi.FitRule(k, method)
    except ValueError as e:
        refused(e, "fitting", "knot vector")
        return
    assert rule.num_coeffs == k.num_coeffs
    M, nodes = finite(rule.matrix, "fit matrix"), finite(rule.nodes, "fit nodes")
    assert M.shape == (k.num_coeffs, len(nodes))
    # Every rule reproduces constants: a local quasi-interpolant's rows sum to 1.
    np.testing.assert_allclose(M.sum(axis=1), 1, atol=1e-6)


@settings(max_examples=examples(400))
@given(points=st.integers(-3, 70), order=st.integers(-2, 12), endpoint=st.booleans(), bezier=st.booleans(),
       cyclic=st.booleans())
def test_blender_knots(points, order, endpoint, bezier, cyclic):
    case(points=points, order=order, endpoint=endpoint, bezier=bezier, cyclic=cyclic)
    problem = bsgi.blender_nurbs_problem(points, order, endpoint, bezier, cyclic)
    assert isinstance(problem, str)
    try:
        knots, (a, b) = bsgi.blender_knots(points, order, endpoint, bezier, cyclic)
    except ValueError as e:
        refused(e, "NURBS", "knot", "order", "points")
        return
    if not problem:
        finite(knots, "Blender's knots")
        assert np.all(np.diff(knots) >= 0) and a <= b
