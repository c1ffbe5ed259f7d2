"""A room lit by the sun through a window (issue 15's validation, a scene the presets were not
tuned on), against Mitsuba 3's directional emitter: the sun's patch on the floor and the shadows
of a block turned in it, and the room lit by that patch. What the discontinuity knots of a light
at infinity buy at the final preset, and where the solve stands.

    .venv/bin/python -m pytest tests/core/test_solver_sunlit_room.py -s     (prints the figures)
"""
import math

import numpy as np
import pytest

import bsgi
from reference import committed, mitsuba_reference, scene_spec
from reference.scene_spec import quad

SUN = np.array([math.cos(math.radians(35)), 0.0, math.sin(math.radians(35))])  # over the window's wall
E = np.array([4.0, 3.8, 3.4])


def sunlit_room() -> scene_spec.SceneSpec:
    """A 4 x 3 x 2.5 m room, its quads facing in; a 1.2 x 0.9 m window in its x = 2 wall (sill at
    0.9 m); a block turned 30 degrees standing in the sun's patch (its shadow edges oblique to
    the floor's parameters, the patch's own along them) and a box in the shade."""
    spec = scene_spec.SceneSpec()
    spec.add("floor", quad([0, 0, 0], [2, 0, 0], [0, 1.5, 0]), (0.7, 0.68, 0.65))
    spec.add("ceiling", quad([0, 0, 2.5], [0, 1.5, 0], [2, 0, 0]), (0.8, 0.8, 0.8))
    spec.add("back wall", quad([-2, 0, 1.25], [0, 1.5, 0], [0, 0, 1.25]), (0.65, 0.65, 0.7))
    spec.add("left wall", quad([0, -1.5, 1.25], [0, 0, 1.25], [2, 0, 0]), (0.7, 0.6, 0.5))
    spec.add("right wall", quad([0, 1.5, 1.25], [2, 0, 0], [0, 0, 1.25]), (0.5, 0.6, 0.7))
    for name, c, hu, hv in (("sill wall", [2, 0, 0.45], [0, 0, 0.45], [0, 1.5, 0]),
                            ("lintel wall", [2, 0, 2.15], [0, 0, 0.35], [0, 1.5, 0]),
                            ("window left", [2, -1.05, 1.35], [0, 0, 0.45], [0, 0.45, 0]),
                            ("window right", [2, 1.05, 1.35], [0, 0, 0.45], [0, 0.45, 0])):
        spec.add(name, quad(c, hu, hv), (0.75, 0.75, 0.75))
    for i, corners in enumerate(scene_spec.box([0.3, 0.25, 0.2], [0.3, 0.3, 0.4], math.radians(30))):
        spec.add(f"block {i}", corners, (0.6, 0.5, 0.4))
    for i, corners in enumerate(scene_spec.box([-1.2, -0.8, 0.125], [0.5, 0.4, 0.25])):
        spec.add(f"box {i}", corners, (0.5, 0.55, 0.6))
    return spec


def mitsuba_under_the_sun(spec):
    mi = mitsuba_reference.load_mitsuba()
    shapes = {f"shape{i}": s for i, s in enumerate(mitsuba_reference.to_mitsuba(spec).shapes())}
    return mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": -1},
                         "sun": {"type": "directional", "direction": list(-SUN),
                                 "irradiance": {"type": "rgb", "value": list(E)}}, **shapes})


_solved = {}
_compared = {}  # label: (spec, pairs, ours, Mitsuba's, its standard error)


