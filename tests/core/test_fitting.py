"""Fitting (12)/(25), the quadratic quasi-interpolant of section 2.2.1 and the cubic one after
Lee, Lyche and Morken: polynomial reproduction, measured convergence orders, tensor products."""
import numpy as np
import pytest

import bsgi

METHOD_DEGREE = {"schoenberg": 2, "quadratic": 2, "cubic": 3}


def knots(kind, n, degree, rng=None):
    if kind == "uniform":
        return bsgi.KnotVector.clamped_uniform(n, degree, 0.0, 1.0)
    if kind == "graded":  # refined towards 0
        inner = (np.arange(1, n - degree) / (n - degree)) ** 1.5
    elif kind == "random":
        inner = np.sort(rng.uniform(0, 1, n - degree - 1))
    elif kind == "repeated":
        inner = np.sort(rng.uniform(0, 1, n - degree - 1))
        inner[2:4] = inner[2]  # a double knot
    return bsgi.KnotVector(np.r_[[0.0] * (degree + 1), inner, [1.0] * (degree + 1)], degree)


def fit_1d(k, f, method):
    s = bsgi.TensorSpline([k], 1)
    bsgi.fit(s, lambda x: f(x[:, 0]), method)
    return s


def max_error(s, f, lo=0.0, hi=1.0):
    x = np.linspace(lo, hi, 4001)
    return float(np.max(np.abs(s.evaluate(x[:, None])[:, 0] - f(x))))


# ---- polynomial reproduction -----------------------------------------------------------------


@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("kind", ["uniform", "random", "repeated"])
def test_schoenberg_reproduces_linear_functions(degree, kind):
    rng = np.random.default_rng(degree)
    k = knots(kind, degree + 8, degree, rng)
    f = lambda x: 0.3 - 1.7 * x  # noqa: E731
    assert max_error(fit_1d(k, f, "schoenberg"), f) <= 1e-13
    if degree >= 2:  # but not quadratics: the rule is only O(h^2)
        g = lambda x: x * x  # noqa: E731
        assert max_error(fit_1d(k, g, "schoenberg"), g) > 1e-4


@pytest.mark.parametrize("method, degree", [("quadratic", 2), ("cubic", 3)])
@pytest.mark.parametrize("kind", ["uniform", "random", "repeated", "graded"])
def test_quasi_interpolants_reproduce_polynomials_of_their_degree(method, degree, kind):
    rng = np.random.default_rng(degree * 7 + len(kind))
    for n in (degree + 1, degree + 2, degree + 9):  # from one span (Bezier) up
        k = knots(kind if n > degree + 4 else "uniform", n, degree, rng)
        p = np.polynomial.Polynomial(rng.uniform(-2, 2, degree + 1))
        assert max_error(fit_1d(k, p, method), p) <= 1e-12
    # and not one degree more
    k = knots(kind, degree + 9, degree, rng)
    q = np.polynomial.Polynomial([0] * (degree + 1) + [1.0])
    assert max_error(fit_1d(k, q, method), q) > 1e-6


def test_quadratic_quasi_interpolant_on_unclamped_knots_reproduces_quadratics():
    k = bsgi.KnotVector(np.linspace(-0.3, 1.3, 12), 2)  # domain [t_2, t_9], nodes stay inside it
    rule = bsgi.FitRule(k, "quadratic")
    lo, hi = k.domain
    assert rule.nodes.min() >= lo and rule.nodes.max() <= hi
    p = np.polynomial.Polynomial([0.5, -1.0, 2.0])
    assert max_error(fit_1d(k, p, "quadratic"), p, lo, hi) <= 1e-12


