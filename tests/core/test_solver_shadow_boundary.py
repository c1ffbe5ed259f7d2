"""A sharp shadow against the closed form (issue #15, discontinuities): a square Lambertian light
facing down, a black opaque square parallel below it (it blocks rays from both sides and reflects
nothing, so the floor's radiance is its direct light alone) and a floor, all aligned with the
floor's parameter lines. The exact irradiance is Lambert's formula over the part of the light the
occluder leaves visible (closed_forms.shadowed_square_irradiance, polygon clipping independent of
the solver). Errors are measured separately in the umbra (light fully hidden), the penumbra and
the lit region; the umbra's exact radiance is 0, so there (and in the penumbra, where it goes to
0 at the umbra's edge) the error is taken relative to the radiance the point would have unshadowed."""
import numpy as np
import pytest

import bsgi
from closed_forms import polygon_irradiance, shadowed_square_irradiance

ALBEDO = 0.6
HALF_FLOOR, LIGHT_HEIGHT, LIGHT_HALF, OCCLUDER_HEIGHT, OCCLUDER_HALF = 1.5, 2.0, 0.25, 1.0, 0.3
# From the geometry: the occluder hides the whole light for |x| <= 0.35 (both axes), none of it
# for |x| >= 0.85 (either axis).
UMBRA, LIT = 0.35, 0.85


def rect(center, half_u, half_v):
    c, a, b = (np.asarray(x, float) for x in (center, half_u, half_v))
    return np.array([c - a - b, c + a - b, c + a + b, c - a + b])


FLOOR = rect([0, 0, 0], [HALF_FLOOR, 0, 0], [0, HALF_FLOOR, 0])
LIGHT = rect([0, 0, LIGHT_HEIGHT], [0, LIGHT_HALF, 0], [LIGHT_HALF, 0, 0])  # normal -z
OCCLUDER = rect([0, 0, OCCLUDER_HEIGHT], [OCCLUDER_HALF, 0, 0], [0, OCCLUDER_HALF, 0])


def exact(x, y):
    square = (-LIGHT_HALF, LIGHT_HALF, -LIGHT_HALF, LIGHT_HALF)
    hole = (-OCCLUDER_HALF, OCCLUDER_HALF, -OCCLUDER_HALF, OCCLUDER_HALF)
    return ALBEDO / np.pi * shadowed_square_irradiance(x, y, square, LIGHT_HEIGHT, hole, OCCLUDER_HEIGHT)


def unshadowed(x, y):
    return ALBEDO / np.pi * polygon_irradiance([x, y, 0], [0, 0, 1], list(LIGHT))


def solve(**overrides):
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", FLOOR, albedo=[ALBEDO] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("lamp", LIGHT, albedo=[0] * 3, emission=[1] * 3, receiver=False, occluder=False)
    scene.add_bilinear_patch("occluder", OCCLUDER, albedo=[0] * 3, emission=[0] * 3)
    s = bsgi.SolverSettings.preset("final")
    s.max_bounces = 0
    for k, v in overrides.items():
        setattr(s, k, v)
    return bsgi.solve(scene, s)


def floor_grid(count):
    """(u, v) on a count x count grid just inside the floor's parameter square, and their (x, y)."""
    g = np.linspace(0.005, 0.995, count)
    U, V = np.meshgrid(g, g, indexing="ij")
    uv = np.stack([U.ravel(), V.ravel()], 1)
    x, y = (2 * uv - 1).T * HALF_FLOOR
    return uv, x, y


@pytest.fixture(scope="module")
def reference():
    uv, x, y = floor_grid(61)
    ref = {"uv": uv, "exact": np.array([exact(a, b) for a, b in zip(x, y)]),
           "free": np.array([unshadowed(a, b) for a, b in zip(x, y)])}
    ax, ay = np.abs(x), np.abs(y)
    ref["umbra"] = (ax <= UMBRA) & (ay <= UMBRA)
    ref["lit"] = (ax >= LIT) | (ay >= LIT)
    ref["penumbra"] = ~ref["umbra"] & ~ref["lit"]
    # A line across the penumbra at y = 0, for its 10-90% width.
    ref["line_x"] = np.linspace(0.2, 1.0, 801)
    ref["line_exact"] = np.array([exact(a, 0) for a in ref["line_x"]])
    return ref


