"""World light (Scene.world_radiance): a constant radiance arriving along every direction no
occluder blocks, against closed forms and Mitsuba 3's constant environment emitter."""
import numpy as np
import pytest

import bsgi
from closed_forms import polygon_irradiance
from reference import committed, mitsuba_reference, scene_spec
from reference.scene_spec import quad

WORLD = np.array([0.6, 0.8, 1.0])
ALBEDO = 0.7


def settings(**kw):
    s = bsgi.SolverSettings()
    for k, v in kw.items():
        setattr(s, k, v)
    return s


def floor_scene(*extra):
    """A 2 x 2 floor (normal +z) under the world, with more patches (name, corners) above it."""
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), albedo=[ALBEDO] * 3, emission=[0, 0, 0])
    for name, corners in extra:
        scene.add_bilinear_patch(name, corners, albedo=[0.5] * 3, emission=[0, 0, 0])
    scene.world_radiance = WORLD
    return scene


def floor_points(uv):
    return np.column_stack([2 * uv[:, 0] - 1, 2 * uv[:, 1] - 1, np.zeros(len(uv))])


UV = np.vstack([np.random.default_rng(3).uniform(0, 1, (100, 2)), [[0, 0], [1, 1], [0.5, 0.5], [0, 1], [1, 0]]])


@pytest.mark.parametrize("preset", ["draft", "preview", "final"])
def test_open_floor_reflects_albedo_times_world(preset):
    # Every ray escapes: (rho / pi) * pi * L_world exactly, whatever the node count, up to the
    # rounding of the final gather's coefficients to float32 (the bake's precision): at most 2^-24
    # relative (measured 0.52 * 2^-24 at every preset).
    sol = bsgi.solve(floor_scene(), bsgi.SolverSettings.preset(preset))
    got = sol.radiance[0].evaluate(UV)
    assert np.allclose(got, ALBEDO * WORLD, rtol=2.0**-24, atol=0)


def test_floor_under_a_ceiling_matches_the_unblocked_solid_angle():
    # Without bounces, the floor sees the world except through the ceiling: rho / pi times the
    # irradiance of the whole sky minus that of the sky behind the ceiling (Lambert's polygon
    # formula, independent of the solver's hemisphere nodes).
    ceiling = quad([0.2, 0.1, 0.8], [0, 0.6, 0], [0.7, 0, 0])  # 1.4 x 1.2 at z = 0.8, facing down
    want = np.array([ALBEDO / np.pi * (np.pi - polygon_irradiance(p, [0, 0, 1], list(ceiling))) * WORLD
                     for p in floor_points(UV)])
    errors = {}
    for nodes in (8, 16, 32):
        s = settings(max_bounces=0, hemisphere_nodes_theta=nodes, hemisphere_nodes_phi=2 * nodes)
        got = bsgi.solve(floor_scene(("ceiling", ceiling)), s).radiance[0].evaluate(UV)
        errors[nodes] = np.abs(got / want - 1).max()
    print("\nfloor under a ceiling, max relative error by theta nodes:", {k: f"{v:.4f}" for k, v in errors.items()})
    # The hemisphere rule (cosine-weighted nodes) cuts the ceiling's edge: about first order in
    # the node spacing; the spline is fitted at the Schoenberg nodes, so what remains at 32 is
    # mostly the spatial fit of the shadow's gradient.
    assert errors[8] < 0.066  # measured 0.033
    assert errors[32] < 0.018  # measured 0.009
    assert errors[32] < errors[8]


def test_no_world_light_reaches_inside_a_closed_box():
    scene = bsgi.Scene()
    for i, face in enumerate(scene_spec.box([0, 0, 0], [1, 1, 1])):
        # Inward-facing: the corners reversed.
        scene.add_bilinear_patch(f"wall {i}", face[::-1], albedo=[0.9] * 3, emission=[0, 0, 0])
    scene.world_radiance = [5, 5, 5]
    sol = bsgi.solve(scene, settings(max_bounces=3))
    for i in range(6):
        assert np.abs(sol.radiance[i].evaluate(UV)).max() == 0


