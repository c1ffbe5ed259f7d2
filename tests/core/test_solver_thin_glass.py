"""Window panes (thin glass, Scene.add_surface(thin_glass=eta)): light passes straight through
with the thin sheet's Fresnel factor, against the closed form (written out here from the Fresnel
equations) and Mitsuba 3's thindielectric."""
import math

import numpy as np
import pytest

import bsgi
from reference import mitsuba_reference, scene_spec
from reference.scene_spec import quad

ALBEDO = 0.7
E = np.array([3.0, 2.0, 1.0])
ETA = 1.5


def fresnel(mu, eta):
    """Unpolarised reflectance of a smooth dielectric interface at cos(theta_i) = mu."""
    mu = np.abs(np.asarray(mu, float))
    sin_t = np.sqrt(1 - mu**2) / eta
    cos_t = np.sqrt(1 - sin_t**2)
    rs = (mu - eta * cos_t) / (mu + eta * cos_t)
    rp = (eta * mu - cos_t) / (eta * mu + cos_t)
    return 0.5 * (rs**2 + rp**2)


def sheet_transmittance(mu, eta=ETA):
    """A thin sheet: t (1 + r^2 + r^4 + ...) t = (1 - r)^2 / (1 - r^2) = (1 - r) / (1 + r)."""
    r = fresnel(mu, eta)
    return (1 - r) / (1 + r)


def test_the_closed_form_at_normal_incidence():
    # ((n - 1) / (n + 1))^2 = 0.04 per face: the pane passes 0.96 / 1.04 and reflects about 8%.
    assert sheet_transmittance(1.0) == pytest.approx(0.96 / 1.04, rel=1e-12)


def pane_caster(panes, opaque=()):
    surfaces = [bsgi.BilinearPatch(f"pane {k}", quad([0, 0, z], [100, 0, 0], [0, 100, 0])) for k, z in enumerate(panes)]
    surfaces += [bsgi.BilinearPatch(f"wall {k}", quad([0, 0, z], [100, 0, 0], [0, 100, 0])) for k, z in enumerate(opaque)]
    return bsgi.RayCaster(surfaces, panes={k: ETA for k in range(len(panes))})


@pytest.mark.parametrize("theta", [0, 30, 60, 80, 89])
def test_transmittance_is_the_thin_sheet_factor(theta):
    t = math.radians(theta)
    d = np.array([[math.sin(t), 0.0, -math.cos(t)], [-math.sin(t), 0.0, math.cos(t)]])
    o = np.array([[0.0, 0.0, 0.05], [0.0, 0.0, -0.05]])  # from either side
    got = pane_caster([0.0]).transmittance(o, d)
    assert got.shape == (2, 3)  # RGB: a clear pane's the same in each
    np.testing.assert_allclose(got, sheet_transmittance(math.cos(t)), rtol=1e-9, atol=1e-12)
    # Two panes in a row: the product; the segment stopping short of the second: one pane.
    two = pane_caster([0.0, -0.5])
    np.testing.assert_allclose(two.transmittance(o[:1], d[:1]), sheet_transmittance(math.cos(t)) ** 2, rtol=1e-9)
    tfar = np.array([0.3 / math.cos(t)])
    np.testing.assert_allclose(two.transmittance(o[:1], d[:1], tfar=tfar), sheet_transmittance(math.cos(t)), rtol=1e-9)


def test_an_opaque_surface_behind_the_pane_blocks_the_light():
    caster = pane_caster([0.0], opaque=[-0.5])
    o, d = np.array([[0.0, 0, 1]]), np.array([[0.0, 0, -1]])
    assert (caster.transmittance(o, d)[0] == 0).all()
    np.testing.assert_allclose(caster.transmittance(o, d, tfar=np.array([1.25]))[0], sheet_transmittance(1.0), rtol=1e-9)
    assert caster.occluded(o, d)[0]  # to occluded() a pane is a surface like any


H, A = 0.25, 0.3  # ceiling height, half width of the opening


