"""The add-on's export -> solve -> bake at the extremes (issue 8, point 4): tiny, huge and far-off
scenes, a lamp 1e6 times brighter than another, degree 0 with one coefficient and degree 3 with
many, coincident faces, an object scaled flat. The baked float images are checked against
Lambert's closed form for a square lamp and against the unit-size scene; tests/core/test_stability.py
covers the core alone."""
import math

import bpy
import numpy as np
import pytest

import scenes
from bsgi_addon import bake, pipeline
from bsgi_addon.errors import ExportError
from core.closed_forms import polygon_irradiance  # tests/core, on the path as a namespace package

GREY = 0.5


def lamp_square(location, size):
    """Corners of a square area light (it faces -z) of side `size` at `location`."""
    x, y, z = location
    h = size / 2
    return [[x - h, y - h, z], [x + h, y - h, z], [x + h, y + h, z], [x - h, y + h, z]]


def lambert(point, location, size, energy):
    """Radiance of the grey floor at `point` under a square lamp of Cycles' radiance P / (pi A)."""
    radiance = energy / (math.pi * size * size)
    return GREY / math.pi * polygon_irradiance(point, [0, 0, 1], lamp_square(location, size), radiance)


def floor_scene(scale=1.0, offset=(0, 0, 0), name="Floor", lamp="Lamp", energy=50.0, blocker=False):
    """A 2 x 2 grey floor under a 1 x 1 lamp at height 1 (with `blocker`, a 0.6 x 0.6 quad at
    height 0.5 between them), all scaled by `scale` about the origin, then moved by `offset`; the
    lamp's power scales with its area, so its radiance stays."""
    o = np.asarray(offset, float)
    grey = scenes.diffuse_material(f"{name} grey", (GREY,) * 3)
    corners = o + scale * np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], float)
    floor = scenes.add_quad(name, corners, grey)
    if blocker:
        scenes.add_quad("Blocker", o + scale * np.array([(-0.3, -0.3, 0.5), (0.3, -0.3, 0.5), (0.3, 0.3, 0.5), (-0.3, 0.3, 0.5)]), grey)
    scenes.add_area_light(lamp, location=tuple(o + scale * np.array([0, 0, 1.0])), size=scale, energy=energy * scale * scale)
    return floor


def custom(context, coeffs, degree=2, bounces=0):
    s = context.scene.bsgi
    s.preset = "CUSTOM"
    s.spatial_coeffs = coeffs
    s.spatial_degree = degree
    s.max_bounces = bounces


def baked(context):
    """Solve and bake the scene; (job, solution) and each object's image as (height, width, 3)."""
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    images = {}
    for exported in job.export.objects:
        image = bpy.data.images[f"BSGI {exported.name}"]
        width, height = image.size  # a surface lit on both sides: its back side's tiles above
        pixels = np.array(image.pixels[:], np.float32).reshape(height, width, 4)[..., :3]
        assert np.isfinite(pixels).all()
        images[exported.name] = pixels
    return job, solution, images


def tile(pixels, solution, job, name):
    """The first face's tile of an object's image, and its texels' (u, v) (corners at 0 and 1)."""
    exported = next(e for e in job.export.objects if e.name == name)
    t = bake.tile_size(solution.radiance[exported.patches[0][1]])
    g = np.arange(t) / (t - 1)
    return pixels[:t, :t], np.stack(np.meshgrid(g, g), -1)  # image rows are v, columns u


# Measured 1.4e-7, 1.1e-7 and 4.1e-3.
@pytest.mark.parametrize("scale, offset, tolerance", [(1e-3, (0, 0, 0), 3e-7), (1e4, (0, 0, 0), 3e-7),
                                                      (1e-3, (100, 50, -30), 8.2e-3)])
def test_tiny_huge_and_far_off_scenes_bake_the_unit_scenes_image(context, scale, offset, tolerance):
    # A floor, a blocker casting a shadow on it, one bounce between them. Blender stores
    # vertices in float: 100 units from the origin they move by up to 8e-6, 0.8% of this
    # scene's size, which bounds the far-off case (before the core centred Embree's
    # coordinates, the ray offsets there were as large as the scene and the floor came out black).
    custom(context, 8, bounces=1)
    floor_scene(blocker=True)
    _, _, unit = baked(context)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    context = bpy.context
    custom(context, 8, bounces=1)
    floor_scene(scale, offset, blocker=True)
    _, _, images = baked(context)
    diff = max(np.abs(images[k] - unit[k]).max() / unit[k].max() for k in ("Floor", "Blocker"))
    print(f"\nbaked floor and blocker at scale {scale:g}, {offset} from the origin: max difference from the unit scene {diff:.1e} of the peak")
    assert diff <= tolerance


