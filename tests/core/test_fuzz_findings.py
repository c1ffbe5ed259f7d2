"""Inputs the fuzz tests (tests/fuzz, issue 17) found to crash, hang or give NaN, kept as regular
tests after their fix. Each names what went wrong before."""
import time

import numpy as np
import pytest

import bsgi

QUAD = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)


def test_a_knot_span_whose_inverse_overflows_is_refused():
    # Was: a valid knot vector whose basis functions were all NaN (1 / 2e-311 = inf).
    with pytest.raises(ValueError, match="knot vector: knot span .* too narrow"):
        bsgi.KnotVector([0.0, 0.0, 2.225073858507e-311, 1.0], 1)


def test_knot_averages_near_the_largest_double_are_finite():
    # Was: the Schoenberg node (t1 + t2) / 2 = -inf (the sum overflows).
    big = 1.7976931348623157e308
    k = bsgi.KnotVector.clamped_uniform(3, 2, -big, 0.0)
    np.testing.assert_array_equal(k.schoenberg_nodes(), [-big, -big / 2, 0.0])


@pytest.mark.parametrize("make", [bsgi.KnotVector.clamped_uniform, lambda n, d: bsgi.KnotVector.symmetric(n, d, 1.0)])
def test_a_knot_vector_of_two_billion_coefficients_is_refused_at_once(make):
    # Was: minutes and gigabytes building the knots (and an int overflow in their count).
    start = time.monotonic()
    with pytest.raises(bsgi.MemoryBudgetError, match="knot vector"):
        make(2**31 - 1, 5)
    assert time.monotonic() - start < 1.0


def test_scene_name_and_area_of_a_missing_surface_raise_index_error():
    # Was: a read past the end of the scene's surfaces (a crash or garbage).
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", QUAD, albedo=[0.5] * 3, emission=[0] * 3)
    for call in (scene.name, scene.area):
        with pytest.raises(IndexError, match="no surface 5"):
            call(5)


@pytest.mark.parametrize("call, message", [
    (lambda s: s.add_distant_light("Sun", [], [1, 1, 1]), "distant light 'Sun': direction must have 3 values"),
    (lambda s: s.add_distant_light("Sun", [0, 0, 1], [1]), "distant light 'Sun': irradiance must have 3 values"),
    (lambda s: s.set_spot_cone(0, [0, 1], 1.0), "spot light 'lamp': axis must have 3 values"),
    (lambda s: s.add_bilinear_patch("Wall", QUAD, albedo=[0.5], emission=[0] * 3), "surface 'Wall': albedo must have 3 values"),
    (lambda s: s.add_disk("Disc", [0, 0], [1, 0, 0], [0, 1, 0], albedo=[0.5] * 3, emission=[0] * 3),
     "surface 'Disc': center must have 3 values"),
])
def test_vectors_of_the_wrong_length_name_their_object(call, message):
    # Was: 'direction must have 3 values' without the light or surface it belongs to.
    scene = bsgi.Scene()
    scene.add_bilinear_patch("lamp", QUAD, albedo=[0] * 3, emission=[1] * 3)
    with pytest.raises(ValueError, match=message):
        call(scene)


def test_a_truncated_or_damaged_solution_file_is_refused_naming_the_file(tmp_path):
    # Was: zipfile.BadZipFile, EOFError, KeyError or zlib.error from deep inside numpy.
    spline = bsgi.TensorSpline([bsgi.KnotVector.clamped_uniform(3, 2)] * 2, 3)
    path = tmp_path / "solution.npz"
    bsgi.save_solution(path, [spline], ["floor"], bsgi.SolverSettings())
    data = path.read_bytes()
    for name, content in (("cut.npz", data[: len(data) // 2]), ("empty.npz", b""),
                          ("flipped.npz", data[:200] + bytes([data[200] ^ 0x10]) + data[201:])):
        (tmp_path / name).write_bytes(content)
        with pytest.raises(ValueError, match=name):
            bsgi.load_solution(tmp_path / name)


def test_a_solution_file_with_non_finite_coefficients_is_refused(tmp_path):
    spline = bsgi.TensorSpline([bsgi.KnotVector.clamped_uniform(3, 2)] * 2, 3)
    spline.coefficients = np.full(spline.shape, np.nan)
    path = tmp_path / "nan.npz"
    bsgi.save_solution(path, [spline], ["floor"], bsgi.SolverSettings())
    with pytest.raises(ValueError, match="nan.npz: surface 'floor': upper spline: coefficients must be finite"):
        bsgi.load_solution(path)


@pytest.mark.parametrize("field, value", [("emitter_coeffs", 10**6), ("hemisphere_nodes_theta", 10**6),
                                          ("bsdf_samples", 10**6), ("final_integration_factor", 1000)])
def test_settings_that_would_never_finish_are_refused(field, value):
    # Was: emitter_coeffs = 10^6 solved for hours (10^12 nodes per emitter cell).
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", QUAD, albedo=[0.5] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("lamp", QUAD[::-1] + [0, 0, 1], albedo=[0] * 3, emission=[1] * 3)
    settings = bsgi.SolverSettings()
    setattr(settings, field, value)
    with pytest.raises(ValueError, match="solver settings: "):
        bsgi.solve(scene, settings)


@pytest.mark.parametrize("make", [bsgi.SmoothDielectric, lambda eta: bsgi.RoughDielectric(eta, 0.3, 0.3)])
def test_a_dielectric_of_a_denormal_index_is_refused(make):
    # Was: accepted, and its samples had infinite weights.
    with pytest.raises(ValueError, match=r"dielectric eta must be in \[0.01, 10\]"):
        make(2.225073858507e-311)


def test_the_memory_estimate_refuses_invalid_settings():
    # Was: UBSan, signed integer overflow in the solver's plan (angular_degree -1, emitter_coeffs -1).
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", QUAD, albedo=[0.5] * 3, emission=[0] * 3, bsdf=bsgi.GgxReflection(0.3, 0.3, [0.5] * 3))
    scene.add_bilinear_patch("lamp", QUAD[::-1] + [0, 0, 1], albedo=[0] * 3, emission=[1] * 3)
    settings = bsgi.SolverSettings()
    settings.angular_degree, settings.emitter_coeffs, settings.angular_resolution = -1, -1, -1.5e176
    with pytest.raises(ValueError, match="solver settings: angular_degree must be in 0..5"):
        bsgi.estimate_solve_bytes(scene, settings)


def _unit_square():
    return bsgi.BilinearPatch("S", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]))


@pytest.mark.parametrize("origin, direction", [([1e300, 0, 0], [0, 0, 1]), ([0.5, 0.5, 1], [0, 0, -1e19])])
def test_a_ray_beyond_single_precision_is_refused(origin, direction):
    # The sanitizer run's fuzzing found it: Embree takes float rays and aborted the process (an
    # assertion in Debian's build) on an origin of 1e300, a finite double.
    caster = bsgi.RayCaster([_unit_square()])
    with pytest.raises(ValueError, match="ray origins and directions must be finite and at most 1e18"):
        caster.closest_hit(np.array([origin], float), np.array([direction], float))


def test_a_ray_embree_cannot_represent_misses_instead_of_aborting():
    # A surface 1e20 away puts the scene's centre there: a ray near the origin is beyond Embree's
    # range relative to it, and misses.
    far = bsgi.BilinearPatch("far", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]) * 1e20)
    caster = bsgi.RayCaster([_unit_square(), far])
    hits = caster.closest_hit(np.array([[0.5, 0.5, 1.0]]), np.array([[0, 0, -1.0]]))
    assert hits["surface"][0] == -1
