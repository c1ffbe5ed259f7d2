"""Tensor-product splines (13)-(18): evaluation against scipy's NdBSpline (independent), float32
storage against its stated bound, domain rules, integrals (11) against quadrature, the memory
guard."""
import itertools

import numpy as np
import pytest
from scipy.interpolate import BSpline, NdBSpline

import bsgi

U = 2.0**-24


def float32_bound(dims, degree):
    """The bound stated in tensor_spline.h: K u / (1 - K u) max|a|, K = D (d + 2) + 1."""
    K = dims * (degree + 2) + 1
    return K * U / (1 - K * U)


def knot_vector(rng, degree, n, kind):
    if kind == "uniform":
        return bsgi.KnotVector.clamped_uniform(n, degree, 0.0, 1.0)
    inner = np.sort(rng.uniform(0, 1, n - degree - 1))
    if kind == "clustered":  # around a "highlight" at 0.3
        inner = np.sort(0.3 + 0.3 * (inner - 0.5) ** 3)
    return bsgi.KnotVector(np.r_[[0.0] * (degree + 1), inner, [1.0] * (degree + 1)], degree)


def random_spline(rng, dims, degree, kind, channels=3, precision="float64", sizes=None):
    sizes = sizes or [int(rng.integers(degree + 1, degree + 7)) for _ in range(dims)]
    axes = [knot_vector(rng, degree, n, kind) for n in sizes]
    s = bsgi.TensorSpline(axes, channels, precision)
    s.coefficients = rng.uniform(0.5, 1.5, s.shape)  # positive: values >= 0.5, relative diffs defined
    return s


def scipy_peer(s, coefficients=None):
    c = np.asarray(s.coefficients if coefficients is None else coefficients, dtype=np.float64)
    return NdBSpline(tuple(a.knots for a in s.axes), c, tuple(a.degree for a in s.axes))


def rel_diff(a, b):
    return float(np.max(np.abs(a - b) / np.abs(b)))


@pytest.mark.parametrize("dims", [2, 4])
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("kind", ["uniform", "random", "clustered"])
def test_agrees_with_scipy(dims, degree, kind):
    rng = np.random.default_rng(dims * 100 + degree * 10 + len(kind))
    s = random_spline(rng, dims, degree, kind)
    x = rng.uniform(0, 1, (4000, dims))
    ref = scipy_peer(s)(x)
    assert rel_diff(s.evaluate(x), ref) <= 1e-10
    # float32 storage: compared with the float64 spline, within the stated bound (values >= 0.5
    # and max|a| <= 1.5 turn the absolute bound into a relative one).
    s32 = s.with_precision("float32")
    assert s32.precision == "float32"
    err = np.max(np.abs(s32.evaluate(x) - ref))
    assert err <= float32_bound(dims, degree) * np.max(np.abs(s.coefficients))


@pytest.mark.parametrize("dims, degrees", [(3, (2, 1, 3)), (5, (1, 2, 0, 2, 1)), (4, (2, 2, 1, 2)), (2, (3, 0))])
def test_other_dimensions_and_mixed_degrees_agree_with_scipy(dims, degrees):
    rng = np.random.default_rng(dims)
    axes = [knot_vector(rng, d, d + 3, "random") for d in degrees]
    for precision in ("float64", "float32"):
        s = bsgi.TensorSpline(axes, 2, precision)
        s.coefficients = rng.uniform(0.5, 1.5, s.shape)
        x = rng.uniform(0, 1, (2000, dims))
        tol = 1e-10 if precision == "float64" else float32_bound(dims, max(degrees)) * 1.5
        assert rel_diff(s.evaluate(x), scipy_peer(s)(x)) <= tol


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_channels(channels):
    rng = np.random.default_rng(channels)
    s = random_spline(rng, 4, 2, "uniform", channels=channels)
    x = rng.uniform(0, 1, (500, 4))
    ref = scipy_peer(s)(x).reshape(500, channels)
    assert rel_diff(s.evaluate(x), ref) <= 1e-10


