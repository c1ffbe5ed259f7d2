"""Normal maps (normal_map.h, Scene.set_normal_texture, BumpedLambert): a Lambertian surface under a
bumped normal n reflects albedo / pi max(0, n . wi) G1 of the light above it, G1 Cycles' bump
shadowing term (closure/bsdf.h bump_shadowing_term, re-derived here from its formula). Closed
forms: a constant tilted map under a sun is a tilted plane (without Bump Map Correction), a
uniform world gives a tilted plane's (1 + cos theta) / 2 of the sky, and another surface sees the
bumped one as it sees an emitter of the radiance the closed form gives."""
import math

import numpy as np
import pytest

import bsgi
from reference.scene_spec import quad
from test_solver_distant_light import solve  # direct light alone unless told

ALBEDO = 0.7
E = np.array([3.0, 2.0, 1.0])
RNG = np.random.default_rng(11)
UV = RNG.uniform(0.02, 0.98, (60, 2))


def cycles_shadowing(cos_n, cos_i):
    """Cycles' bump_shadowing_term for a diffuse closure with Bump Map Correction: Smith's GGX G1
    along the light at alpha^2 = min(1, tan^2(theta_n) / 8)."""
    cos_n, cos_i = np.broadcast_arrays(np.asarray(cos_n, float), np.asarray(cos_i, float))
    alpha2 = np.clip(0.125 * (1 / cos_n**2 - 1), 0, 1)
    lam = 0.5 * (np.sqrt(1 + alpha2 * (1 / np.maximum(cos_i, 1e-12) ** 2 - 1)) - 1)
    g = 1 / (1 + lam)
    return np.where((cos_n >= 1) | (cos_i >= 1), 1.0, np.where(cos_i < 1e-6, 0.0, g))


def tilted(theta_deg, azimuth_deg=0.0):
    t, a = math.radians(theta_deg), math.radians(azimuth_deg)
    return np.array([math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), math.cos(t)])


def floor_scene(normals, bump_correction=True, albedo=ALBEDO):
    """A 2 x 2 floor (normal +z, u along +x) under the normal map `normals` (H, W, 3) world space."""
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), albedo=[albedo] * 3, emission=[0, 0, 0])
    scene.set_normal_texture(0, np.asarray(normals, np.float32), bump_correction=bump_correction)
    return scene


def views(n, below=False):
    """Random directions towards viewers above (or below) the floor: a bumped Lambertian surface
    looks the same from every one."""
    d = RNG.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.05
    if below:
        d[:, 2] *= -1
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("theta", [0, 20, 45])
@pytest.mark.parametrize("sun", [(30, 0), (30, 180), (60, 90), (75, 180)])
@pytest.mark.parametrize("correction", [False, True])
def test_a_tilted_map_under_a_sun_shades_as_a_tilted_plane(theta, sun, correction):
    # Without the correction, exactly a plane tilted to n: rho / pi E max(0, n . d); with it,
    # times Cycles' G1 at the sun's cosine to the floor.
    n, d = tilted(theta), tilted(*sun)
    scene = floor_scene(np.tile(n, (4, 4, 1)), bump_correction=correction)
    scene.add_distant_light("sun", d, E)
    got = solve(scene).surfaces[0].evaluate(UV, views(len(UV)))
    expected = ALBEDO / math.pi * E * max(0.0, float(n @ d)) * (cycles_shadowing(n[2], d[2]) if correction else 1.0)
    err = np.abs(got - expected).max() / (ALBEDO / math.pi * E).max()
    print(f"theta {theta} sun {sun} correction {correction}: max error {err:.2e} of the flat value")
    # Measured (the default settings: 7-9 angular coefficients over a cap of 1.5 x the tilt + 5
    # degrees): at most 1.3e-3 but for 45 degrees away from the sun at 30, 4.5e-3: the sun's
    # terminator (n . d = 0, where the clamped cosine has a kink the spline rounds over a span)
    # lies at 60 degrees, inside the 72.5-degree cap.
    assert err < 7e-3