def test_quadratic_quasi_interpolant_weights_are_the_papers():
    k = bsgi.KnotVector.clamped_uniform(10, 2, 0.0, 1.0)
    rule = bsgi.FitRule(k, "quadratic")
    t = k.knots
    W = rule.matrix
    for i in range(1, 9):  # interior coefficients: -f(t_i+1)/2 + 2 f(mid) - f(t_i+2)/2
        a, b = t[i + 1], t[i + 2]
        expected = {a: -0.5, (a + b) / 2: 2.0, b: -0.5}
        got = {x: w for x, w in zip(rule.nodes, W[i]) if w != 0}
        assert got.keys() == expected.keys()
        for x in expected:
            assert got[x] == pytest.approx(expected[x], abs=1e-14)
    assert W[0] @ (rule.nodes == 0) == 1.0  # the clamped ends interpolate: a_0 = f(0)
    # Knots and span midpoints: 2 (n - d) + 1 nodes for n - d spans.
    np.testing.assert_allclose(rule.nodes, np.linspace(0, 1, 2 * 8 + 1), atol=1e-15)


def test_cubic_rule_samples_knots_and_midpoints_only():
    k = bsgi.KnotVector.clamped_uniform(12, 3, 0.0, 1.0)
    rule = bsgi.FitRule(k, "cubic")
    np.testing.assert_allclose(rule.nodes, np.linspace(0, 1, 2 * 9 + 1), atol=1e-15)
    np.testing.assert_allclose(rule.matrix.sum(axis=1), 1, atol=1e-13)  # reproduces constants


# ---- measured convergence orders -------------------------------------------------------------


def smooth(x):
    return np.sin(5 * x) + np.exp(x) * np.cos(2 * x)


def measured_order(method, degree, kind, sizes=(16, 32, 64, 128), f=smooth):
    h, err = [], []
    for n in sizes:
        k = knots(kind, n, degree)
        h.append(1 / (n - degree))
        err.append(max_error(fit_1d(k, f, method), f))
    return np.polyfit(np.log(h), np.log(err), 1)[0]


@pytest.mark.parametrize("kind", ["uniform", "graded"])
@pytest.mark.parametrize("method, degree, order", [("schoenberg", 2, 2), ("schoenberg", 3, 2), ("quadratic", 2, 3), ("cubic", 3, 4)])
def test_convergence_orders(method, degree, kind, order):
    assert abs(measured_order(method, degree, kind) - order) <= 0.3


def test_convergence_order_in_two_dimensions():
    f = lambda x: np.sin(3 * x[:, 0]) * np.exp(x[:, 1]) + x[:, 0] * np.cos(2 * x[:, 1])  # noqa: E731
    rng = np.random.default_rng(0)
    xs = rng.uniform(0, 1, (4000, 2))
    for method, degree, order in (("schoenberg", 2, 2), ("quadratic", 2, 3), ("cubic", 3, 4)):
        h, err = [], []
        for n in (8, 16, 32):
            k = bsgi.KnotVector.clamped_uniform(n, degree, 0.0, 1.0)
            s = bsgi.fit(bsgi.TensorSpline([k, k], 1), f, method)
            h.append(1 / (n - degree))
            err.append(np.max(np.abs(s.evaluate(xs)[:, 0] - f(xs))))
        slope = np.polyfit(np.log(h), np.log(err), 1)[0]
        assert abs(slope - order) <= 0.3, (method, slope)


# ---- tensor products -------------------------------------------------------------------------


@pytest.mark.parametrize("method, degree", [("quadratic", 2), ("cubic", 3), ("schoenberg", 2)])
def test_tensor_fit_reproduces_tensor_polynomials(method, degree):
    rng = np.random.default_rng(degree)
    axes = [knots("random", degree + 4, degree, rng) for _ in range(4)]
    s = bsgi.TensorSpline(axes, 3)
    deg = 1 if method == "schoenberg" else degree
    coef = rng.uniform(-1, 1, (4, deg + 1))

    def f(x):
        v = np.prod([np.polynomial.polynomial.polyval(x[:, i], coef[i]) for i in range(4)], axis=0)
        return np.column_stack([v, 2 * v + 1, x[:, 0] ** deg - x[:, 3]])

    bsgi.fit(s, f, method)
    x = rng.uniform(0, 1, (3000, 4))
    np.testing.assert_allclose(s.evaluate(x), f(x), atol=1e-12)


