"""Solution files (python/bsgi/solution_io.py): exact round trip of splines and settings."""
import numpy as np
import pytest

import bsgi


def solved_scene():
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), albedo=[0.5, 0.6, 0.7],
                             emission=[0] * 3)
    scene.add_triangle("wedge", np.array([[0, 0, 0.2], [0, 1, 0.2], [0, 0.5, 0.8]], float), albedo=[0.3] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("lamp", np.array([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]], float), albedo=[0] * 3,
                             emission=[4] * 3, receiver=False, occluder=False)
    settings = bsgi.SolverSettings()
    settings.spatial_coeffs = 9
    settings.max_bounces = 2
    return scene, settings, bsgi.solve(scene, settings)


def test_round_trip_is_exact(tmp_path):
    scene, settings, sol = solved_scene()
    names = [scene.name(i) for i in range(len(scene))]
    path = tmp_path / "solution.npz"
    bsgi.save_solution(path, sol.radiance, names, settings, sol.stats)
    stored = bsgi.load_solution(path)
    assert stored.names == names
    assert stored.radiance[2] is None  # the lamp emits only
    for a, b in zip(sol.radiance[:2], stored.radiance[:2]):
        np.testing.assert_array_equal(a.coefficients, b.coefficients)
        for ka, kb in zip(a.axes, b.axes):
            np.testing.assert_array_equal(ka.knots, kb.knots)
            assert ka.degree == kb.degree
        uv = np.random.default_rng(3).uniform(0, 1, (50, 2))
        np.testing.assert_array_equal(a.evaluate(uv), b.evaluate(uv))
    assert stored.settings.spatial_coeffs == 9 and stored.settings.max_bounces == 2
    assert stored.stats["bounces"] == sol.stats["bounces"]


def test_non_uniform_knots_round_trip():
    k = bsgi.KnotVector([0, 0, 0, 0.1, 0.15, 0.7, 1, 1, 1], 2)
    spline = bsgi.TensorSpline([k, bsgi.KnotVector.clamped_uniform(4, 1)], 2)
    spline.coefficients = np.random.default_rng(0).normal(size=spline.coefficients.shape)
    back = bsgi.spline_from_arrays(bsgi.spline_to_arrays(spline))
    np.testing.assert_array_equal(back.coefficients, spline.coefficients)
    np.testing.assert_array_equal(back.axes[0].knots, k.knots)


def test_other_files_are_refused(tmp_path):
    path = tmp_path / "other.npz"
    np.savez(path, meta=np.frombuffer(b'{"format": "something"}', np.uint8))
    with pytest.raises(ValueError, match="not a bsgi solution"):
        bsgi.load_solution(path)


def test_glossy_and_transmitting_surfaces_round_trip(tmp_path):
    # A rough glass sheet (4D, both hemispheres) and a GGX patch over a floor.
    scene = bsgi.Scene()
    quad = lambda z, s=1.0: np.array([[0, 0, z], [s, 0, z], [s, s, z], [0, s, z]], float)
    scene.add_bilinear_patch("floor", quad(0), albedo=[0.5] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("glass", quad(0.5, 0.6), albedo=[0] * 3, emission=[0] * 3,
                             bsdf=bsgi.RoughDielectric(1.5, 0.4, 0.4), spatial_coeffs=4, angular_coeffs=6)
    scene.add_bilinear_patch("lamp", quad(1)[::-1].copy(), albedo=[0] * 3, emission=[3] * 3, receiver=False)
    scene.add_bilinear_patch("plastic", quad(0.2, 0.3), albedo=[0] * 3, emission=[0] * 3,
                             bsdf=bsgi.DiffuseGgx([0.5] * 3, 0.3, 0.3, [0.04] * 3), representation="decomposed")
    settings = bsgi.SolverSettings.preset("draft")
    settings.final_gather = False
    sol = bsgi.solve(scene, settings)
    path = tmp_path / "glass.npz"
    bsgi.save_solution(path, sol.surfaces, [scene.name(i) for i in range(len(scene))], settings)
    stored = bsgi.load_solution(path)
    a, b = sol.surfaces[1], stored.surfaces[1]
    assert b.kind == "glossy" and b.lower is not None and b.disc_radius == a.disc_radius
    rng = np.random.default_rng(0)
    uv = rng.uniform(0, 1, (40, 2))
    d = rng.normal(size=(40, 3))  # both hemispheres
    np.testing.assert_array_equal(a.evaluate(uv, d), b.evaluate(uv, d))
    assert np.abs(a.evaluate(uv, d)[d[:, 2] < 0]).max() > 0  # the lower spline carries light
    assert stored.surfaces[0].kind == "diffuse" and stored.surfaces[2] is None
    assert stored.surfaces[3].kind == "decomposed" and stored.surfaces[3].diffuse is not None
    np.testing.assert_array_equal(sol.surfaces[3].evaluate(uv, np.abs(d)), stored.surfaces[3].evaluate(uv, np.abs(d)))


def test_back_sides_round_trip(tmp_path):
    # A decomposed plane lit from below only: its back side has a glossy S and a diffuse D of
    # its own (lower, lower_diffuse), its front none; the file keeps them exactly.
    scene = bsgi.Scene()
    scene.add_bilinear_patch("plane", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), albedo=[0.5] * 3,
                             emission=[0] * 3, bsdf=bsgi.DiffuseGgx([0.4] * 3, 0.3, 0.3, [0.5] * 3),
                             representation="decomposed")
    scene.add_bilinear_patch("lamp", np.array([[0, 0, -1], [1, 0, -1], [1, 1, -1], [0, 1, -1]], float), albedo=[0] * 3,
                             emission=[4] * 3, receiver=False, occluder=False)
    settings = bsgi.SolverSettings()
    settings.spatial_coeffs = 6
    settings.max_bounces = 0
    sol = bsgi.solve(scene, settings)
    surface = sol.surfaces[0]
    assert surface.lower is not None and surface.lower_diffuse is not None
    path = tmp_path / "two_sided.npz"
    bsgi.save_solution(path, sol.surfaces, ["plane", "lamp"], settings)
    stored = bsgi.load_solution(path).surfaces[0]
    rng = np.random.default_rng(1)
    uv, dirs = rng.uniform(0, 1, (40, 2)), rng.normal(size=(40, 3))
    got = stored.evaluate(uv, dirs)
    np.testing.assert_array_equal(got, surface.evaluate(uv, dirs))
    assert got[dirs[:, 2] < 0].max() > 0 and got[dirs[:, 2] > 0].max() == 0