def skylight(tilt_deg, pane=True, one_interface=False, **glass):
    """A 2 x 2 floor under a ceiling at height H with a 2A x 2A opening, holding a pane (or two
    faces of a thin slab), under a sun tilted towards +x. The sun also comes in under the
    ceiling's edge at x = 1 for tilts beyond 0: there the floor is lit without glass."""
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), albedo=[ALBEDO] * 3, emission=[0, 0, 0])
    w = (1 - A) / 2
    strips = [([-(1 + A) / 2, 0, H], [w, 0, 0], [0, 1, 0]), ([(1 + A) / 2, 0, H], [w, 0, 0], [0, 1, 0]),
              ([0, -(1 + A) / 2, H], [A, 0, 0], [0, w, 0]), ([0, (1 + A) / 2, H], [A, 0, 0], [0, w, 0])]
    for k, (c, u, v) in enumerate(strips):  # facing down
        scene.add_bilinear_patch(f"ceiling {k}", quad(c, v, u), albedo=[0.5] * 3, emission=[0, 0, 0])
    if pane:
        faces = [H] if not one_interface else [H, H + 0.01]
        for k, z in enumerate(faces):
            scene.add_surface(bsgi.BilinearPatch(f"pane {k}", quad([0, 0, z], [A, 0, 0], [0, A, 0])), albedo=[0] * 3,
                              emission=[0] * 3, thin_glass=ETA, one_interface=one_interface, **glass)
    t = math.radians(tilt_deg)
    scene.add_distant_light("sun", [math.sin(t), 0, math.cos(t)], E)
    return scene


def solve_direct(scene, coeffs=40):
    s = bsgi.SolverSettings()
    s.max_bounces = 0
    s.spatial_coeffs = coeffs
    return bsgi.solve(scene, s)


def floor_line(solution, x, y=0.0):
    uv = np.column_stack([(np.asarray(x) + 1) / 2, np.full(len(x), (y + 1) / 2)])
    return solution.radiance[0].evaluate(uv)


@pytest.mark.parametrize("tilt", [0, 40, 70])
def test_sun_through_a_pane_lights_the_patch_with_the_pass_through_factor(tilt):
    coeffs = 40
    sol = solve_direct(skylight(tilt), coeffs)
    t = math.radians(tilt)
    shift = H * math.tan(t)
    lit = ALBEDO / math.pi * E * math.cos(t)
    through = lit * sheet_transmittance(math.cos(t))
    span = 2 / (coeffs - 2)
    # Beyond three knot spans from the patch's edges the spline is the closed form.
    inside = np.linspace(-shift - A + 3 * span, -shift + A - 3 * span, 15)
    got = floor_line(sol, inside)
    print(f"\nsun at {tilt} deg through a pane: patch {got[:, 0].mean() / lit[0]:.5f} of the open floor, "
          f"closed form {sheet_transmittance(math.cos(t)):.5f}")
    np.testing.assert_allclose(got, np.tile(through, (len(inside), 1)), rtol=1e-6)
    # Between the patch and the light under the ceiling's edge: nothing.
    dark = np.linspace(-shift + A + 3 * span, 1 - shift - 3 * span, 9) if tilt else np.linspace(A + 3 * span, 0.95, 9)
    assert np.abs(floor_line(sol, dark)).max() < 1e-9 * lit.max()
    if tilt:  # the floor in the open sun, beside: without the glass
        open_floor = np.linspace(1 - shift + 3 * span, 0.98, 5)
        np.testing.assert_allclose(floor_line(sol, open_floor), np.tile(lit, (5, 1)), rtol=1e-6)
    # The patch's outline: where the light crosses half its level, within one knot span of the
    # window's projection.
    x = np.linspace(-1, 1, 2001)
    red = floor_line(sol, x)[:, 0]
    half = red > 0.5 * through[0]
    near = np.abs(x + shift) < A + 2 * span
    edges = x[np.nonzero(np.diff(half & near))[0]]
    print(f"  edges at {edges}, window's projection {-shift - A:.4f}, {-shift + A:.4f} (knot span {span:.4f})")
    assert len(edges) == 2
    # Measured: 0.36 of a span at most (0.019, at 70 degrees).
    assert abs(edges[0] - (-shift - A)) < 0.7 * span and abs(edges[1] - (-shift + A)) < 0.7 * span


def test_a_thin_slab_passes_each_face_once():
    # Two faces, each one interface: (1 - R)^2, within R^2 of the sheet's (1 - R) / (1 + R).
    sol = solve_direct(skylight(0, one_interface=True))
    got = floor_line(sol, np.linspace(-0.1, 0.1, 5))
    lit = ALBEDO / math.pi * E
    np.testing.assert_allclose(got, np.tile(lit * (1 - fresnel(1.0, ETA)) ** 2, (5, 1)), rtol=1e-6)