def test_a_lamp_1e6_times_brighter_keeps_the_dim_floors_relative_accuracy(context):
    # Floor A under a lamp of 5e7 W, floor B beside it, above A's lamp (which faces down) under
    # a 50 W lamp: B sees only its own lamp. Both bake to Lambert's closed form with the same
    # relative accuracy (Schoenberg's bias under the peak, 12 coefficients), in float32 images,
    # and B is what it is alone.
    custom(context, 12, bounces=2)
    floor_scene(name="Bright", lamp="Bright lamp", energy=5e7)
    floor_scene(offset=(4, 0, 1.5), name="Dim", lamp="Dim lamp", energy=50.0)
    job, solution, images = baked(context)
    errors = {}
    for name, offset, energy in (("Bright", (0, 0, 0), 5e7), ("Dim", (4, 0, 1.5), 50.0)):
        pixels, uv = tile(images[name], solution, job, name)
        centre = pixels[len(pixels) // 2, len(pixels) // 2, 0]
        middle = uv[len(pixels) // 2, len(pixels) // 2]
        point = np.asarray(offset, float) + [2 * middle[0] - 1, 2 * middle[1] - 1, 0]
        errors[name] = abs(centre / lambert(point, np.asarray(offset) + [0, 0, 1], 1.0, energy) - 1)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    custom(bpy.context, 12, bounces=2)
    floor_scene(offset=(4, 0, 1.5), name="Dim", lamp="Dim lamp", energy=50.0)
    _, _, alone = baked(bpy.context)
    same = np.abs(images["Dim"] - alone["Dim"]).max() / alone["Dim"].max()
    print(f"\nlamps 1e6 apart: centre texel against Lambert's closed form, bright floor {errors['Bright']:.1e}, "
          f"dim floor {errors['Dim']:.1e}; dim floor against itself alone {same:.1e} of its peak; "
          f"peak texels {images['Bright'].max():.3e} and {images['Dim'].max():.3e}")
    assert errors["Bright"] <= 0.044 and errors["Dim"] <= 0.044  # measured 0.022
    assert abs(errors["Bright"] - errors["Dim"]) <= 1e-4
    assert same <= 1e-5


@pytest.mark.parametrize("degree, coeffs, tolerance", [(0, 1, 1e-4), (3, 48, 9.4e-3)])  # measured 4.2e-5, 4.7e-3
def test_degree_and_coefficient_extremes_bake_the_closed_form(context, degree, coeffs, tolerance):
    # One coefficient of degree 0: the whole face shows the light at its centre (its one
    # Schoenberg node). Degree 3 with 48 coefficients: every texel is the closed form there, to
    # Schoenberg's O(h^2) bias.
    custom(context, coeffs, degree)
    floor_scene()
    job, solution, images = baked(context)
    pixels, uv = tile(images["Floor"], solution, job, "Floor")
    if coeffs == 1:
        uv = np.full_like(uv, 0.5)
    points = np.concatenate([2 * uv - 1, np.zeros(uv.shape[:2] + (1,))], axis=2).reshape(-1, 3)
    want = np.array([lambert(p, (0, 0, 1), 1.0, 50.0) for p in points]).reshape(uv.shape[:2])
    err = np.abs(pixels[..., 0] / want - 1).max()
    print(f"\nbaked floor, degree {degree}, {coeffs} coefficients ({len(pixels)} texels a side): "
          f"max relative error against Lambert's closed form {err:.1e}")
    assert err <= tolerance


def test_coincident_faces_of_two_objects_both_bake_the_lit_floor(context):
    # Two floors at the same place (z-fighting in Blender): neither shadows the other.
    custom(context, 8)
    floor_scene()
    scenes.add_quad("Twin", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], bpy.data.materials["Floor grey"])
    _, _, images = baked(context)
    assert np.array_equal(images["Floor"], images["Twin"])
    assert images["Floor"].min() > 0


def test_object_scaled_flat_is_refused_by_name(context):
    floor_scene()
    wall = scenes.add_quad("Wall", [(0, 0, 0), (0.5, 0, 0), (0.5, 0, 0.5), (0, 0, 0.5)])
    wall.scale = (1, 1, 0)  # flattened to a line in the world
    context.view_layer.update()
    before = {m.name for m in bpy.data.materials}
    with pytest.raises(ExportError) as info:
        baked(context)
    assert "Wall" in str(info.value) and "zero area" in str(info.value), str(info.value)
    assert {m.name for m in bpy.data.materials} == before