def compare(preset, **overrides):
    """Relative RMSE over all pairs and per object (the block's and the box's faces together):
    (mean ratio ours / Mitsuba, relative RMSE), Mitsuba's noise taken out in quadrature."""
    label = (preset, tuple(sorted(overrides.items())))
    if label in _solved:
        return _solved[label]
    spec = sunlit_room()
    pairs, ref, stderr = committed.reference("sunlit room", spec, pairs=3000, pair_seed=5, spp=16384, seed=3,
                                             scene=mitsuba_under_the_sun, inputs={"SUN": SUN, "E": E})
    scene = scene_spec.to_bsgi(spec)
    scene.add_distant_light("sun", SUN, E)
    settings = bsgi.SolverSettings.preset(preset)
    for k, v in overrides.items():
        setattr(settings, k, v)
    sol = bsgi.solve(scene, settings)
    ours = scene_spec.solved_radiance(scene, sol, pairs)

    def error(m):
        return math.sqrt(max(((ours[m] - ref[m]) ** 2).sum() - (stderr[m] ** 2).sum(), 0) / (ref[m] ** 2).sum())

    names = np.array([spec.patches[i].name.split(" ")[0] if spec.patches[i].name.startswith(("block", "box"))
                      else spec.patches[i].name for i in pairs["patch"]])
    objects = {n: (ours[names == n].sum() / ref[names == n].sum(), error(names == n)) for n in sorted(set(names))}
    noise = math.sqrt((stderr ** 2).sum() / (ref ** 2).sum())
    total = error(np.ones(len(ref), bool))
    print(f"\nsunlit room, {preset} {overrides or ''}: {100 * total:.2f}% (Mitsuba's noise {100 * noise:.2f}%); "
          + ", ".join(f"{n} {r:.3f} ({100 * e:.1f}%)" for n, (r, e) in objects.items()))
    _solved[label] = total, objects, sol
    _compared[label] = spec, pairs, ours, ref, stderr
    return _solved[label]


@pytest.mark.slow
@pytest.mark.mitsuba_reference
def test_the_suns_lines_sharpen_the_patch_at_final():
    # Measured (5 December), final's one solve (its refinement off): 14.8% (the floor 16.5%: most
    # of it the block's oblique shadow edges, which get no knots), 16.5% without discontinuity
    # knots (the floor 18.5%).
    total, objects, sol = compare("final", refine_to_error=0)
    without, objects_without, _ = compare("final", refine_to_error=0, discontinuity_knots=False)
    assert "discontinuity knots: 4 lines in u, 4 in v" in sol.reports[0]["reason"]  # the window's and the box's
    assert total < 0.22  # measured 0.148
    assert total < without  # measured 0.148 against 0.165
    assert objects["floor"][1] < objects_without["floor"][1]  # measured 0.165 against 0.185
    # Every object's mean within 6% (measured 0.996 to 1.034, the floor; issue 15's target of 1%
    # not met).
    for name, (ratio, _) in objects.items():
        assert abs(ratio - 1) < 0.06, (name, ratio)


@pytest.mark.slow
@pytest.mark.mitsuba_reference
def test_final_refines_the_floor_under_the_patch():
    # The final preset's refinement (to 1%, within 5x the rays): the floor's estimate (its fit, the
    # blurred oblique edges) over the target, its coefficients raised 1.5x per direction (48 x 48 in
    # the final gather).
    # Measured (5 December, within 3x the rays; the same within 5x, 6 December): 6.90% against one
    # solve's 14.8%, the floor 7.8% against 16.5%, every object's mean within 0.989-1.012 of Mitsuba's.
    total, objects, sol = compare("final")
    one, objects_one, _ = compare("final", refine_to_error=0)
    floor = next(s for s in sol.refinement["surfaces"] if s["name"] == "floor")
    assert floor["refined"] >= 1, sol.refinement
    assert total < 0.14 and total < 0.6 * one, (total, one)  # measured 0.069 against 0.148
    assert objects["floor"][1] < 0.6 * objects_one["floor"][1]  # measured 0.078 against 0.165
    for name, (ratio, _) in objects.items():
        assert abs(ratio - 1) < 0.025, (name, ratio)


@pytest.mark.slow
@pytest.mark.mitsuba_reference
def test_the_reference_preset_resolves_the_patch():
    # Four times final's coefficients and twice its integration nodes: the floor 0.5% (18.5% at
    # final without the sun's lines, before the nodes beside them kept off the shadow rays'
    # lift: 11.4%), the walls lit by the patch 3.0-5.0%, means 0.989 to 1.020.
    total, objects, _ = compare("reference")
    assert total < 0.02  # measured 0.0110
    assert objects["floor"][1] < 0.01  # measured 0.005
    for name, (ratio, error) in objects.items():
        assert abs(ratio - 1) < 0.05 and error < 0.1, (name, ratio, error)


ROOM = ("back wall", "left wall", "right wall", "ceiling", "sill wall", "lintel wall", "window left", "window right")