def test_the_pane_gets_no_spline_and_is_reported():
    scene = skylight(30)
    sol = solve_direct(scene, 12)
    reports = {r["name"]: r for r in sol.reports}
    assert reports["pane 0"]["representation"] == "thin glass"
    assert "straight through" in reports["pane 0"]["reason"]
    assert sol.surfaces[5] is None and scene.is_thin_glass(5) and not scene.is_thin_glass(0)
    # Its memory: its triangles for the rays only.
    s = bsgi.SolverSettings.preset("preview")
    with_pane, without = bsgi.estimate_solve_bytes(scene, s), bsgi.estimate_solve_bytes(skylight(30, pane=False), s)
    assert with_pane - without < 4096


def test_bad_panes_are_refused_by_name():
    scene = bsgi.Scene()
    patch = bsgi.BilinearPatch("Window", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]))
    with pytest.raises(ValueError, match="Window.*index of refraction"):
        scene.add_surface(patch, albedo=[0] * 3, emission=[0] * 3, thin_glass=0.5)
    with pytest.raises(ValueError, match="Window.*cannot emit"):
        scene.add_surface(patch, albedo=[0] * 3, emission=[1] * 3, thin_glass=1.5)
    with pytest.raises(ValueError, match="Window.*for thin glass"):
        scene.add_surface(patch, albedo=[0] * 3, emission=[0] * 3, one_interface=True)


TINT = np.array([0.9, 0.6, 0.3])


@pytest.mark.parametrize("one_interface", [False, True])
def test_a_tinted_pane_colours_the_sun_through_it(one_interface):
    # Cycles tints each glass event: a sheet's crossing once, a slab's two faces once each.
    t = math.radians(40)
    sol = solve_direct(skylight(40, one_interface=one_interface, transmission_tint=TINT, reflection_tint=TINT))
    x = -H * math.tan(t) + np.linspace(-0.1, 0.1, 5)
    clear = solve_direct(skylight(40, one_interface=one_interface))
    ratio = floor_line(sol, x) / floor_line(clear, x)
    print(f"\ntinted pane ({'slab' if one_interface else 'sheet'}): the patch {np.round(ratio.mean(axis=0), 6)} of the "
          "clear pane's")
    np.testing.assert_allclose(ratio, np.tile(TINT ** (2 if one_interface else 1), (5, 1)), rtol=1e-9)


def test_the_light_path_trick_passes_its_colour():
    # A Transparent BSDF's colour for shadow rays, RGB: the patch gets the sun times it, no Fresnel.
    t = math.radians(40)
    colour = np.array([0.2, 0.7, 0.4])
    sol = solve_direct(skylight(40, shadow_transmittance=colour, transmission_tint=TINT))
    x = -H * math.tan(t) + np.linspace(-0.1, 0.1, 5)
    lit = ALBEDO / math.pi * E * math.cos(t)
    np.testing.assert_allclose(floor_line(sol, x), np.tile(lit * colour, (5, 1)), rtol=1e-9)


def test_pane_colours_are_checked():
    scene = bsgi.Scene()
    patch = bsgi.BilinearPatch("Window", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]))
    with pytest.raises(ValueError, match="Window.*tints and shadow transmittance must be in"):
        scene.add_surface(patch, albedo=[0] * 3, emission=[0] * 3, thin_glass=1.5, transmission_tint=[1.2, 1, 1])
    with pytest.raises(ValueError, match="Window.*for thin glass"):
        scene.add_surface(patch, albedo=[0] * 3, emission=[0] * 3, reflection_tint=[0.5, 1, 1])


