"""Sun lights (addon/lights.py sun_light): a distant light of irradiance strength x colour along
the object's +Z axis; a floor beside a wall under it against the closed form and a Cycles render."""
import math

import bpy
import numpy as np
import pytest

import scenes
from bsgi_addon import export
from test_pipeline import render_floor_from_above, solve_floor_direct

ALBEDO, STRENGTH, COLOR, TILT = 0.5, 3.0, (1.0, 0.8, 0.6), 40.0
EDGE = 1 - math.tan(math.radians(TILT))  # the wall's shadow covers the floor where x > EDGE


def floor_beside_wall_under_sun(context, angle_degrees=0.53):
    grey = scenes.diffuse_material("Grey", (ALBEDO,) * 3)
    scenes.add_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], grey)
    scenes.add_quad("Wall", [(1, -1, 0), (1, 1, 0), (1, 1, 1), (1, -1, 1)], grey)
    light = bpy.data.lights.new("Sun", "SUN")
    light.energy, light.color, light.angle = STRENGTH, COLOR, math.radians(angle_degrees)
    sun = bpy.data.objects.new("Sun", light)
    sun.location = (5, 5, 5)  # where a sun is does not matter
    sun.rotation_euler = (0, math.radians(TILT), 0)  # +Z turned towards +x: shines down towards -x
    context.scene.collection.objects.link(sun)
    return sun


def lit():
    """Floor radiance in the sun: albedo / pi * irradiance * cos(tilt)."""
    return ALBEDO / math.pi * STRENGTH * np.array(COLOR) * math.cos(math.radians(TILT))


def test_sun_is_a_distant_light_along_its_z_axis(context):
    floor_beside_wall_under_sun(context)
    result = export.export_scene(context.evaluated_depsgraph_get())
    assert not result.warnings
    (sun,) = result.scene.distant_lights
    t = math.radians(TILT)
    np.testing.assert_allclose(sun["direction"], [math.sin(t), 0, math.cos(t)], atol=1e-6)
    np.testing.assert_allclose(sun["irradiance"], STRENGTH * np.array(COLOR), rtol=1e-6)
    assert sun["angle"] == pytest.approx(math.radians(0.53), rel=1e-5)
    assert sun["name"] == "Sun"


def test_floor_in_and_out_of_the_suns_shadow_matches_the_closed_form(context):
    floor_beside_wall_under_sun(context)
    spline, _ = solve_floor_direct(context)
    x = np.array([-0.9, -0.6, -0.4, 0.75, 0.9])
    got = spline.evaluate(np.column_stack([(x + 1) / 2, np.full_like(x, 0.3)]))
    print("\nfloor under the sun / closed form:", np.round(got[:, 0] / lit()[0], 4))
    np.testing.assert_allclose(got[x < 0], np.tile(lit(), (3, 1)), rtol=1e-4)  # exact: 1.0000
    assert np.abs(got[x > 0.5]).max() < 0.01 * lit().max()


@pytest.mark.slow
def test_sun_convention_is_cycles(context, tmp_path):
    # Cycles' own render (direct light only) from straight above through an orthographic
    # camera: the floor in the sun against the closed form the solver is checked against above.
    floor_beside_wall_under_sun(context)
    image, points = render_floor_from_above(context, tmp_path / "top.exr", samples=64)
    image, x = image.reshape(-1, 3), points[:, 0]
    ratio = image[x < EDGE - 0.1] / lit()
    shade = image[x > EDGE + 0.1].mean(axis=0) / lit()
    print(f"\nCycles / closed form in the sun: median {np.median(ratio):.4f}; in the shadow {np.round(shade, 4)}")
    # Measured 1.0000 and 0.0003: bounded by Cycles' noise at 64 samples rather.
    assert abs(np.median(ratio) - 1) < 0.005
    assert shade.max() < 0.001


def test_study_refuses_scenes_its_reference_cannot_light(context):
    # bench/study compares with a Mitsuba scene of emissive surfaces and area lights only.
    import importlib.util
    import pathlib

    path = pathlib.Path(__file__).resolve().parents[2] / "bench" / "study" / "solve_blend.py"
    spec = importlib.util.spec_from_file_location("study_solve_blend", path)
    solve_blend = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(solve_blend)
    floor_beside_wall_under_sun(context)
    with pytest.raises(SystemExit, match="sun light 'Sun'"):
        solve_blend.refuse_light_the_reference_lacks(context, export.export_scene(context.evaluated_depsgraph_get()))
    bpy.data.objects.remove(bpy.data.objects["Sun"])
    solve_blend.refuse_light_the_reference_lacks(context, export.export_scene(context.evaluated_depsgraph_get()))


def test_sun_scaled_to_nothing_is_skipped_by_name(context):
    sun = floor_beside_wall_under_sun(context)
    sun.scale = (1, 1, 0)
    result = export.export_scene(context.evaluated_depsgraph_get())
    assert any("light 'Sun': scaled to zero" in w for w in result.warnings)
    assert result.scene.distant_lights == []
