"""The disc-to-hemisphere map (20)-(22), its inverse and the pull-in to radius R."""
import numpy as np
import pytest

import bsgi


def paper_map(ab):
    """(20)-(22) as printed, for 0 < r < 1: z = 1 - r^2, (x, y) = sqrt(1 - z^2) / r (alpha, beta)."""
    r = np.linalg.norm(ab, axis=1)
    z = 1 - r**2
    f = np.sqrt(1 - z**2) / r
    return np.column_stack([f * ab[:, 0], f * ab[:, 1], z])


def random_directions(rng, n, theta_max):
    """Uniform on the cap theta <= theta_max."""
    z = rng.uniform(np.cos(theta_max), 1, n)
    phi = rng.uniform(-np.pi, np.pi, n)
    s = np.sqrt(1 - z * z)
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), z])


def test_forward_map_is_20_to_22():
    rng = np.random.default_rng(0)
    h = bsgi.HemisphereMap(0.99)
    r = rng.uniform(0.01, 0.99, 1000)
    phi = rng.uniform(-np.pi, np.pi, 1000)
    ab = np.column_stack([r * np.cos(phi), r * np.sin(phi)])
    d = h.to_direction(ab)
    np.testing.assert_allclose(d, paper_map(ab), atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1, atol=1e-15)


@pytest.mark.parametrize("delta", [0.3, 0.05, 1e-3, 1e-6])
def test_round_trip_inside_the_cone(delta):
    rng = np.random.default_rng(1)
    h = bsgi.HemisphereMap.for_max_angle(delta)
    assert h.max_theta == pytest.approx(np.pi / 2 - delta, abs=1e-12)
    d = random_directions(rng, 20000, np.pi / 2 - delta)
    ab = h.to_disc(d)
    assert np.all(np.linalg.norm(ab, axis=1) <= h.radius * (1 + 1e-15))
    assert np.max(np.abs(h.to_direction(ab) - d)) <= 1e-6  # the bound
    assert np.max(np.abs(h.to_direction(ab) - d)) <= 1e-12  # what the formulas achieve
    # and the other way round, (alpha, beta) -> direction -> (alpha, beta)
    np.testing.assert_allclose(h.to_disc(h.to_direction(ab)), ab, atol=1e-12)


def test_any_positive_length_is_accepted():
    rng = np.random.default_rng(2)
    h = bsgi.HemisphereMap.for_max_angle(0.05)
    d = random_directions(rng, 100, 1.4)
    scale = rng.uniform(1e-3, 1e3, (100, 1))
    np.testing.assert_allclose(h.to_disc(d * scale), h.to_disc(d), atol=1e-13)


def test_pole():
    h = bsgi.HemisphereMap(0.9)
    np.testing.assert_array_equal(h.to_direction(np.array([0.0, 0.0])), [0, 0, 1])
    np.testing.assert_array_equal(h.to_disc(np.array([0.0, 0.0, 1.0])), [0, 0])
    np.testing.assert_array_equal(h.angles(np.array([0.0, 0.0])), [0, 0])  # phi = 0 at the pole
    # Near the pole theta = 2 asin(r / sqrt 2) keeps full relative accuracy (acos(1 - r^2) would not).
    r = 1e-9
    assert h.angles(np.array([r, 0.0]))[0] == pytest.approx(np.sqrt(2) * r, rel=1e-12)


def test_angles_are_the_spherical_coordinates_4_5_of_the_direction():
    rng = np.random.default_rng(3)
    h = bsgi.HemisphereMap(0.95)
    ab = rng.uniform(-0.6, 0.6, (1000, 2))
    d = h.to_direction(ab)
    tp = h.angles(ab)
    np.testing.assert_allclose(tp[:, 0], np.arccos(d[:, 2]), atol=1e-12)
    np.testing.assert_allclose(tp[:, 1], np.arctan2(d[:, 1], d[:, 0]), atol=1e-12)


