"""Spot cones (Scene.set_spot_cone, Blender's spot light): a small emitting sphere whose light is
limited to a cone with Cycles' smoothstep edge, against the closed form of a floor under it."""
import math

import numpy as np
import pytest

import bsgi
from nurbs_reference import SPHERE_FLAGS, blender_sphere_points

ALBEDO, RADIANCE, RADIUS, HEIGHT = 0.5, 1e4, 0.01, 1.0
SIZE = math.radians(60)  # full cone angle: the edge's foot at x = tan(30 deg) = 0.577 on the floor


def solve_spot(blend, axis=(0, 0, -1), spatial_coeffs=32):
    points = blender_sphere_points(RADIUS)
    points[:, 2] += HEIGHT
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float),
                             albedo=[ALBEDO] * 3, emission=[0] * 3)
    k = scene.add_surface(bsgi.NurbsSurface("spot", points, front="blender", **SPHERE_FLAGS), albedo=[0] * 3,
                          emission=[RADIANCE] * 3, receiver=False, occluder=False)
    scene.set_spot_cone(k, axis, SIZE, blend)
    s = bsgi.SolverSettings()
    s.spatial_coeffs, s.max_bounces = spatial_coeffs, 0
    return bsgi.solve(scene, s)


def closed_form(x, blend):
    """The uniform sphere's floor radiance (albedo / pi) pi L (r/d)^2 cos(theta), times Cycles'
    cone factor smoothstep((cos angle - cos(size/2)) / ((1 - cos(size/2)) blend)) along the
    direction from the centre (the sphere is 1 cm across: its points see the floor point within
    0.6 degrees of that)."""
    d2 = x**2 + HEIGHT**2
    cos_angle = HEIGHT / np.sqrt(d2)
    cos_half = math.cos(SIZE / 2)
    t = np.clip((cos_angle - cos_half) / ((1 - cos_half) * blend), 0, 1) if blend > 0 else (cos_angle > cos_half) * 1.0
    return ALBEDO * RADIANCE * RADIUS**2 / d2 * cos_angle * t * t * (3 - 2 * t)


def floor_values(sol, x):
    return sol.radiance[0].evaluate(np.stack([(x + 1) / 2, np.full_like(x, 0.5)], axis=1))[:, 0]


def test_soft_cone_follows_the_smoothstep_edge():
    # blend 0.5: the edge spreads from x = 0.577 inwards to about x = 0.39; the solve follows the
    # closed form across it, up to the (Schoenberg, second order) fit of its bends.
    x = np.linspace(0, 0.95, 39)
    want = closed_form(x, 0.5)
    errors = {}
    for n in (16, 32, 64):
        got = floor_values(solve_spot(0.5, spatial_coeffs=n), x)
        errors[n] = np.abs(got - want).max() / want.max()
        assert np.abs(got[x > 0.75]).max() < 1e-3 * want.max()  # outside the cone, beyond the splines' reach
    print("\nsoft spot cone: max error of the peak by coefficients", {k: f"{v:.3f}" for k, v in errors.items()})
    # Measured 0.152, 0.044, 0.012: each doubling divides the error by 3.5-3.7, second order (4).
    assert errors[64] < 0.024
    assert errors[64] < errors[32] / 3 and errors[32] < errors[16] / 3


def test_hard_cone_is_full_inside_and_dark_outside():
    x = np.array([0.0, 0.2, 0.35, 0.8, 0.9])
    got, want = floor_values(solve_spot(0.0), x), closed_form(x, 0.0)
    np.testing.assert_allclose(got[:3], want[:3], rtol=0.02)
    assert np.abs(got[3:]).max() < 1e-3 * want.max()


def test_cone_turns_with_its_axis():
    # Tilted 20 degrees towards +x: the lit disc moves to the right.
    t = math.radians(20)
    sol = solve_spot(0.2, axis=(math.sin(t), 0, -math.cos(t)))
    left, right = floor_values(sol, np.array([-0.6, 0.85]))
    assert left < 1e-3 * right


def test_bad_cones_are_refused_by_name():
    scene = bsgi.Scene()
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    scene.add_bilinear_patch("floor", quad, albedo=[0.5] * 3, emission=[0] * 3)
    k = scene.add_bilinear_patch("lamp", quad + [0, 0, 1], albedo=[0] * 3, emission=[1] * 3, receiver=False)
    with pytest.raises(ValueError, match="spot light 'floor': emits no light"):
        scene.set_spot_cone(0, [0, 0, -1], 1.0, 0.1)
    for args, what in ((([0, 0, 0], 1.0, 0.1), "axis"), (([0, 0, -1], 0.0, 0.1), "spot size"),
                       (([0, 0, -1], 4.0, 0.1), "spot size"), (([0, 0, -1], 1.0, 1.5), "blend")):
        with pytest.raises(ValueError, match=f"spot light 'lamp': {what}"):
            scene.set_spot_cone(k, *args)
    with pytest.raises(IndexError):
        scene.set_spot_cone(5, [0, 0, -1], 1.0, 0.1)