@pytest.mark.parametrize("dims", [2, 4])
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("kind", ["uniform", "clustered"])
@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_single_point_evaluation_agrees_with_scipy(dims, degree, kind, precision):
    """One point at a time (what the solver's gather does per ray) through the specialised
    kernels, at random points, on every knot and outside the domain: scipy's value within 1e-10
    (float64) or the float32 bound, and the batch's value within rounding."""
    rng = np.random.default_rng(100 * dims + 10 * degree + len(kind) + len(precision))
    s = random_spline(rng, dims, degree, kind, channels=3, precision=precision)
    x = rng.uniform(-0.1, 1.1, (40, dims))
    for k, axis in enumerate(s.axes):  # every distinct knot on axis k, other parameters random
        t = np.unique(axis.knots)
        x = np.vstack([x, np.column_stack([t if j == k else rng.uniform(0, 1, len(t)) for j in range(dims)])])
    one = np.array([s.evaluate(p) for p in x])
    peer = scipy_peer(s)(np.clip(x, 0, 1))
    if precision == "float64":
        assert rel_diff(one, peer) <= 1e-10
    else:
        assert np.max(np.abs(one - peer)) <= float32_bound(dims, degree) * np.max(np.abs(s.coefficients))
    np.testing.assert_allclose(one, s.evaluate(x), rtol=1e-14 if precision == "float64" else 1e-6)


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("kind", ["uniform", "clustered"])
def test_big_batches_agree_with_scipy(precision, kind):
    """Tens of thousands of points on a 4D spline bigger than the core's cache are evaluated in
    the order of their knot cell on the first three axes and put back (directions mapped first):
    each point still gets scipy's value in the
    caller's order, a non-finite point NaN; parameters and (u, v, direction) inputs."""
    rng = np.random.default_rng(7 + len(kind) + len(precision))
    s = random_spline(rng, 4, 2, kind, precision=precision, sizes=[16] * 4)
    amax = float(np.max(np.abs(s.coefficients)))

    def check(got, ref):
        if precision == "float64":
            assert rel_diff(got, ref) <= 1e-10
        else:
            assert np.max(np.abs(got - ref)) <= float32_bound(4, 2) * amax

    n = 40000
    x = rng.uniform(-0.05, 1.05, (n, 4))
    x[123, 1] = np.nan
    got = s.evaluate(x)
    good = np.ones(n, bool)
    good[123] = False
    assert np.all(np.isnan(got[123]))
    check(got[good], scipy_peer(s)(np.clip(x[good], 0, 1)))

    h = bsgi.HemisphereMap.for_max_angle(0.05)
    angular = bsgi.KnotVector.symmetric(16, 2, h.radius)
    L = bsgi.TensorSpline([s.axes[0], s.axes[1], angular, angular], 3, precision)
    L.coefficients = rng.uniform(0.5, 1.5, L.shape)
    amax = float(np.max(np.abs(L.coefficients)))
    uv = rng.uniform(0, 1, (n, 2))
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2])
    u = d / np.linalg.norm(d, axis=1, keepdims=True)  # (20)-(22) inverted in numpy, pulled in to R
    ab = u[:, :2] / np.sqrt(1 + u[:, 2:3])
    r = np.linalg.norm(ab, axis=1, keepdims=True)
    ab = np.where(r > h.radius, ab * h.radius / np.where(r > 0, r, 1), ab)
    got = L.evaluate_directions(uv, d, h)
    check(got, scipy_peer(L)(np.column_stack([uv, ab])))
    # A zero or NaN direction gives NaN for its point only (the directions are mapped before
    # the points are ordered).
    d[321] = 0.0
    d[654, 0] = np.nan
    bad = L.evaluate_directions(uv, d, h)
    assert np.all(np.isnan(bad[[321, 654]]))
    keep = np.ones(n, bool)
    keep[[321, 654]] = False
    np.testing.assert_array_equal(bad[keep], got[keep])


def test_single_point_and_batch_shapes():
    rng = np.random.default_rng(1)
    s = random_spline(rng, 4, 2, "uniform")
    x = rng.uniform(0, 1, 4)
    one = s.evaluate(x)  # the single-point path, not the batch machinery
    assert one.shape == (3,)
    np.testing.assert_allclose(one, s.evaluate(x[None, :])[0], rtol=1e-14)
    np.testing.assert_allclose(one, scipy_peer(s)(x[None, :])[0], rtol=1e-12)
    for p in (np.array([np.nan, 0.5, 0.5, 0.5]), np.array([2.0, -1.0, 0.5, 7.0])):
        np.testing.assert_allclose(s.evaluate(p), s.evaluate(p[None, :])[0], rtol=1e-14)
    with pytest.raises(ValueError, match=r"shape \(N, 4\)"):
        s.evaluate(np.zeros((3, 2)))