def test_fit_from_samples_is_25_for_schoenberg():
    """(25): the Schoenberg coefficients are the samples at the node grid, unchanged."""
    rng = np.random.default_rng(1)
    k = bsgi.KnotVector.clamped_uniform(5, 2, 0.0, 1.0)
    a = bsgi.KnotVector.symmetric(4, 2, 0.9)
    s = bsgi.TensorSpline([k, k, a, a], 3)
    nodes = bsgi.fitting_nodes(s, "schoenberg")
    np.testing.assert_allclose(nodes[0], k.schoenberg_nodes())
    samples = rng.uniform(0, 1, (5, 5, 4, 4, 3))
    bsgi.fit_from_samples(s, samples, "schoenberg")
    np.testing.assert_array_equal(s.coefficients, samples)


def test_per_axis_methods_and_float32_storage():
    rng = np.random.default_rng(2)
    k2 = knots("random", 7, 2, rng)
    k3 = knots("random", 8, 3, rng)
    s = bsgi.TensorSpline([k2, k3], 1, "float32")
    p = lambda x: (1 + x[:, 0] - x[:, 0] ** 2) * (x[:, 1] ** 3 - 0.5)  # noqa: E731
    bsgi.fit(s, p, ["quadratic", "cubic"])
    x = rng.uniform(0, 1, (1000, 2))
    np.testing.assert_allclose(s.evaluate(x)[:, 0], p(x), atol=1e-6)


def test_fitting_errors():
    k2 = bsgi.KnotVector.clamped_uniform(6, 2, 0.0, 1.0)
    s = bsgi.TensorSpline([k2, k2], 3)
    with pytest.raises(ValueError, match="cubic quasi-interpolant needs degree 3, got degree 2"):
        bsgi.fit(s, lambda x: np.zeros((len(x), 3)), "cubic")
    with pytest.raises(ValueError, match="quadratic quasi-interpolant needs degree 2"):
        bsgi.FitRule(bsgi.KnotVector.clamped_uniform(6, 1, 0.0, 1.0), "quadratic")
    with pytest.raises(ValueError, match="'schoenberg', 'quadratic' or 'cubic'"):
        bsgi.fit(s, lambda x: np.zeros((len(x), 3)), "lsq")
    with pytest.raises(ValueError, match="expected"):
        bsgi.fit(s, lambda x: np.zeros((len(x), 2)), "quadratic")
    with pytest.raises(ValueError, match=r"samples must have shape \(9, 9, 3\)"):
        bsgi.fit_from_samples(s, np.zeros((6, 6, 3)), "quadratic")
    with pytest.raises(ValueError, match="one method per dimension"):
        bsgi.fit(s, lambda x: np.zeros((len(x), 3)), ["quadratic"])


def test_fitting_grid_over_budget_is_refused():
    old = bsgi.memory_budget()
    k = bsgi.KnotVector.clamped_uniform(16, 2, 0.0, 1.0)
    s = bsgi.TensorSpline([k] * 4, 3)
    bsgi.set_memory_budget(4 << 20)
    try:
        with pytest.raises(bsgi.MemoryBudgetError, match="29 x 29 x 29 x 29 nodes"):
            bsgi.fit(s, lambda x: np.zeros((len(x), 3)), "quadratic")
        with pytest.raises(bsgi.MemoryBudgetError, match="fitting samples: 29 x 29 x 29 x 29 x 3 x 8 bytes"):
            bsgi.fit_from_samples(s, np.zeros((29, 29, 29, 29, 3)), "quadratic")
    finally:
        bsgi.set_memory_budget(old)


# ---- periodic axes ---------------------------------------------------------------------------