@pytest.mark.parametrize("tint", [None, TINT])
def test_the_world_seen_through_a_pane(tint):
    # A floor under a pane, both far wider than the height between them (20 km against 1 m: at 200
    # m the hemisphere rule's lowest nodes passed the pane's edge, 2.8e-4 of untinted sky): every
    # gathering ray crosses the pane (straight on to the world, T'(mu); its reflection goes back to
    # the floor, dark without bounces). Floor radiance = rho W 2 int_0^1 T'(mu) mu dmu (times a tint).
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", quad([0, 0, 0], [2e4, 0, 0], [0, 2e4, 0]), albedo=[ALBEDO] * 3, emission=[0, 0, 0])
    scene.add_surface(bsgi.BilinearPatch("pane", quad([0, 0, 1], [2e4, 0, 0], [0, 2e4, 0])), albedo=[0] * 3,
                      emission=[0] * 3, thin_glass=ETA, transmission_tint=tint)
    W = np.array([0.2, 0.4, 0.6])
    scene.world_radiance = W
    s = bsgi.SolverSettings()
    s.max_bounces = 0
    s.spatial_coeffs = 4
    sol = bsgi.solve(scene, s)
    got = sol.radiance[0].evaluate(np.array([[0.5, 0.5]]))[0]
    mu = (np.arange(200000) + 0.5) / 200000
    expected = ALBEDO * W * 2 * np.mean(sheet_transmittance(mu) * mu) * (1 if tint is None else tint)
    print(f"\nworld through a pane: {got[0] / (ALBEDO * W[0]):.5f} of the open sky, closed form "
          f"{expected[0] / (ALBEDO * W[0]):.5f}")
    # The hemisphere rule's 12 x 24 nodes on a smooth integrand (its Gauss nodes in cos(theta),
    # cosine_rule.h; the former equal-weight nodes in cos^2(theta) were 4.4e-3 off): 2e-12, the
    # closed form's own midpoint sum's order.
    print(f"off by {np.abs(got / expected - 1).max():.1e}")
    np.testing.assert_allclose(got, expected, rtol=1e-9)