def test_rim_and_pull_in():
    rng = np.random.default_rng(4)
    delta = 0.05
    h = bsgi.HemisphereMap.for_max_angle(delta)
    R = h.radius
    assert R == pytest.approx(np.sqrt(1 - np.sin(delta)), abs=1e-15)
    phi = rng.uniform(-np.pi, np.pi, 200)
    rim = R * np.column_stack([np.cos(phi), np.sin(phi)])
    d = h.to_direction(rim)
    np.testing.assert_allclose(np.arccos(d[:, 2]), np.pi / 2 - delta, atol=1e-12)
    # Points outside the disc are pulled in radially to radius R.
    far = rim * rng.uniform(1.0, 50.0, (200, 1))
    np.testing.assert_allclose(h.to_direction(far), d, atol=1e-14)
    np.testing.assert_allclose(h.angles(far), h.angles(rim), atol=1e-14)
    # Directions beyond the cone, also below the horizon, go to the rim point of their azimuth.
    for theta in (np.pi / 2 - delta / 2, np.pi / 2, 2.0, np.pi - 1e-3):
        out = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.full(200, np.cos(theta))])
        np.testing.assert_allclose(h.to_disc(out), rim, atol=1e-12)
    np.testing.assert_array_equal(h.to_disc(np.array([0.0, 0.0, -1.0])), [R, 0])  # straight down


def test_R_to_one():
    h = bsgi.HemisphereMap(1.0)
    assert h.max_theta == pytest.approx(np.pi / 2)
    np.testing.assert_allclose(h.to_direction(np.array([1.0, 0.0])), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(h.to_disc(np.array([0.0, 1.0, 0.0])), [0, 1], atol=1e-15)
    np.testing.assert_allclose(h.to_disc(np.array([0.0, 1.0, -0.5])), [0, 1], atol=1e-15)
    h = bsgi.HemisphereMap(1 - 1e-15)
    np.testing.assert_allclose(h.to_direction(np.array([1.0, 0.0])), [1, 0, 0], atol=1e-7)
    assert bsgi.HemisphereMap.for_max_angle(0.0).radius == 1.0


def test_invalid_inputs():
    for R in (0.0, -0.5, 1.0000001, np.nan):
        with pytest.raises(ValueError, match="R must be in"):
            bsgi.HemisphereMap(R)
    with pytest.raises(ValueError, match="delta"):
        bsgi.HemisphereMap.for_max_angle(-0.1)
    h = bsgi.HemisphereMap(0.9)
    bad = np.array([[0, 0, 0], [np.nan, 0, 1], [np.inf, 0, 1], [0, 0, -np.inf]], float)
    assert np.all(np.isnan(h.to_disc(bad)))
    assert np.all(np.isnan(h.to_direction(np.array([[np.nan, 0.0], [np.inf, 0.0]]))))
    with pytest.raises(ValueError, match="shape"):
        h.to_disc(np.zeros((4, 2)))


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_radiance_evaluation_through_the_map(precision):
    """L(u, v, direction) equals the spline at (u, v, alpha, beta) with (alpha, beta) mapped
    independently in numpy: (x, y) / sqrt(1 + z) for unit directions, pulled in to R."""
    rng = np.random.default_rng(5)
    h = bsgi.HemisphereMap.for_max_angle(0.05)
    sk = bsgi.KnotVector.clamped_uniform(7, 2, 1e-3, 1 - 1e-3)
    ak = bsgi.KnotVector.symmetric(6, 2, h.radius)
    L = bsgi.TensorSpline([sk, sk, ak, ak], 3, precision)
    L.coefficients = rng.uniform(0.5, 1.5, L.shape)
    n = 5000
    uv = rng.uniform(0, 1, (n, 2))
    d = np.r_[random_directions(rng, n - 3, np.pi / 2), [[0, 0, 1], [1, 0, 0], [0, 0.2, -1]]]
    d = d * rng.uniform(0.5, 2, (n, 1))
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    ab = u[:, :2] / np.sqrt(1 + u[:, 2:3])
    r = np.linalg.norm(ab, axis=1, keepdims=True)
    ab = np.where(r > h.radius, ab * h.radius / np.where(r > 0, r, 1), ab)
    expected = L.evaluate(np.column_stack([uv, ab]))
    got = L.evaluate_directions(uv, d, h)
    np.testing.assert_allclose(got, expected, rtol=1e-12 if precision == "float64" else 1e-5)
    bad = d.copy()
    bad[7] = 0
    out = L.evaluate_directions(uv, bad, h)
    assert np.all(np.isnan(out[7])) and not np.any(np.isnan(np.delete(out, 7, axis=0)))
    with pytest.raises(ValueError, match="4D spline"):
        bsgi.TensorSpline([sk, sk], 3).evaluate_directions(uv, d, h)