def test_a_flat_map_is_the_unbumped_floor():
    # Every normal the surface's own: the 2D solve's value, rho / pi E cos(theta_sun).
    d = tilted(40, 30)
    scene = floor_scene(np.tile([0.0, 0.0, 1.0], (3, 5, 1)))
    scene.add_distant_light("sun", d, E)
    got = solve(scene).surfaces[0].evaluate(UV, views(len(UV)))
    np.testing.assert_allclose(got, np.tile(ALBEDO / math.pi * E * d[2], (len(UV), 1)), rtol=2e-3)


@pytest.mark.parametrize("theta", [15, 35, 60])
def test_a_uniform_world_gives_the_tilted_planes_sky(theta):
    # Without the correction a plane tilted by theta sees (1 + cos theta) / 2 of an upper sky of
    # radiance W (the rest of its hemisphere is below the floor, which Cycles does not light it
    # through): rho W (1 + cos theta) / 2. With it, the same integral times G1 (a quadrature here).
    n = tilted(theta, 60)
    W = 0.8
    for correction in (False, True):
        scene = floor_scene(np.tile(n, (2, 2, 1)), bump_correction=correction)
        scene.world_radiance = [W] * 3
        got = solve(scene).surfaces[0].evaluate(UV, views(len(UV)))[:, 0]
        if correction:
            mu, phi = np.meshgrid((np.arange(2000) + 0.5) / 2000, (np.arange(720) + 0.5) / 720 * 2 * np.pi, indexing="ij")
            s = np.sqrt(1 - mu**2)
            w = np.stack([s * np.cos(phi), s * np.sin(phi), mu], -1)
            integrand = np.maximum(w @ n, 0) * cycles_shadowing(n[2], mu)
            expected = ALBEDO * W / np.pi * integrand.mean() * 2 * np.pi
        else:
            expected = ALBEDO * W * (1 + n[2]) / 2
        err = np.abs(got / expected - 1).max()
        print(f"theta {theta} correction {correction}: {got.mean() / expected:.5f} of the closed form, worst {err:.2e}")
        # Measured: 1.7e-4 to 5.3e-4 without the correction; with it 1.7e-4 to 8.0e-4, and 7.3e-3 at
        # 60 degrees (G1 falls steeply towards the horizon: the cosine nodes' quadrature).
        assert err < (1.5e-2 if correction and theta == 60 else 1.5e-3)


def test_the_radiance_follows_the_map_point_by_point():
    # Normals turning along u (a washboard): at each texel centre the radiance is that normal's.
    W_TEXELS = 16
    angles = np.radians(40 * np.sin(2 * np.pi * (np.arange(W_TEXELS) + 0.5) / W_TEXELS))
    row = np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], -1)
    normals = np.tile(row, (3, 1, 1))
    d = tilted(35, 0)
    scene = floor_scene(normals, bump_correction=False)
    scene.add_distant_light("sun", d, E)
    uv = np.stack([(np.arange(W_TEXELS) + 0.5) / W_TEXELS, np.full(W_TEXELS, 0.5)], -1)
    got = solve(scene).surfaces[0].evaluate(uv, views(W_TEXELS))
    expected = ALBEDO / math.pi * np.outer(np.maximum(row @ d, 0), E)
    err = np.abs(got - expected).max() / (ALBEDO / math.pi * E).max()
    print(f"washboard: max error {err:.2e} of the flat value")
    assert err < 2.5e-3  # measured 1.0e-3


def test_the_back_side_turns_the_map_around():
    # Lit from below, a back-facing point's normal is the map's turned around (Cycles'
    # svm_node_normal_map): rho / pi E max(0, -n . d) G1.
    n, d = tilted(30, 0), -tilted(40, 180)
    scene = floor_scene(np.tile(n, (2, 2, 1)))
    scene.add_distant_light("sun", d, E)
    got = solve(scene, two_sided=True).surfaces[0].evaluate(UV, views(len(UV), below=True))
    expected = ALBEDO / math.pi * E * max(0.0, float(-n @ d)) * cycles_shadowing(n[2], -d[2])
    np.testing.assert_allclose(got, np.tile(expected, (len(UV), 1)), rtol=6e-3)