def test_periodic_fits():
    rng = np.random.default_rng(3)
    b = np.r_[0.0, np.sort(rng.uniform(0, 2 * np.pi, 9)), 2 * np.pi]
    k = bsgi.KnotVector.periodic(b, 2)
    # The quadratic quasi-interpolant is a projector onto the spline space: a periodic quadratic
    # spline is recovered exactly from its own values.
    target = bsgi.TensorSpline([k], 1)
    target.coefficients = rng.uniform(-1, 1, target.shape)
    s = bsgi.fit(bsgi.TensorSpline([k], 1), lambda x: target.evaluate(x), "quadratic")
    np.testing.assert_allclose(s.coefficients, target.coefficients, atol=1e-12)
    assert np.all((bsgi.FitRule(k, "quadratic").nodes >= 0) & (bsgi.FitRule(k, "quadratic").nodes < 2 * np.pi))
    # Schoenberg on a periodic function converges at order 2.
    errs = []
    for m in (16, 32, 64):
        kp = bsgi.KnotVector.periodic(np.linspace(0, 2 * np.pi, m + 1), 2)
        sp = bsgi.fit(bsgi.TensorSpline([kp], 1), lambda x: np.sin(x[:, 0]) + np.cos(3 * x[:, 0]), "schoenberg")
        x = np.linspace(0, 2 * np.pi, 2001)
        errs.append(np.max(np.abs(sp.evaluate(x[:, None])[:, 0] - np.sin(x) - np.cos(3 * x))))
    slope = np.polyfit(np.log([1 / 16, 1 / 32, 1 / 64]), np.log(errs), 1)[0]
    assert abs(slope - 2) <= 0.3


def test_pointwise_callback_fit_matches_the_vectorised_one():
    rng = np.random.default_rng(9)
    axes = [knots("random", 6, 2, rng), knots("random", 5, 2, rng), knots("uniform", 4, 2)]
    f = lambda x: np.stack([np.sin(x[..., 0]) * x[..., 1], np.exp(x[..., 2]) - x[..., 0]], axis=-1)  # noqa: E731
    a = bsgi.fit(bsgi.TensorSpline(axes, 2), f, "quadratic")
    calls = []

    def one_point(x):
        assert x.shape == (3,)
        calls.append(1)
        return f(x)

    b = bsgi.fit(bsgi.TensorSpline(axes, 2), one_point, "quadratic", vectorized=False)
    np.testing.assert_allclose(b.coefficients, a.coefficients, atol=1e-15)
    assert len(calls) == np.prod([len(n) for n in bsgi.fitting_nodes(b, "quadratic")])
    with pytest.raises(ValueError, match="must return 2 values"):
        bsgi.fit(bsgi.TensorSpline(axes, 2), lambda x: np.zeros(3), "quadratic", vectorized=False)
    with pytest.raises(ZeroDivisionError):
        bsgi.fit(bsgi.TensorSpline(axes, 2), lambda x: 1 / 0, "schoenberg", vectorized=False)


@pytest.mark.parametrize("method", ["schoenberg", "quadratic"])
def test_a_kink_on_a_double_knot_is_reproduced(method):
    # The discontinuity knots of a D1 line (solver, discontinuities.h): a quadratic spline with a
    # double knot at the kink is C0 there, so a function with a kink on it is in its space.
    # Schoenberg reproduces piecewise linear functions, the quasi-interpolant piecewise quadratics.
    t = 0.37
    k = bsgi.KnotVector([0, 0, 0, 0.1, 0.2, 0.3, t, t, 0.5, 0.7, 0.85, 1, 1, 1], 2)
    if method == "schoenberg":
        f = lambda x: np.where(x < t, 1 + 2 * x, 1 + 2 * t - 3 * (x - t))
    else:
        f = lambda x: np.where(x < t, 1 + 2 * x - x * x, 1 + 2 * t - t * t + 5 * (x - t) ** 2 - 3 * (x - t))
    assert max_error(fit_1d(k, f, method), f) < 1e-12
    # On single knots near it the kink is smoothed over a span: the double knot is what buys it.
    near = bsgi.KnotVector([0, 0, 0, 0.1, 0.2, 0.3, t - 0.02, t + 0.02, 0.5, 0.7, 0.85, 1, 1, 1], 2)
    assert max_error(fit_1d(near, f, method), f) > 1e-3
