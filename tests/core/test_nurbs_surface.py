"""NurbsSurface: Blender's knot rule, rational evaluation with derivatives (against scipy's
NdBSpline on homogeneous coordinates), exactness of rational conics, and clear errors."""
import itertools

import numpy as np
import pytest

import bsgi
from nurbs_reference import SPHERE_FLAGS, blender_sphere_points, rational_derivatives, scipy_nurbs

FLAGS = list(itertools.product([False, True], repeat=3))  # (endpoint, bezier, cyclic)


def valid_count(order, extra=0):
    n = max(4, order + 1) + extra
    while n % (order - 1):
        n += 1
    return n


# Knot vectors worked out by hand from Blender's calcknots (curve.cc) and checked against
# Blender's meshes in tests/blender: (points, order, endpoint, bezier, cyclic) -> knots, range.
HAND_KNOTS = [
    ((4, 4, False, False, False), [0, 1, 2, 3, 4, 5, 6, 7], (3, 4)),
    ((4, 4, True, False, False), [0, 0, 0, 0, 1, 1, 1, 1], (0, 1)),
    ((5, 3, True, False, False), [0, 0, 0, 1, 2, 3, 3, 3], (0, 3)),
    ((5, 3, True, True, False), [0, 0, 0, 1, 1, 2, 2, 2], (0, 2)),  # sphere profile
    ((7, 4, False, True, False), [0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3], (1, 2)),
    ((4, 3, False, False, True), [0, 1, 2, 3, 4, 5, 6, 7, 8], (2, 6)),
    ((8, 3, True, True, True), [0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6], (1, 5)),  # torus, sphere ring
    ((2, 2, False, False, False), [0, 1, 2, 3], (1, 2)),  # cylinder's straight direction
]


@pytest.mark.parametrize("args,knots,rng", HAND_KNOTS)
def test_knots_follow_blenders_rule(args, knots, rng):
    got, got_range = bsgi.blender_knots(*args)
    assert got.tolist() == knots
    assert got_range == rng


@pytest.mark.parametrize("order", [2, 3, 4, 5, 6])
def test_knot_vectors_have_blenders_length_and_are_nondecreasing(order):
    for endpoint, bezier, cyclic in FLAGS:
        n = valid_count(order)
        knots, (a, b) = bsgi.blender_knots(n, order, endpoint, bezier, cyclic)
        assert len(knots) == n + order + (order - 1 if cyclic else 0)
        assert np.all(np.diff(knots) >= 0) and a < b


def random_surface(rng, order_u, order_v, fu, fv):
    nu, nv = valid_count(order_u, rng.integers(0, 3)), valid_count(order_v, rng.integers(0, 3))
    g = np.stack(np.meshgrid(np.arange(nu), np.arange(nv), indexing="xy"), -1).reshape(-1, 2).astype(float)
    pts = np.column_stack([g[:, 0] + rng.uniform(-0.3, 0.3, len(g)), g[:, 1] + rng.uniform(-0.3, 0.3, len(g)),
                           rng.uniform(-1, 1, len(g)), rng.uniform(0.3, 3.0, len(g))])
    kw = dict(count_u=nu, count_v=nv, order_u=order_u, order_v=order_v, endpoint_u=fu[0], bezier_u=fu[1],
              cyclic_u=fu[2], endpoint_v=fv[0], bezier_v=fv[1], cyclic_v=fv[2])
    return pts, kw


@pytest.mark.parametrize("order_u,order_v", [(2, 3), (3, 3), (4, 2), (4, 5), (5, 4), (6, 6), (3, 6)])
def test_rational_evaluation_and_derivatives_match_scipy(order_u, order_v):
    rng = np.random.default_rng(order_u * 10 + order_v)
    for fu, fv in itertools.islice(itertools.product(FLAGS, FLAGS), 0, 64, 5):
        pts, kw = random_surface(rng, order_u, order_v, fu, fv)
        s = bsgi.NurbsSurface("random", pts, **kw)
        ref = scipy_nurbs(pts, kw["count_u"], kw["count_v"], s.knots_u, s.knots_v, order_u, order_v, fu[2], fv[2])
        (au, bu), (av, bv) = s.range_u, s.range_v
        uv = rng.uniform(0, 1, (40, 2))
        uv[:4] = [[0, 0], [1, 1], [0, 1], [1, 0]]
        e = s.evaluate(uv)
        for i, (u, v) in enumerate(uv):
            # Right ends evaluate from the left (scipy's last span), except in cyclic
            # directions, where 1 is 0 again.
            x = au if (u == 1 and fu[2]) else min(au + u * (bu - au), np.nextafter(bu, -np.inf))
            y = av if (v == 1 and fv[2]) else min(av + v * (bv - av), np.nextafter(bv, -np.inf))
            p, su, sv, suv = rational_derivatives(ref, x, y, bu - au, bv - av)
            scale = np.abs(pts[:, :3]).max()
            assert np.allclose(e["position"][i], p, atol=1e-11 * scale), (fu, fv, u, v)
            assert np.allclose(e["dpdu"][i], su, atol=1e-9 * scale * (bu - au)), (fu, fv, u, v)
            assert np.allclose(e["dpdv"][i], sv, atol=1e-9 * scale * (bv - av)), (fu, fv, u, v)
            assert np.allclose(s.mixed_derivative(u, v), suv, atol=1e-8 * scale * (bu - au) * (bv - av))


