"""Generalized form factors (36)-(37): the transport operator of the Lambertian receivers,
assembled once, gives the light that gathering by rays gives every bounce (solver.cpp)."""
import numpy as np

import bsgi
from reference import scene_spec


def solve(spec, form_factors, **kw):
    scene = scene_spec.to_bsgi(spec)
    settings = bsgi.SolverSettings()
    settings.form_factors = form_factors
    settings.max_bounces = 6
    settings.tolerance = 0
    for k, v in kw.items():
        setattr(settings, k, v)
    return bsgi.solve(scene, settings)


def test_form_factors_match_ray_gathering_on_the_cornell_box():
    spec = scene_spec.cornell_box()
    rays, operator = solve(spec, False), solve(spec, True)
    assert operator.stats["transport_terms"] > 0 and rays.stats["transport_terms"] == 0
    # Fewer rays: cast once instead of every bounce.
    assert operator.stats["rays"] < 0.5 * rays.stats["rays"]
    for a, b in zip(rays.radiance, operator.radiance):
        if a is None:
            continue
        # float32 weights: agreement to about 1e-6 of the radiance
        np.testing.assert_allclose(b.coefficients, a.coefficients, rtol=1e-5, atol=1e-6 * np.abs(a.coefficients).max())


def test_form_factors_with_a_glossy_wall_in_the_scene():
    spec = scene_spec.glossy_cornell_box(alpha=0.4)
    kw = dict(angular_coeffs_max=8, bsdf_samples=4, max_bounces=3)
    rays, operator = solve(spec, False, **kw), solve(spec, True, **kw)
    for a, b in zip(rays.radiance, operator.radiance):
        if a is not None:
            np.testing.assert_allclose(b.coefficients, a.coefficients, rtol=1e-5, atol=1e-6 * np.abs(a.coefficients).max())
