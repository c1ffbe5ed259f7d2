"""Fuzzing tensor splines, their evaluation and fitting, and the hemisphere map (issue 17, item 1).
A working call is checked against properties that hold for every B-spline (independent of the
code): values inside the convex hull of the coefficients, constants reproduced by fitting,
directions of unit length."""
import numpy as np
from hypothesis import given, settings, strategies as st

import bsgi
from fuzz_support import any_float, arrays, case, examples, finite, points, refused, usable

AXIS = st.one_of(
    st.builds(lambda n, d: (n, d, "clamped"), st.integers(1, 6), st.integers(0, 3)),
    st.builds(lambda n, d: (n, d, "periodic"), st.integers(2, 6), st.integers(0, 3)),
)


def make_axis(n, degree, kind):
    if kind == "periodic":
        return bsgi.KnotVector.periodic(np.linspace(0, 1, n + 1), degree)
    return bsgi.KnotVector.clamped_uniform(max(n, degree + 1), degree)


@st.composite
def splines(draw, dims=st.integers(1, 5)):
    axes = [make_axis(*draw(AXIS)) for _ in range(draw(dims))]
    channels = draw(st.integers(1, 4))
    precision = draw(st.sampled_from(["float64", "float32"]))
    spline = bsgi.TensorSpline(axes, channels, precision)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = draw(st.sampled_from([0.0, 1.0, 1e3, 1e-30, 1e30]))
    spline.coefficients = scale * rng.uniform(-1, 1, spline.coefficients.shape)
    return spline


def in_hull(values, spline):
    """B-splines are >= 0 and sum to 1: each value lies between the extreme coefficients."""
    c = np.asarray(spline.coefficients, np.float64).reshape(-1, spline.channels)
    slack = 1e-6 * (1 + np.abs(c).max())
    assert (values >= c.min(axis=0) - slack).all() and (values <= c.max(axis=0) + slack).all()


@settings(max_examples=examples(600))
@given(spline=splines(), data=st.data())
def test_evaluate_any_points(spline, data):
    x = data.draw(points(spline.dims, elements=st.one_of(any_float, st.floats(-0.5, 1.5))))
    check = data.draw(st.booleans())
    threads = data.draw(st.sampled_from([0, 1, 2, -1, 64]))
    case(shape=spline.shape, x=x, check=check, threads=threads)
    try:
        values = spline.evaluate(x, threads=threads, check_finite=check)
    except ValueError as e:
        refused(e, "points", "evaluate")
        return
    n = 1 if x.ndim == 1 else x.shape[0]
    assert values.shape == ((spline.channels,) if x.ndim == 1 else (n, spline.channels))
    rows = np.isfinite(x.reshape(n, spline.dims)).all(axis=1)
    v = values.reshape(n, spline.channels)
    finite(v[rows], "values at finite points")
    in_hull(v[rows], spline)
    assert np.isnan(v[~rows]).all()


@settings(max_examples=examples(400))
@given(spline=splines(dims=st.just(4)), data=st.data())
def test_evaluate_directions(spline, data):
    uv = data.draw(points(2, elements=st.one_of(any_float, st.floats(0, 1))))
    n = uv.shape[0] if uv.ndim == 2 else 1
    d = data.draw(st.one_of(arrays((n, 3)), points(3)))
    R = data.draw(st.floats(0.05, 1))
    case(shape=spline.shape, uv=uv, d=d, R=R)
    try:
        values = spline.evaluate_directions(uv, d, bsgi.HemisphereMap(R), check_finite=data.draw(st.booleans()))
    except ValueError as e:
        refused(e, "uv", "directions", "evaluate_directions")
        return
    good = np.isfinite(uv.reshape(-1, 2)).all(axis=1) & np.isfinite(d.reshape(-1, 3)).all(axis=1)
    good &= usable(d.reshape(-1, 3))
    v = values.reshape(-1, spline.channels)
    in_hull(finite(v[good], "radiance along finite directions"), spline)


@settings(max_examples=examples(400))
@given(spline=splines(), lo=st.lists(any_float, min_size=0, max_size=6), hi=st.lists(any_float, min_size=0, max_size=6))
def test_integrals(spline, lo, hi):
    case(shape=spline.shape, lo=lo, hi=hi)
    total = finite(spline.integral(), "integral")
    assert total.shape == (spline.channels,)
    try:
        part = spline.integral_over(np.array(lo), np.array(hi))
    except ValueError as e:
        refused(e, "integral_over", "knot vector")
        return
    assert part.shape == (spline.channels,)
    if np.isfinite(lo).all() and np.isfinite(hi).all():
        finite(part, "integral over a box")


@settings(max_examples=examples(300))
@given(spline=splines(), precision=st.sampled_from(["float64", "float32", "int32", "float16"]))
def test_precision_round_trip(spline, precision):
    case(shape=spline.shape, precision=precision)
    try:
        other = spline.with_precision(precision)
    except ValueError as e:
        refused(e, "precision")
        return
    assert other.shape == spline.shape and other.precision == precision
    np.testing.assert_allclose(np.asarray(other.coefficients, np.float64), np.asarray(spline.coefficients, np.float64),
                               rtol=1e-6, atol=1e-6)


@settings(max_examples=examples(300))
@given(counts=st.lists(st.one_of(st.integers(1, 8), st.integers(1000, 5000), st.integers(1, 2**31 - 1)), min_size=0, max_size=8),
       degree=st.integers(0, 5), channels=st.integers(-1, 5))