def penumbra_width(x, f, lit):
    """Distance from where f first reaches 10% of the lit level to where it first reaches 90%."""
    return x[np.argmax(f >= 0.9 * lit)] - x[np.argmax(f >= 0.1 * lit)]


def errors(solution, ref):
    got = solution.radiance[0].evaluate(ref["uv"])[:, 0]
    e = np.abs(got - ref["exact"])
    line_uv = np.stack([(ref["line_x"] / HALF_FLOOR + 1) / 2, np.full_like(ref["line_x"], 0.5)], 1)
    lit_level = exact(LIT, 0)
    width = penumbra_width(ref["line_x"], solution.radiance[0].evaluate(line_uv)[:, 0], lit_level)
    exact_width = penumbra_width(ref["line_x"], ref["line_exact"], lit_level)
    return {"umbra": np.mean(e[ref["umbra"]] / ref["free"][ref["umbra"]]),
            "penumbra": np.mean(e[ref["penumbra"]] / ref["free"][ref["penumbra"]]),
            "lit": np.mean(e[ref["lit"]] / ref["exact"][ref["lit"]]),
            "width": width / exact_width - 1, "exact_width": exact_width}


def test_the_closed_form_matches_a_brute_force_integral_over_the_light():
    # Midpoint rule over the light with each point's segment to (x, y, 0) tested against the
    # occluder square: no clipping involved.
    n = 600
    s = (np.arange(n) + 0.5) / n * 2 * LIGHT_HALF - LIGHT_HALF
    lx, ly = np.meshgrid(s, s, indexing="ij")
    for x, y in [(0.0, 0.0), (0.5, 0.0), (0.6, 0.7), (0.84, 0.2), (1.2, -0.3)]:
        t = OCCLUDER_HEIGHT / LIGHT_HEIGHT  # where the segment crosses the occluder's plane
        cx, cy = x + t * (lx - x), y + t * (ly - y)
        visible = (np.abs(cx) > OCCLUDER_HALF) | (np.abs(cy) > OCCLUDER_HALF)
        d2 = (lx - x) ** 2 + (ly - y) ** 2 + LIGHT_HEIGHT ** 2
        brute = np.sum(visible * LIGHT_HEIGHT ** 2 / d2 ** 2) * (2 * LIGHT_HALF / n) ** 2 * ALBEDO / np.pi
        assert exact(x, y) == pytest.approx(brute, rel=2e-3, abs=1e-7)


def test_shadow_splitting_resolves_umbra_penumbra_and_lit_region(reference):
    # The final preset with discontinuity knots (on the umbra's and penumbra's edges, adaptive
    # knots between them) and the emitter's cells split while partly shadowed, down to depth 5.
    sol = solve(discontinuity_knots=True, emitter_shadow_depth=5)
    err = errors(sol, reference)
    print(f"\nfinal preset, discontinuity knots, shadow depth 5: umbra {err['umbra']:.2e}, penumbra {err['penumbra']:.2e}, lit {err['lit']:.2e} "
          f"(mean error relative to the unshadowed / exact radiance), 10-90% penumbra width "
          f"{err['width']:+.3f} against the exact {err['exact_width']:.3f}; {sol.stats['rays']} rays")
    print(sol.reports[0]["reason"])
    assert "discontinuity knots: 4 lines in u, 4 in v" in sol.reports[0]["reason"]
    # Issue #15's bounds: each region within 1%, the width within 10%.
    assert err["umbra"] <= 0.01 and err["penumbra"] <= 0.01 and err["lit"] <= 0.01 and abs(err["width"]) <= 0.1
    # Within about 2x of what is measured (umbra 0: knots of multiplicity 2 on its edges).
    assert err["umbra"] <= 1e-6
    assert err["penumbra"] <= 6e-3  # measured 2.9e-3 (1.4e-3 with a quarter of the knots uniform, not half)
    assert err["lit"] <= 2e-3  # measured 8e-4
    assert abs(err["width"]) <= 0.03  # measured +0.016 (+0.003 with a quarter uniform)