def test_world_alone_is_enough_light_and_bad_world_is_refused():
    scene = floor_scene()
    bsgi.solve(scene, settings(max_bounces=0))  # no emitter, but the world lights it
    scene.world_radiance = [0, 0, 0]
    with pytest.raises(ValueError, match="no emitter"):
        bsgi.solve(scene, settings(max_bounces=0))
    for bad in ([-1, 0, 0], [np.nan, 0, 0], [np.inf, 1, 1]):
        with pytest.raises(ValueError, match="world"):
            scene.world_radiance = bad
    with pytest.raises(ValueError, match="3 values"):
        scene.world_radiance = [1, 1]


def with_world(scene, radiance):
    """A loaded Mitsuba scene's shapes (and their area emitters) under a constant environment."""
    mi = mitsuba_reference.load_mitsuba()
    d = {"type": "scene", "integrator": {"type": "path", "max_depth": -1},
         "world": {"type": "constant", "radiance": {"type": "rgb", "value": list(radiance)}}}
    for i, shape in enumerate(scene.shapes()):
        d[f"shape{i}"] = shape
    return mi.load_dict(d)


def open_box() -> scene_spec.SceneSpec:
    """The Cornell box without its ceiling, front or lamp, lit only by the world: light comes in
    from above and bounces between the walls and the boxes; one wall is rough metal."""
    spec = scene_spec.cornell_box()
    # The boxes' bottoms lie in the floor's plane: seen from under the floor, where the world
    # shines too, the two would be told apart by rounding only.
    spec.patches = [p for p in spec.patches if p.name not in ("ceiling", "lamp", "tall box 4", "short box 4")]
    back = next(p for p in spec.patches if p.name == "back")
    back.ggx_alpha, back.albedo = 0.3, (0.0, 0.0, 0.0)
    return spec


def open_box_errors(spec, scene, pairs, ref, stderr):
    """The open box's scene solved at the preview preset against a reference along `pairs`:
    (the reference's relative noise, NRMSE, bias, NRMSE on the metal back wall, the solution)."""
    noise = np.sqrt((stderr ** 2).sum() / (ref ** 2).sum())
    sol = bsgi.solve(scene, bsgi.SolverSettings.preset("preview"))
    ours = scene_spec.solved_radiance(scene, sol, pairs)
    err = np.sqrt(((ours - ref) ** 2).sum() / (ref ** 2).sum())
    bias = (ours - ref).sum() / ref.sum()
    metal = np.array([spec.patches[i].name == "back" for i in pairs["patch"]])
    err_metal = np.sqrt(((ours - ref)[metal] ** 2).sum() / (ref[metal] ** 2).sum())
    return noise, err, bias, err_metal, sol


def mitsuba_under_the_world(spec):
    return with_world(mitsuba_reference.to_mitsuba(spec), WORLD)


@pytest.mark.slow
@pytest.mark.mitsuba_reference
def test_open_box_under_the_world_against_mitsuba():
    spec = open_box()
    pairs, ref, stderr = committed.reference("open box under the world", spec, pairs=1500, pair_seed=5, spp=16384,
                                             seed=3, scene=mitsuba_under_the_world,
                                             inputs={"with_world": with_world, "world": WORLD})
    scene = scene_spec.to_bsgi(spec)
    scene.world_radiance = WORLD
    noise, err, bias, err_metal, sol = open_box_errors(spec, scene, pairs, ref, stderr)
    print(f"\nopen box under the world vs Mitsuba 3 (noise {noise:.4f}): NRMSE {err:.4f}, bias {bias:+.4f}, "
          f"metal wall {err_metal:.4f}, {sol.stats['bounces']} bounces")
    assert noise < 0.01
    assert err < 0.06  # measured 0.038
    assert abs(bias) < 0.022  # measured -0.011
    assert err_metal < 0.042  # measured 0.021