def test_construction_sizes_and_the_memory_budget(counts, degree, channels):
    """Huge knot vectors and splines are refused before allocating (MemoryBudgetError, also when
    their sizes overflow 64 bits); wrong dims or channels are ValueErrors."""
    case(counts=counts, degree=degree, channels=channels)
    budget = bsgi.memory_budget()
    bsgi.set_memory_budget(64 << 20)  # what fits is built: keep it small
    try:
        construct(counts, degree, channels)
    finally:
        bsgi.set_memory_budget(budget)


def construct(counts, degree, channels):
    try:
        axes = [bsgi.KnotVector.clamped_uniform(max(n, degree + 1), degree) for n in counts]
    except (ValueError, MemoryError) as e:
        refused(e, "knot vector")
        return
    try:
        need = bsgi.TensorSpline.required_bytes(axes, channels)
        spline = bsgi.TensorSpline(axes, channels)
    except bsgi.MemoryBudgetError as e:
        refused(e, "budget")
        return
    except ValueError as e:
        refused(e, "tensor spline")
        return
    assert spline.nbytes == need and need <= bsgi.memory_budget()
    assert (np.asarray(spline.coefficients) == 0).all()


@settings(max_examples=examples(400))
@given(spline=splines(dims=st.integers(1, 3)), data=st.data())
def test_fit_reproduces_constants_and_checks_shapes(spline, data):
    methods = ["schoenberg", "quadratic", "cubic", "nonsense"]
    method = data.draw(st.one_of(st.sampled_from(methods), st.lists(st.sampled_from(methods), min_size=0, max_size=4)))
    constant = np.array(data.draw(st.lists(st.floats(-1e3, 1e3), min_size=spline.channels, max_size=spline.channels)))
    wrong = data.draw(st.sampled_from([None, "channels", "rows", "nan"]))
    vectorized = data.draw(st.booleans())
    case(shape=spline.shape, method=method, constant=constant, wrong=wrong, vectorized=vectorized)

    def f(x):
        x = np.atleast_2d(x)
        out = np.tile(constant, (len(x), 1))
        if wrong == "channels":
            out = out[:, :-1] if spline.channels > 1 else np.hstack([out, out])
        elif wrong == "rows":
            out = out[1:] if vectorized else out[:, 1:]
        elif wrong == "nan":
            out[:] = np.nan
        return out if vectorized else out[0]

    try:
        bsgi.fit(spline, f, method, vectorized=vectorized)
    except ValueError as e:
        refused(e, "fit", "fitting", "method")
        return
    if wrong == "nan":
        return  # NaN samples give NaN coefficients: the caller's values, passed on
    assert wrong is None, f"f returning wrong {wrong} was accepted"
    np.testing.assert_allclose(np.asarray(spline.coefficients, np.float64).reshape(-1, spline.channels),
                               np.broadcast_to(constant, (int(np.prod(spline.shape[:-1])), spline.channels)),
                               rtol=1e-5, atol=1e-4)


@settings(max_examples=examples(300))
@given(spline=splines(dims=st.integers(1, 3)), data=st.data())
def test_fit_from_samples_shapes(spline, data):
    nodes = bsgi.fitting_nodes(spline)
    good = tuple(len(n) for n in nodes) + (spline.channels,)
    shape = data.draw(st.one_of(st.just(good), st.lists(st.integers(0, 5), max_size=5).map(tuple)))
    samples = np.ones(shape)
    case(shape=spline.shape, samples=shape)
    try:
        bsgi.fit_from_samples(spline, samples)
    except ValueError as e:
        refused(e, "fit_from_samples")
        return
    assert shape == good
    np.testing.assert_allclose(np.asarray(spline.coefficients, np.float64), 1, rtol=1e-6)


@settings(max_examples=examples(500))
@given(R=any_float, delta=any_float, ab=points(2), d=points(3))
def test_hemisphere_maps(R, delta, ab, d):
    case(R=R, delta=delta, ab=ab, d=d)
    maps = []
    for make, arg, what in ((bsgi.HemisphereMap, R, "radius"), (bsgi.HemisphereMap.for_max_angle, delta, "delta")):
        try:
            maps.append(make(arg))
        except ValueError as e:
            refused(e, "hemisphere map")
    for h in maps:
        assert 0 < h.radius <= 1 and 0 <= h.max_theta <= np.pi / 2
        for method, x, width, out_width in ((h.to_direction, ab, 2, 3), (h.angles, ab, 2, 2), (h.to_disc, d, 3, 2)):
            try:
                y = method(x)
            except ValueError as e:
                refused(e, "alpha, beta", "directions")
                continue
            rows = x.reshape(-1, width)
            y = y.reshape(-1, out_width)
            with np.errstate(all="ignore"):  # disc points of |(alpha, beta)| < 1e150 (squares stay finite)
                ok = np.isfinite(rows).all(axis=1) & (np.sqrt((rows ** 2).sum(axis=1)) < 1e150)
            if method == h.to_disc:
                ok &= usable(rows)
                assert (np.linalg.norm(finite(y[ok]), axis=1) <= h.radius * (1 + 1e-9)).all()
            elif method == h.to_direction:
                np.testing.assert_allclose(np.linalg.norm(finite(y[ok]), axis=1), 1, rtol=1e-9)
            else:
                finite(y[ok])