def test_other_surfaces_see_the_bumped_radiance():
    # A small ceiling tile over the floor gets the same light from the bumped floor as from a flat
    # floor whose albedo gives it the radiance the closed form gives the bumped one (both gathered
    # alike: the tile's light is their second bounce; it faces down, away from the sun).
    n, d = tilted(35, 0), tilted(20, 0)

    def ceiling(scene):
        scene.add_bilinear_patch("tile", quad([0, 0, 0.5], [0.2, 0, 0], [0, -0.2, 0]), albedo=[0.5] * 3, emission=[0, 0, 0],
                                 occluder=False)  # casting no shadow on the sunlit floor
        scene.add_distant_light("sun", d, E)
        return scene

    bumped = floor_scene(np.tile(n, (2, 2, 1)), bump_correction=False)
    flat = bsgi.Scene()
    flat.add_bilinear_patch("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), albedo=[ALBEDO * float(n @ d) / d[2]] * 3,
                            emission=[0, 0, 0])
    up = np.tile([0, 0, 1.0], (len(UV), 1))
    a = solve(ceiling(bumped), max_bounces=1).surfaces[1].evaluate(UV, up)
    b = solve(ceiling(flat), max_bounces=1).surfaces[1].evaluate(UV, up)
    print(f"tile: {a.mean() / b.mean():.6f} of the flat floor's light, worst {np.abs(a / b - 1).max():.2e}")
    np.testing.assert_allclose(a, b, rtol=1e-4)


def test_a_normal_map_on_a_glossy_surface_is_refused_by_name():
    scene = bsgi.Scene()
    with pytest.raises(ValueError, match="'bumped': a BumpedLambert reads its direction as a bumped normal"):
        scene.add_bilinear_patch("bumped", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), albedo=[0.5] * 3, emission=[0, 0, 0],
                                 bsdf=bsgi.BumpedLambert([0.5] * 3))
    scene.add_bilinear_patch("shiny floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), albedo=[0.5] * 3, emission=[0, 0, 0],
                             bsdf=bsgi.GgxReflection(0.3, 0.3, [0.9] * 3))
    with pytest.raises(ValueError, match="shiny floor.*Lambertian surfaces only"):
        scene.set_normal_texture(0, np.tile(np.float32([0, 0, 1]), (2, 2, 1)))


@pytest.mark.parametrize("bad", [[0, 0, 0], [np.nan, 0, 1]])
def test_a_texel_that_is_not_a_direction_is_refused(bad):
    normals = np.tile(np.float32([0, 0, 1]), (2, 3, 1))
    normals[1, 2] = bad
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), albedo=[0.5] * 3, emission=[0, 0, 0])
    with pytest.raises(ValueError, match=r"'floor': normal map: texel \(2, 1\) is not a direction"):
        scene.set_normal_texture(0, normals)


def test_the_bsdf_draws_match_its_density():
    # BumpedLambert's draws are cosine about n: the share above the floor is a tilted plane's
    # (1 + cos theta) / 2, the rest scatters nothing; each weight is eval cos / pdf, and their mean
    # is the directional albedo a quadrature of the closed form gives.
    b = bsgi.BumpedLambert([0.6, 0.6, 0.6])
    n = tilted(50, 20)
    count = 200000
    draws = b.sample(np.tile(n, (count, 1)), np.random.default_rng(2).uniform(size=(count, 3)))
    valid = draws["valid"]
    assert abs(valid.mean() - (1 + n[2]) / 2) < 4 * math.sqrt(0.25 / count)
    wi = draws["wi"][valid]
    assert (wi[:, 2] > 0).all()
    wo = np.tile(n, (len(wi), 1))
    np.testing.assert_allclose(draws["pdf"][valid], b.pdf(wo, wi), rtol=1e-12)
    np.testing.assert_allclose(draws["weight"][valid], b.eval(wo, wi) * wi[:, 2:] / b.pdf(wo, wi)[:, None], rtol=1e-12)
    mu, phi = np.meshgrid((np.arange(2000) + 0.5) / 2000, (np.arange(720) + 0.5) / 720 * 2 * np.pi, indexing="ij")
    s = np.sqrt(1 - mu**2)
    w = np.stack([s * np.cos(phi), s * np.sin(phi), mu], -1)
    albedo = 0.6 / np.pi * (np.maximum(w @ n, 0) * cycles_shadowing(n[2], mu)).mean() * 2 * np.pi
    mean = draws["weight"][:, 0] * valid
    assert abs(mean.mean() - albedo) < 4 * mean.std() / math.sqrt(count)