def test_threads_give_the_same_values():
    rng = np.random.default_rng(2)
    s = random_spline(rng, 4, 2, "uniform")
    x = rng.uniform(0, 1, (20000, 4))
    np.testing.assert_array_equal(s.evaluate(x, threads=1), s.evaluate(x, threads=0))
    np.testing.assert_array_equal(s.evaluate(x, threads=1), s.evaluate(x, threads=3))


@pytest.mark.parametrize("kind", ["uniform", "random"])
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_points_on_every_knot_and_both_ends(kind, degree):
    rng = np.random.default_rng(degree + 40)
    s = random_spline(rng, 2, degree, kind, sizes=[degree + 6, degree + 5])
    t0, t1 = (a.knots for a in s.axes)
    x = np.array(list(itertools.product(np.unique(t0), np.unique(t1))))
    ref = scipy_peer(s)(x)
    assert rel_diff(s.evaluate(x), ref) <= 1e-10
    # The 4D kernel too: every knot combination of a small 4D spline.
    s4 = random_spline(rng, 4, degree, kind, sizes=[degree + 3] * 4)
    grids = [np.unique(a.knots) for a in s4.axes]
    x4 = np.array(list(itertools.product(*grids)))
    assert rel_diff(s4.evaluate(x4), scipy_peer(s4)(x4)) <= 1e-10


def test_repeated_knots_agree_with_scipy():
    rng = np.random.default_rng(3)
    t = np.array([0, 0, 0, 0.2, 0.2, 0.5, 0.7, 0.7, 0.7, 1, 1, 1])  # double and triple knots
    k = bsgi.KnotVector(t, 2)
    s = bsgi.TensorSpline([k, k, k, k], 3)
    s.coefficients = rng.uniform(0.5, 1.5, s.shape)
    x = np.r_[rng.uniform(0, 1, (2000, 4)), np.tile(np.unique(t)[:, None], (1, 4))]
    assert rel_diff(s.evaluate(x), scipy_peer(s)(x)) <= 1e-10


def test_one_coefficient_and_degree_zero():
    k1 = bsgi.KnotVector.clamped_uniform(1, 0, 0, 1)  # one constant piece
    k = bsgi.KnotVector.clamped_uniform(5, 0, 0, 1)
    s = bsgi.TensorSpline([k1, k, k1, k], 3)
    rng = np.random.default_rng(4)
    s.coefficients = rng.uniform(0.5, 1.5, s.shape)
    x = rng.uniform(0, 1, (1000, 4))
    assert rel_diff(s.evaluate(x), scipy_peer(s)(x)) <= 1e-10


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_512_coefficients_in_a_dimension(precision):
    rng = np.random.default_rng(5)
    big = bsgi.KnotVector.clamped_uniform(512, 2, 0, 1)
    small = bsgi.KnotVector.clamped_uniform(4, 2, 0, 1)
    s = bsgi.TensorSpline([big, small, small, big], 3, precision)
    s.coefficients = rng.uniform(0.5, 1.5, s.shape)
    x = np.r_[rng.uniform(0, 1, (3000, 4)), [[1, 1, 1, 1], [0, 0, 0, 0]]]
    tol = 1e-10 if precision == "float64" else float32_bound(4, 2) * 1.5
    assert rel_diff(s.evaluate(x), scipy_peer(s)(x)) <= tol


def test_points_outside_the_domain_are_clamped():
    rng = np.random.default_rng(6)
    s = random_spline(rng, 4, 2, "random")
    x = rng.uniform(-2, 3, (1000, 4))
    np.testing.assert_array_equal(s.evaluate(x), s.evaluate(np.clip(x, 0, 1)))
    big = np.array([[1e300, -1e300, 5.0, -5.0]])
    np.testing.assert_array_equal(s.evaluate(big), s.evaluate(np.clip(big, 0, 1)))


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("dims, degree", [(4, 2), (2, 1), (3, 2)])  # fast kernels and generic
def test_nan_or_infinite_parameters_give_nan(precision, dims, degree):
    rng = np.random.default_rng(7)
    s = random_spline(rng, dims, degree, "uniform", precision=precision)
    x = rng.uniform(0, 1, (6, dims))
    x[1, 0] = np.nan
    x[3, dims - 1] = np.inf
    x[4, 1] = -np.inf
    y = s.evaluate(x)
    bad = [1, 3, 4]
    assert np.all(np.isnan(y[bad]))
    good = [0, 2, 5]
    np.testing.assert_array_equal(y[good], s.evaluate(x[good]))
    with pytest.raises(ValueError, match="row 1 is not finite"):
        s.evaluate(x, check_finite=True)