def test_blender_sphere_is_an_exact_sphere_with_its_area():
    s = bsgi.NurbsSurface("sphere", blender_sphere_points(2.0), **SPHERE_FLAGS)
    g = np.linspace(0, 1, 101)
    uv = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    r = np.linalg.norm(s.evaluate(uv)["position"], axis=1)
    assert np.abs(r - 2).max() < 1e-13
    assert s.area == pytest.approx(4 * np.pi * 4, rel=1e-8)


def test_cyclic_directions_are_periodic_and_continuous():
    rng = np.random.default_rng(5)
    pts, kw = random_surface(rng, 4, 3, (False, False, True), (True, True, True))
    s = bsgi.NurbsSurface("periodic", pts, **kw)
    uv = rng.uniform(0, 1, (50, 2))
    a = s.evaluate(uv)["position"]
    assert np.allclose(s.evaluate(uv + [1, 0])["position"], a, atol=1e-12)
    assert np.allclose(s.evaluate(uv - [0, 1])["position"], a, atol=1e-12)
    # Across the seam the surface (and its tangent) continue.
    seam = np.column_stack([np.zeros(20), np.linspace(0, 1, 20)])
    left = s.evaluate(seam - [1e-9, 0])
    right = s.evaluate(seam)
    assert np.allclose(left["position"], right["position"], atol=1e-7)
    assert np.allclose(left["dpdu"], right["dpdu"], rtol=1e-5, atol=1e-6)


def test_derivatives_match_finite_differences_on_sphere():
    s = bsgi.NurbsSurface("sphere", blender_sphere_points(), **SPHERE_FLAGS)
    uv = np.random.default_rng(2).uniform(0.05, 0.95, (30, 2))
    h = 1e-6
    e = s.evaluate(uv)
    du = (s.evaluate(uv + [h, 0])["position"] - s.evaluate(uv - [h, 0])["position"]) / (2 * h)
    dv = (s.evaluate(uv + [0, h])["position"] - s.evaluate(uv - [0, h])["position"]) / (2 * h)
    assert np.allclose(e["dpdu"], du, atol=1e-6)
    assert np.allclose(e["dpdv"], dv, atol=1e-6)


def grid_points(nu, nv):
    g = np.stack(np.meshgrid(np.arange(nu), np.arange(nv), indexing="xy"), -1).reshape(-1, 2)
    return np.column_stack([g, np.zeros(len(g)), np.ones(len(g))]).astype(float)


@pytest.mark.parametrize("field,value,message", [
    (0, np.nan, "control point 5 .* NaN or infinite"),
    (1, np.inf, "NaN or infinite"),
    (3, 0.0, "weight 0; weights must be > 0"),
    (3, -1.0, "weight -1"),
])
def test_bad_control_points_are_named(field, value, message):
    pts = grid_points(4, 4)
    pts[5, field] = value
    with pytest.raises(ValueError, match=f"surface 'Patch.001'.*{message}"):
        bsgi.NurbsSurface("Patch.001", pts, 4, 4)


@pytest.mark.parametrize("count_u,order_u,flags,message", [
    (4, 7, (False, False, False), "order 7 is outside 2..6"),
    (4, 1, (False, False, False), "order 1 is outside 2..6"),
    (3, 4, (False, False, False), "3 control points are fewer than the order 4"),
    (7, 4, (False, True, True), "cyclic Bezier needs a multiple of order-1 = 3"),
    (4, 4, (False, True, False), "Bezier without endpoints needs more control points"),
])
def test_point_counts_blender_refuses_are_named(count_u, order_u, flags, message):
    with pytest.raises(ValueError, match=f"surface 'Bad': direction u: {message}"):
        bsgi.NurbsSurface("Bad", grid_points(count_u, 4), count_u, 4, order_u, 4, endpoint_u=flags[0], bezier_u=flags[1],
                          cyclic_u=flags[2])


def test_wrong_number_of_points_is_named():
    with pytest.raises(ValueError, match=r"surface 'Short': expected 4 x 4 = 16 control points"):
        bsgi.NurbsSurface("Short", grid_points(4, 4)[:15], 4, 4)
    with pytest.raises(ValueError, match="surface 'Flat3'.*shape"):
        bsgi.NurbsSurface("Flat3", grid_points(4, 4)[:, :3], 4, 4)


def test_tessellation_chords_stay_close_and_lifted_triangles_enclose_the_sphere():
    s = bsgi.NurbsSurface("sphere", blender_sphere_points(), **SPHERE_FLAGS)
    t = s.tessellate()
    assert np.allclose(np.linalg.norm(t["positions"], axis=1), 1, atol=1e-6)  # vertices on the surface
    tri = t["positions"][t["triangles"]]
    centroid_r = np.linalg.norm(tri.mean(1), axis=1)
    # Chords within the tolerance (2e-4 of the size 2 sqrt 3) in each direction.
    assert centroid_r.min() > 1 - 2 * 2e-4 * 2 * np.sqrt(3)
    lifted = s.tessellate(for_rays=True)
    tri = lifted["positions"][lifted["triangles"]]
    # Every triangle's points lie outside the sphere: rays from outside meet them first.
    w = np.random.default_rng(0).dirichlet([1, 1, 1], size=(len(tri), 4))
    pts = np.einsum("tkc,tcx->tkx", w, tri)
    assert np.linalg.norm(pts, axis=2).min() >= 1 - 1e-6