def test_a_bumped_solution_is_stored_and_a_bumped_scene_pickles(tmp_path):
    # The solution file keeps the map (SurfaceRadiance.normals) and a scene sent to Ray's workers
    # keeps it too (rebuildable replays set_normal_texture).
    import pickle

    n = np.stack([tilted(10 * k, 40 * k) for k in range(6)]).reshape(2, 3, 3)
    scene = floor_scene(n)
    scene.add_distant_light("sun", tilted(30, 10), E)
    settings = bsgi.SolverSettings()
    settings.max_bounces = 0
    solution = bsgi.solve(scene, settings)
    dirs = views(len(UV))
    want = solution.surfaces[0].evaluate(UV, dirs)
    bsgi.save_solution(tmp_path / "bumped.npz", solution.surfaces, ["floor"], settings)
    stored = bsgi.load_solution(tmp_path / "bumped.npz").surfaces[0]
    np.testing.assert_array_equal(stored.normals, solution.surfaces[0].normals)
    np.testing.assert_array_equal(stored.evaluate(UV, dirs), want)
    again = bsgi.solve(pickle.loads(pickle.dumps(scene)), settings).surfaces[0]
    np.testing.assert_array_equal(again.evaluate(UV, dirs), want)


@pytest.mark.parametrize("preset", ["draft", "preview"])
def test_the_error_estimate_of_a_bumped_floor_is_honest(preset):
    # Ridges of +-40 degrees under a sun and a grey world: the solve's estimate (its checks
    # compare the spline and the gather at the map's normal, whatever the viewer) against the
    # closed form at 4,000 random points, each at the normal the map gives there.
    from scipy.interpolate import RegularGridInterpolator

    a = np.radians(40) * np.sin(2 * np.pi * 3 * (np.arange(16) + 0.5) / 16)
    scene = floor_scene(np.tile(np.stack([np.sin(a), np.zeros_like(a), np.cos(a)], -1), (4, 1, 1)),
                        bump_correction=False)
    d = tilted(35, 0)
    scene.add_distant_light("sun", d, E)
    scene.world_radiance = [0.4] * 3
    settings = bsgi.SolverSettings.preset(preset)
    settings.max_bounces = 0
    settings.refine_to_error = 0
    solution = bsgi.solve(scene, settings)
    floor = solution.surfaces[0]
    uv = np.random.default_rng(1).uniform(0, 1, (4000, 2))
    got = floor.evaluate(uv, views(len(uv)))
    texels = floor.normals.astype(float)  # bilinear between texel centres, clamped at the edges
    centres = [(np.arange(k) + 0.5) / k for k in texels.shape[:2]]
    at = np.clip(uv[:, ::-1], [c[0] for c in centres], [c[-1] for c in centres])
    n = 2 * RegularGridInterpolator(centres, texels)(at) - 1
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    want = ALBEDO / math.pi * np.outer(np.maximum(n @ d, 0), E) + ALBEDO * 0.4 * (1 + n[:, 2:]) / 2
    measured = np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1)) / np.mean(np.sum(want**2, axis=1)))
    estimated = solution.reports[0]["estimated_error"]
    print(f"\nbumped floor at {preset}: measured {measured:.2e}, estimated {estimated:.2e}")
    # Measured: 4.7e-3 against 3.7e-3 (draft), 5e-4 against 5e-4 (preview).
    assert 0.5 < estimated / measured < 2