def test_periodic_axis():
    rng = np.random.default_rng(8)
    period = bsgi.KnotVector.periodic(np.linspace(-np.pi, np.pi, 9), 2)
    k = bsgi.KnotVector.clamped_uniform(5, 2, 0, 1)
    s = bsgi.TensorSpline([k, period], 3)
    s.coefficients = rng.uniform(0.5, 1.5, s.shape)
    x = np.column_stack([rng.uniform(0, 1, 500), rng.uniform(-np.pi, np.pi, 500)])
    y = s.evaluate(x)
    np.testing.assert_allclose(s.evaluate(x + [0, 2 * np.pi]), y, rtol=1e-12)
    np.testing.assert_allclose(s.evaluate(x - [0, 4 * np.pi]), y, rtol=1e-12)
    seam = np.array([[0.3, np.pi - 1e-11], [0.3, -np.pi]])
    v = s.evaluate(seam)
    np.testing.assert_allclose(v[0], v[1], rtol=1e-9)  # C^1 across the seam
    # Against scipy on the equivalent open spline: extended knots, coefficients wrapped.
    ext = period.knots
    m = period.num_coeffs
    c = np.asarray(s.coefficients)[:, [j % m for j in range(len(ext) - 3)], :]
    ref = NdBSpline((k.knots, ext), c, 2)(x)
    assert rel_diff(y, ref) <= 1e-10


def test_coefficients_view_writes_through_and_checks_shape():
    k = bsgi.KnotVector.clamped_uniform(3, 1, 0, 1)
    for precision, dtype in (("float64", np.float64), ("float32", np.float32)):
        s = bsgi.TensorSpline([k, k], 2, precision)
        view = s.coefficients
        assert view.dtype == dtype and view.shape == (3, 3, 2)
        view[...] = 0.25
        np.testing.assert_allclose(s.evaluate(np.array([0.4, 0.7])), [0.25, 0.25])
        with pytest.raises(ValueError, match="shape"):
            s.coefficients = np.zeros((3, 2, 2))
    with pytest.raises(ValueError, match="float64 or float32"):
        bsgi.TensorSpline([k, k], 2, "float16")


def gauss_integral(s, lo, hi, points=4):
    """Tensor Gauss-Legendre on every knot cell of the box, from evaluated values."""
    x, w = np.polynomial.legendre.leggauss(points)
    per_axis = []
    for a, l, h in zip(s.axes, lo, hi):
        cuts = np.unique(np.clip(np.r_[l, a.knots, h], l, h))
        xs, ws = [], []
        for c0, c1 in zip(cuts[:-1], cuts[1:]):
            if c1 > c0:
                xs.append(c0 + (c1 - c0) * (x + 1) / 2)
                ws.append((c1 - c0) / 2 * w)
        per_axis.append((np.concatenate(xs), np.concatenate(ws)))
    grid = np.stack(np.meshgrid(*[p[0] for p in per_axis], indexing="ij"), -1).reshape(-1, s.dims)
    weight = np.ones(1)
    for p in per_axis:
        weight = np.multiply.outer(weight, p[1]).ravel()
    return weight @ s.evaluate(grid)


@pytest.mark.parametrize("dims, degree, kind", [(2, 2, "random"), (4, 2, "uniform"), (3, 3, "random"), (2, 0, "uniform")])
def test_integrals_against_quadrature(dims, degree, kind):
    rng = np.random.default_rng(dims + degree)
    s = random_spline(rng, dims, degree, kind, sizes=[degree + 3] * dims)
    np.testing.assert_allclose(s.integral(), gauss_integral(s, [0] * dims, [1] * dims), rtol=1e-12)
    lo = rng.uniform(0, 0.4, dims)
    hi = rng.uniform(0.5, 1, dims)
    np.testing.assert_allclose(s.integral_over(lo, hi), gauss_integral(s, lo, hi), rtol=1e-12)
    with pytest.raises(ValueError, match="inside the domain"):
        s.integral_over(lo - 1, hi)


def test_integral_of_constant_is_box_volume():
    k = bsgi.KnotVector.clamped_uniform(6, 2, 0.1, 0.9)
    a = bsgi.KnotVector.symmetric(5, 2, 0.8)
    s = bsgi.TensorSpline([k, k, a, a], 3)
    s.coefficients = np.broadcast_to([1.0, 2.0, 3.0], s.shape)
    np.testing.assert_allclose(s.integral(), np.array([1, 2, 3]) * 0.8**2 * 1.6**2, rtol=1e-13)