def test_knots_alone_leave_the_penumbra_a_staircase(reference):
    # Without the shadow splitting the knots make the umbra exact, but the penumbra's node values
    # come from 3 x 3 shadow rays to the light: a staircase that no knot placement smooths.
    # Issue #15's 1% is not reached this way.
    sol = solve(discontinuity_knots=True, emitter_shadow_depth=0)  # the preset splits to depth 5
    err = errors(sol, reference)
    # Kinks (the occluder's edges parallel to the light's): double knots at the umbra's and the
    # penumbra's edges, x = +-0.35 and +-0.85, in u and in v.
    for axis in sol.radiance[0].axes:
        for x in (-LIT, -UMBRA, UMBRA, LIT):
            assert np.sum(np.abs(np.array(axis.knots) - (x / HALF_FLOOR + 1) / 2) < 1e-9) == 2
    print(f"\nfinal preset, discontinuity knots: umbra {err['umbra']:.2e}, penumbra {err['penumbra']:.2e}, lit {err['lit']:.2e}, "
          f"width {err['width']:+.3f}")
    assert err["umbra"] <= 1e-6
    assert err["penumbra"] <= 0.2  # measured 0.104
    assert err["lit"] <= 0.004  # measured 0.0020
    assert abs(err["width"]) <= 0.75  # measured -0.375


@pytest.mark.slow
def test_what_each_step_buys(reference):
    """Uniform, adaptive and discontinuity knots, with and without the shadow splitting of the
    emitter's cells: the knots on the umbra's edges make the umbra exact; the penumbra needs the
    visible part of the light resolved (3 x 3 shadow rays per cell are a staircase of 3 steps)."""
    table = {}
    for depth in (0, 5):
        for adaptive in (False, True):
            for disc in (False, True):
                sol = solve(adaptive_knots=adaptive, discontinuity_knots=disc, emitter_shadow_depth=depth)
                err = errors(sol, reference)
                table[depth, adaptive, disc] = err
                print(f"\nshadow depth {depth}, adaptive {adaptive:d}, discontinuity {disc:d}: umbra {err['umbra']:.4f} "
                      f"penumbra {err['penumbra']:.4f} lit {err['lit']:.4f} width {err['width']:+.3f}, "
                      f"{sol.stats['rays']} rays", end="")
    for depth in (0, 5):
        for adaptive in (False, True):
            # measured umbra 1.9e-3 .. 1.2e-2 without, 0 with the discontinuity knots
            assert table[depth, adaptive, False]["umbra"] >= 1e-3
            assert table[depth, adaptive, True]["umbra"] <= 1e-6
    for adaptive in (False, True):
        for disc in (False, True):
            # measured penumbra 6.8e-2 .. 9.6e-2 at depth 0, 1.4e-3 .. 1.0e-2 at depth 5; the
            # width -21% .. -35% at depth 0, within 2.1% at depth 5
            assert table[0, adaptive, disc]["penumbra"] >= 3 * table[5, adaptive, disc]["penumbra"]
            assert abs(table[5, adaptive, disc]["width"]) <= 0.05 < abs(table[0, adaptive, disc]["width"])


