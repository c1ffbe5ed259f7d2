"""bsgi.Scene (scene.h, bind_scene.cpp): the surfaces it holds, shared with Python."""
import numpy as np
import pytest

import bsgi


def two_patch_scene():
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]], float),
                             albedo=[0.5] * 3, emission=[0] * 3)
    scene.add_triangle("lamp", np.array([[0, 0, 1], [0, 1, 1], [1, 0, 1]], float), albedo=[0] * 3, emission=[1] * 3)
    return scene


def test_surface_is_the_scenes_own_and_of_its_kind():
    scene = two_patch_scene()
    floor, lamp = scene.surface(0), scene.surface(1)
    assert isinstance(floor, bsgi.BilinearPatch) and isinstance(lamp, bsgi.TrianglePatch)
    assert (floor.name, lamp.name) == ("floor", "lamp")
    uv = np.array([[0.25, 0.75]])
    np.testing.assert_allclose(floor.evaluate(uv)["position"][0], [0.5, 0.75, 0.0], atol=1e-15)
    assert floor.area == pytest.approx(scene.area(0))


def test_surface_index_out_of_range_is_an_index_error():
    with pytest.raises(IndexError, match="surface index 2"):
        two_patch_scene().surface(2)


def test_ray_caster_over_the_scenes_surfaces_answers_with_scene_indices():
    scene = two_patch_scene()
    caster = bsgi.RayCaster([scene.surface(i) for i in range(len(scene))])
    hit = caster.closest_hit(np.array([[1.5, 0.5, 0.5], [0.2, 0.2, 0.5]]), np.array([[0, 0, -1.0], [0, 0, 1.0]]))
    assert list(hit["surface"]) == [0, 1]