# Measured: the walls' and ceiling's means without the support means, with them (draft 5 December;
# preview 8 December, with its adaptive knots: before them (0.868, 0.943), (0.954, 1.045)).
MEANS_MEASURED = {"draft": ((0.735, 0.834), (0.965, 1.044)), "preview": ((0.820, 0.915), (0.953, 1.006))}


@pytest.mark.slow
@pytest.mark.mitsuba_reference
@pytest.mark.parametrize("preset", ["draft", "preview"])
def test_the_coarse_floor_carries_the_patchs_light(preset):
    # At draft and preview (8 and 12 coefficients, 16 and 24 in the final gather) the patch's
    # light sampled at nodes about its edges: the coarse floor, which the final gather reads,
    # kept or lost light as the nodes fell, and the room it lights with it. Taken as means
    # weighed by each node's basis function where a sun's edge crosses its support
    # (distant_support_means), the coarse floor keeps the patch's integral. Until the means left
    # out the floor under the block (which no ray meets) and sampled each node's support on a
    # grid of its own (on one shared grid every edge moved alike in every mean), the walls at
    # draft went darker with them (0.68-0.76) and at preview 0.958-1.047. The floor itself (its
    # finals, point samples as they are seen) 0.907 at preview: at 24 and 48 coefficients 0.965
    # and 0.997 (not resolved, issue 15); 1.160 at draft.
    total, objects, _ = compare(preset)
    _, before, _ = compare(preset, distant_support_means=False)
    spread = np.sqrt(np.mean([(objects[n][0] - 1) ** 2 for n in ROOM]))
    spread_before = np.sqrt(np.mean([(before[n][0] - 1) ** 2 for n in ROOM]))
    print(f"the room's means off Mitsuba's by {100 * spread_before:.1f}% -> {100 * spread:.1f}% (RMS)")
    assert spread < 0.5 * spread_before  # measured 21.3% -> 2.6% at draft, 12.7% -> 2.5% at preview
    low, high = MEANS_MEASURED[preset][1]
    for name in ROOM:
        assert 0.93 < objects[name][0] < 1.08, (name, objects[name])  # measured low to high
    assert min(objects[n][0] for n in ROOM) == pytest.approx(low, abs=0.03)
    assert max(objects[n][0] for n in ROOM) == pytest.approx(high, abs=0.03)
    assert total < 0.45  # measured 0.345 at draft, 0.306 at preview
    if preset == "preview":
        assert 0.80 < objects["floor"][0] < 1.05  # measured 0.907


@pytest.mark.slow
@pytest.mark.mitsuba_reference
@pytest.mark.parametrize("preset", ["preview", "final"])
def test_the_error_estimate_sees_the_blurred_shadow(preset):
    # The floor's final spline blurs the turned block's shadow over two spans (its edges oblique:
    # no knots), 40% off Mitsuba's as a relative RMS over the floor's pairs. Its checks were chosen
    # by the spline's own second differences, which show no edge where it shows none: estimated
    # at 0.04 of that (and 0.56 at preview). With the sun's light (exact, a shadow ray) taken out
    # of the spline first, an edge it blurs stands out: measured 0.84 (preview 1.18); the other
    # surfaces judged 1.19-1.70 (preview 1.15-1.83). Judged as in test_error_estimate.py.
    from test_error_estimate import MIN_PAIRS, per_surface_errors
    _, _, sol = compare(preset, refine_to_error=0)  # one solve's estimate, what final's refinement acts on
    spec, pairs, ours, ref, stderr = _compared[(preset, (("refine_to_error", 0),))]
    estimated = {r["name"]: r["estimated_error"] for r in sol.reports}
    judged = []
    for i, (n, measured, noise) in per_surface_errors(spec, pairs, ours, ref, stderr).items():
        name = spec.patches[i].name
        if n >= MIN_PAIRS and noise < 0.5 * measured:
            judged.append(name)
            print(f"{preset} {name}: measured {measured:.4f}, estimated {estimated[name]:.4f}")
            assert 0.5 * measured <= estimated[name] <= 2 * measured, (name, measured, estimated[name])
    assert "floor" in judged and len(judged) >= 6  # measured 8