@pytest.mark.slow
def test_contact_lines_of_a_box_on_the_floor_against_mitsuba():
    """A black box resting on the floor, aligned with its parameter lines, under a large square
    light: its contact lines (a jump: knots of multiplicity 3) and the kinks of its shadow's edges
    are parameter lines. Floor radiance at points within 25 cm outside the box against Mitsuba 3's
    path tracer with direct light only (max_depth 2; the box and lamp reflect nothing)."""
    from reference import mitsuba_reference, scene_spec

    spec = scene_spec.SceneSpec()
    spec.add("floor", scene_spec.quad([0, 0, 0], [1.5, 0, 0], [0, 1.5, 0]), (0.6, 0.6, 0.6))
    for i, face in enumerate(scene_spec.box([0.1, -0.05, 0.25], [0.6, 0.5, 0.5])):  # footprint [-0.2, 0.4] x [-0.3, 0.2]
        spec.add(f"box {i}", face, (0, 0, 0))
    spec.add("lamp", scene_spec.quad([0, 0, 2.0], [0, 0.6, 0], [0.6, 0, 0]), emission=(1.0,) * 3, receiver=False)
    rng = np.random.default_rng(3)
    p = rng.uniform([-0.45, -0.55], [0.65, 0.45], (4000, 2))
    gap = np.maximum.reduce([-0.2 - p[:, 0], p[:, 0] - 0.4, -0.3 - p[:, 1], p[:, 1] - 0.2])  # distance outside, in max norm
    keep = (gap > 0) & (gap <= 0.25)
    p, gap = p[keep][:600], gap[keep][:600]
    point = np.c_[p, np.zeros(len(p))]
    ref, stderr = mitsuba_reference.radiance_along(mitsuba_reference.to_mitsuba(spec, max_depth=2), point + [0, 0, 0.05],
                                                   point, 16384, seed=1)
    noise = np.sqrt((stderr ** 2).sum() / (ref ** 2).sum())
    near = gap < 0.05
    uv = (p + 1.5) / 3

    def nrmse(ours, mask):
        return np.sqrt(((ours[mask] - ref[mask]) ** 2).sum() / (ref[mask] ** 2).sum())

    err = {}
    for label, overrides in {"no contact nodes, no shadow splitting": dict(hidden_nodes_to_contact=False, emitter_shadow_depth=0,
                                                                         discontinuity_knots=False),
                             "final preset without discontinuity knots": dict(discontinuity_knots=False),
                             "final preset": {}}.items():
        settings = bsgi.SolverSettings.preset("final")
        settings.max_bounces = 0
        for k, v in overrides.items():
            setattr(settings, k, v)
        floor = bsgi.solve(scene_spec.to_bsgi(spec), settings).radiance[0]
        if settings.discontinuity_knots:  # the contact lines x = -0.2, 0.4 (y = -0.3, 0.2): a jump, triple knots
            for axis, lines in zip(floor.axes, ((-0.2, 0.4), (-0.3, 0.2))):
                for x in lines:
                    assert np.sum(np.abs(np.array(axis.knots) - (x / 1.5 + 1) / 2) < 1e-9) == 3
        ours = floor.evaluate(uv)
        err[label] = nrmse(ours, np.ones(len(ref), bool)), nrmse(ours, near)
        print(f"\n{label}: NRMSE {err[label][0]:.4f}, within 5 cm of the box {err[label][1]:.4f} (reference noise {noise:.4f})", end="")
    assert noise < 0.01  # measured 0.005
    print()
    # measured (3 December, sharpened fit): without the contact-line nodes, the shadow splitting and
    # the discontinuity knots 0.0763 (0.184 within 5 cm); the final preset without the knots (as it
    # was until 3 December) 0.0109 (0.0307); the final preset, with them, 0.0093 (0.0156). (Before
    # the sharpened fit: 0.073 (0.191), 0.0126 (0.0408), 0.0152 (0.0177).)
    without = err["final preset without discontinuity knots"]
    assert without[0] <= 0.022 and without[1] <= 0.061
    assert err["no contact nodes, no shadow splitting"][0] >= 3 * err["final preset"][0]
    knots = err["final preset"]
    assert knots[0] <= 0.019 and knots[1] <= 0.031
    assert knots[1] <= 0.75 * without[1]  # measured 0.51: sharper at the contact lines


@pytest.mark.parametrize("height, multiplicities", [(0.001, [3]), (0.01, [3]), (0.3, [2, 2])])
def test_an_edge_just_off_the_floor_casts_a_jump_at_the_splines_scale(height, multiplicities):
    """A plank leaning up from the floor, its lower edge `height` above it along the floor's v
    lines, under a square light: within a few millimetres the edge's penumbra (the light's width
    times height / distance) is far narrower than a knot span and the discontinuity knots put a
    jump there (a triple knot, as at a contact line: a board leaning on a wall leaked the wall's
    light into the wedge behind it through the kink of a double knot); 30 cm up its penumbra's two
    edges get a double knot each."""
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], albedo=[0.5] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("lamp", [[-0.25, -0.25, 2], [-0.25, 0.25, 2], [0.25, 0.25, 2], [0.25, -0.25, 2]],
                             albedo=[0] * 3, emission=[10] * 3, receiver=False, occluder=False)
    scene.add_bilinear_patch("plank", [[0.5, -1, height], [0.5, 1, height], [1.0, 1, 0.9], [1.0, -1, 0.9]],
                             albedo=[0] * 3, emission=[0] * 3, receiver=False)
    settings = bsgi.SolverSettings.preset("final")
    settings.max_bounces, settings.final_gather, settings.estimate_error, settings.refine_to_error = 0, False, False, 0
    knots = np.array(bsgi.solve(scene, settings).radiance[0].axes[0].knots)
    # Inner knots within 5 cm of the edge's shadow (x = 0.5 to 0.6: u = 0.625 to 0.65), by value.
    near = knots[(knots > 0.62) & (knots < 0.665)]
    values, counts = np.unique(np.round(near, 6), return_counts=True)
    assert sorted(c for c in counts.tolist() if c > 1) == multiplicities, (height, knots)  # (single knots: spread)