# ---- memory guard ----------------------------------------------------------------------------


@pytest.fixture
def small_budget():
    old = bsgi.memory_budget()
    bsgi.set_memory_budget(1 << 20)
    yield
    bsgi.set_memory_budget(old)


def test_required_bytes_is_coefficients_channels_bytes():
    k = bsgi.KnotVector.clamped_uniform(16, 2, 0, 1)
    assert bsgi.TensorSpline.required_bytes([k] * 4, 3) == 16**4 * 3 * 8
    assert bsgi.TensorSpline.required_bytes([k] * 4, 3, "float32") == 16**4 * 3 * 4
    s = bsgi.TensorSpline([k] * 2, 3, "float32")
    assert s.nbytes == 16 * 16 * 3 * 4


def test_spline_over_budget_is_refused_naming_the_sizes(small_budget):
    k = bsgi.KnotVector.clamped_uniform(16, 2, 0, 1)
    with pytest.raises(bsgi.MemoryBudgetError, match=r"16 x 16 x 16 x 16 x 3 x 8 bytes = 1.5 MiB exceeds the memory budget of 1 MiB"):
        bsgi.TensorSpline([k] * 4, 3)
    assert isinstance(bsgi.MemoryBudgetError("x"), MemoryError)
    bsgi.TensorSpline([k] * 4, 3, "float32")  # 768 KiB: fits


def test_absurd_sizes_do_not_overflow():
    k = bsgi.KnotVector.clamped_uniform(100000, 0, 0, 1)
    with pytest.raises(bsgi.MemoryBudgetError, match="more than 16 EiB"):
        bsgi.TensorSpline([k] * 8, 3)


ISA_CHECK = r"""
import numpy as np, bsgi
from scipy.interpolate import NdBSpline
rng = np.random.default_rng(11)
worst = {}
h = bsgi.HemisphereMap.for_max_angle(0.05)
for dims, degree in ((2, 1), (2, 3), (4, 2), (4, 0)):
    for uniform in (True, False):
        axes = []
        for _ in range(dims):
            n = degree + 5
            if uniform:
                axes.append(bsgi.KnotVector.clamped_uniform(n, degree, 0.0, 1.0))
            else:
                inner = np.sort(rng.uniform(0, 1, n - degree - 1))
                axes.append(bsgi.KnotVector(np.r_[[0.0] * (degree + 1), inner, [1.0] * (degree + 1)], degree))
        for channels in (1, 3):
            s = bsgi.TensorSpline(axes, channels)
            s.coefficients = rng.uniform(0.5, 1.5, s.shape)
            x = rng.uniform(0, 1, (3000, dims))
            ref = NdBSpline(tuple(a.knots for a in axes), np.array(s.coefficients), degree)(x).reshape(3000, channels)
            for p in ("float64", "float32"):
                t = s.with_precision(p)
                worst[p] = max(worst.get(p, 0), float(np.max(np.abs(t.evaluate(x) - ref) / ref)))
            if dims == 4:
                d = rng.normal(size=(3000, 3))
                via_params = s.evaluate(np.column_stack([x[:, :2], h.to_disc(d)]))
                worst["directions"] = max(worst.get("directions", 0),
                                          float(np.max(np.abs(s.evaluate_directions(x[:, :2], d, h) - via_params) / via_params)))
print(bsgi._core._kernel_isa(), worst["float64"], worst["float32"], worst["directions"])
"""


@pytest.mark.parametrize("isa", ["baseline", "x86-64-v3", "x86-64-v4"])
def test_every_instruction_set_version_agrees_with_scipy(isa):
    """The kernels are compiled for three instruction-set levels; BSGI_ISA selects a lower one."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, BSGI_ISA=isa)
    out = subprocess.run([sys.executable, "-c", ISA_CHECK], env=env, capture_output=True, text=True, check=True).stdout.split()
    if out[0] != isa:
        pytest.skip(f"this CPU does not run {isa} (got {out[0]})")
    f64, f32, directions = map(float, out[1:])
    assert f64 <= 1e-10
    assert f32 <= float32_bound(4, 3) * 3  # relative: values >= 0.5, max|a| <= 1.5
    assert directions <= 1e-12