@pytest.mark.slow
def test_floor_lit_through_a_pane_against_mitsuba():
    """A floor under a ceiling with a pane in its opening and an area light outside above it:
    Mitsuba 3's path tracer with its thindielectric pane (its directional emitter cannot be
    reached through a delta BSDF, hence an area light), all bounces."""
    spec = scene_spec.SceneSpec()
    spec.add("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), albedo=(ALBEDO,) * 3)
    h, a = 0.6, 0.3
    w = (1 - a) / 2
    strips = [([-(1 + a) / 2, 0, h], [w, 0, 0], [0, 1, 0]), ([(1 + a) / 2, 0, h], [w, 0, 0], [0, 1, 0]),
              ([0, -(1 + a) / 2, h], [a, 0, 0], [0, w, 0]), ([0, (1 + a) / 2, h], [a, 0, 0], [0, w, 0])]
    for k, (c, u, v) in enumerate(strips):
        spec.add(f"ceiling {k}", quad(c, v, u), albedo=(0.5,) * 3)
    spec.add("pane", quad([0, 0, h], [a, 0, 0], [0, a, 0]), receiver=False, thin_glass=ETA)
    spec.add("lamp", quad([0, 0, h + 0.4], [0, a, 0], [a, 0, 0]), emission=(4.0, 3.0, 2.0), receiver=False)
    # Points where the whole lamp is seen through the opening (|x|, |y| < 0.1), looked at from above.
    rng = np.random.default_rng(3)
    xy = rng.uniform(-0.1, 0.1, (64, 2))
    points = np.column_stack([xy, np.zeros(len(xy))])
    eye = points + np.array([0.05, -0.03, 0.3])
    mi = mitsuba_reference.load_mitsuba()
    reference = mitsuba_reference.to_mitsuba(spec)
    ref, stderr = mitsuba_reference.radiance_along(reference, eye, points, spp=1 << 15, seed=11)
    noise = np.sqrt((stderr**2).sum()) / ref.sum() * np.sqrt(3 * len(ref))  # of one point, relative
    mean_noise = np.sqrt((stderr**2).sum()) / ref.sum()
    scene = scene_spec.to_bsgi(spec)
    s = bsgi.SolverSettings()
    s.spatial_coeffs = 32
    sol = bsgi.solve(scene, s)
    ours = sol.radiance[0].evaluate((xy + 1) / 2)
    rel = ours.sum() / ref.sum() - 1
    # Without the pane's factor the floor would be 8% brighter; measured -0.53% (noise of the
    # mean 0.12%).
    print(f"\nfloor through a pane vs Mitsuba thindielectric: mean {rel:+.4f} (noise of the mean {mean_noise:.4f}, "
          f"of a point {noise:.4f}); per point max {np.abs(ours / ref - 1).max():.4f}")
    assert mean_noise < 0.005
    assert abs(rel) < 0.011
    del mi


def test_form_factor_rows_see_through_panes():
    # A reflector outside above the opening, lit through the pane by the floor's sun patch, sends
    # its light back through it: the transport rows (36)-(37) must carry it as gathering does.
    def room(reflector):
        scene = skylight(40)
        if reflector:
            scene.add_bilinear_patch("reflector", quad([-0.6, 0, 0.75], [0, 0.3, 0], [0.3, 0, 0]), albedo=[0.9] * 3,
                                     emission=[0, 0, 0])
        return scene

    def floor(scene, form_factors):
        s = bsgi.SolverSettings()
        s.spatial_coeffs = 12
        s.form_factors = form_factors
        return bsgi.solve(scene, s).radiance[0].evaluate(UV_GRID)

    rows, gathered, without = floor(room(True), True), floor(room(True), False), floor(room(False), False)
    seen = np.abs(gathered - without).max() / np.abs(without).max()
    print(f"\nreflector seen through the pane: {seen:.4f} of the floor's peak; rows vs gathering "
          f"{np.abs(rows - gathered).max() / np.abs(gathered).max():.2e}")
    assert seen > 1e-3
    np.testing.assert_allclose(rows, gathered, rtol=0, atol=1e-8 * np.abs(gathered).max())  # measured 4.1e-9


UV_GRID = np.stack(np.meshgrid(np.linspace(0.05, 0.95, 7), np.linspace(0.05, 0.95, 7)), -1).reshape(-1, 2)


@pytest.mark.parametrize("discontinuity_knots", [False, True])
def test_panes_with_adaptive_knots(discontinuity_knots):
    # Adaptive knots probe the direct light through the pane (the final gather, which would add the
    # floor's light reflected in the pane, is checked against Cycles in tests/blender). The final
    # preset's discontinuity knots find the sun's patch through the pane and the open sun under
    # the ceiling's edge: three jumps in u, which 16 coefficients cannot all take (the longest,
    # the open sun's across the floor, and one of the patch's go first), 24 can.
    s = bsgi.SolverSettings.preset("final")
    s.max_bounces = 0
    s.final_gather = False
    s.discontinuity_knots = discontinuity_knots
    if discontinuity_knots:
        s.spatial_coeffs = 24
    sol = bsgi.solve(skylight(40), s)
    if discontinuity_knots:
        assert "discontinuity knots: 3 lines in u, 2 in v" in sol.reports[0]["reason"]
    t = math.radians(40)
    x = -H * math.tan(t) + np.linspace(-0.1, 0.1, 5)
    lit = ALBEDO / math.pi * E * math.cos(t) * sheet_transmittance(math.cos(t))
    np.testing.assert_allclose(floor_line(sol, x), np.tile(lit, (5, 1)), rtol=1e-6)


def test_a_pane_reflects_with_its_reflection_tint():
    # The world through the pane of the test above, one bounce more: the floor sees itself in the
    # pane, R'(mu) times the reflection tint, so its radiance gains rho 2 int R' mu dmu tint L0.
    def floor_radiance(reflection_tint):
        scene = bsgi.Scene()
        scene.add_bilinear_patch("floor", quad([0, 0, 0], [2e4, 0, 0], [0, 2e4, 0]), albedo=[ALBEDO] * 3, emission=[0] * 3)
        scene.add_surface(bsgi.BilinearPatch("pane", quad([0, 0, 1], [2e4, 0, 0], [0, 2e4, 0])), albedo=[0] * 3,
                          emission=[0] * 3, thin_glass=ETA, reflection_tint=reflection_tint)
        scene.world_radiance = [0.5, 0.5, 0.5]
        s = bsgi.SolverSettings()
        s.max_bounces = 1
        s.tolerance = 0
        s.spatial_coeffs = 4
        return bsgi.solve(scene, s).radiance[0].evaluate(np.array([[0.5, 0.5]]))[0]

    mu = (np.arange(200000) + 0.5) / 200000
    L0 = ALBEDO * 0.5 * 2 * np.mean(sheet_transmittance(mu) * mu)
    gain = ALBEDO * 2 * np.mean((1 - sheet_transmittance(mu)) * mu)
    got = floor_radiance(TINT)
    print(f"\nfloor seeing itself in a tinted pane: {np.round(got / L0 - 1, 6)} over the direct, closed form "
          f"{np.round(gain * TINT, 6)}")
    np.testing.assert_allclose(got / L0 - 1, gain * TINT, rtol=2e-4)  # measured 7e-5
