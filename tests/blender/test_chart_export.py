"""Meshes of many faces solved as one UV chart (addon/charts.py, geometry.py, bake.py `_bake_chart`):
the user's UV map when it is a chart, else one generated on a copy; the result against Lambert's
closed form and against the per-face export of the same mesh."""
import math
import sys

import bpy
import numpy as np
import pytest

import scenes
from bsgi_addon import bake, export, pipeline

sys.path.insert(0, str(scenes.ROOT / "tests" / "core"))
from closed_forms import polygon_irradiance  # noqa: E402

LAMP = [(-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)]
LAMP_RADIANCE = 50.0 / math.pi  # 50 W over 1 m^2, Cycles' convention (test_export.py)


def grid_floor(cuts=8, name="Floor", material=None):
    """A 2 x 2 floor of cuts x cuts quads at z = 0, with Blender's UV map (u, v) = ((x + 1) / 2, (y + 1) / 2)."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=cuts, y_subdivisions=cuts, size=2)
    floor = bpy.context.object
    floor.name = floor.data.name = name
    floor.data.materials.append(material or scenes.diffuse_material("Grey", (0.5, 0.5, 0.5)))
    return floor


def uv_data(mesh, name):
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers[name].data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)


def direct_light_setup(context, threshold):
    context.scene.bsgi.preset = "CUSTOM"
    context.scene.bsgi.max_bounces = 0
    context.scene.bsgi.chart_min_faces = threshold


def test_grid_with_a_uv_map_is_one_chart_lit_as_the_closed_form(context):
    floor = grid_floor()
    scenes.add_area_light()
    direct_light_setup(context, threshold=16)
    job = pipeline.prepare(context)
    (exported,) = job.export.objects
    assert exported.kind == "chart" and len(job.export.scene) == 2
    assert job.export.scene.name(exported.patches[0][1]) == "Floor: chart 0"
    np.testing.assert_array_equal(exported.chart_uvs, uv_data(floor.data, "UVMap"))  # the user's own UV map
    spline = pipeline.run(job).radiance[exported.patches[0][1]]
    # As for the single-quad floor (test_export.py): Schoenberg smoothing of the peak, measured
    # -1.13%, -0.40% and -0.20%.
    for u, v, bound in [(0.5, 0.5, 0.02), (0.2, 0.7, 0.008), (0.85, 0.3, 0.004)]:
        e = polygon_irradiance([2 * u - 1, 2 * v - 1, 0], [0, 0, 1], LAMP, LAMP_RADIANCE)
        got = spline.evaluate(np.array([[u, v]]))[0, 0]
        print(f"\nchart floor at ({u}, {v}): relative error {got / (0.5 / math.pi * e) - 1:.2e}")
        assert got == pytest.approx(0.5 / math.pi * e, rel=bound)


def test_chart_agrees_with_the_per_face_export_of_the_same_mesh(context):
    """Same solve (one bounce off a wall), the floor per face and as a chart: the radiance at the
    64 face centres agrees within 2% of its maximum."""
    grey = scenes.diffuse_material("Grey", (0.5, 0.5, 0.5))
    floor = grid_floor(material=grey)
    wall = scenes.add_quad("Wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], grey)
    scenes.add_area_light()
    context.scene.bsgi.preset = "CUSTOM"
    context.scene.bsgi.max_bounces = 1
    uv = uv_data(floor.data, "UVMap")
    centres_uv = np.array([uv[list(p.loop_indices)].mean(axis=0) for p in floor.data.polygons], np.float64)

    context.scene.bsgi.chart_min_faces = 0
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    per_face = np.array([solution.radiance[first].evaluate(np.array([[0.5, 0.5]]))[0]
                         for _, first, _ in job.export.objects[0].patches])
    assert len(per_face) == 64

    context.scene.bsgi.chart_min_faces = 64
    job = pipeline.prepare(context)
    assert job.export.objects[0].kind == "chart" and job.export.objects[1].kind == "mesh"
    solution = pipeline.run(job)
    chart = solution.radiance[job.export.objects[0].patches[0][1]].evaluate(centres_uv)
    difference = np.abs(chart - per_face).max() / per_face.max()
    print(f"chart vs per-face floor: max difference {difference:.4f} of the maximum radiance")
    assert difference < 0.02  # measured 0.0107
    assert wall.name == "Wall"


def test_mesh_without_a_chart_uv_map_gets_one_generated_on_a_copy(context):
    floor = grid_floor(name="Plain")
    floor.data.uv_layers.remove(floor.data.uv_layers["UVMap"])
    scenes.add_area_light()
    direct_light_setup(context, threshold=16)
    objects, meshes = set(bpy.data.objects.keys()), set(bpy.data.meshes.keys())
    job = pipeline.prepare(context)
    (exported,) = job.export.objects
    assert exported.kind == "chart"
    assert any("object 'Plain'" in w and "Smart UV Project" in w and "no UV map" in w for w in job.export.warnings)
    assert len(floor.data.uv_layers) == 0  # never unwrapped the user's mesh
    assert set(bpy.data.objects.keys()) == objects and set(bpy.data.meshes.keys()) == meshes  # no leftovers
    assert context.view_layer.objects.active == floor  # the active object and the selection are restored
    assert floor.select_get() and not bpy.data.objects["Lamp"].select_get()
    # A planar grid is one island: the generated chart covers it without overlap (checked by the
    # exporter) and the solve agrees with the closed form at the face centres' world positions.
    spline = pipeline.run(job).radiance[exported.patches[0][1]]
    uv = exported.chart_uvs
    for poly in list(floor.data.polygons)[::9]:
        centre = np.mean([floor.data.vertices[v].co[:] for v in poly.vertices], axis=0)
        e = polygon_irradiance([centre[0], centre[1], 0], [0, 0, 1], LAMP, LAMP_RADIANCE)
        got = spline.evaluate(uv[list(poly.loop_indices)].mean(axis=0)[None].astype(np.float64))[0, 0]
        print(f"\ngenerated chart at face {poly.index}: relative error {got / (0.5 / math.pi * e) - 1:.2e}")
        assert got == pytest.approx(0.5 / math.pi * e, rel=0.022)  # measured 1.11% at most


def test_overlapping_uv_map_is_not_used_and_stays_unchanged(context):
    floor = grid_floor(name="Stacked")
    layer = floor.data.uv_layers["UVMap"]
    stacked = np.tile([[0, 0], [1, 0], [1, 1], [0, 1]], (len(floor.data.polygons), 1)).astype(np.float32)
    layer.data.foreach_set("uv", stacked.ravel())  # every face on the whole square
    scenes.add_area_light()
    context.scene.bsgi.chart_min_faces = 16
    result = export.export_scene(context.evaluated_depsgraph_get())
    assert result.objects[0].kind == "chart"
    assert any("'Stacked'" in w and "UV map 'UVMap': its islands overlap" in w for w in result.warnings)
    np.testing.assert_array_equal(uv_data(floor.data, "UVMap"), stacked)
    assert list(floor.data.uv_layers.keys()) == ["UVMap"]


def test_mesh_of_several_materials_stays_per_face(context):
    floor = grid_floor(name="Tiles")
    floor.data.materials.append(scenes.diffuse_material("White", (0.9, 0.9, 0.9)))
    floor.data.polygons[5].material_index = 1
    scenes.add_area_light()
    context.scene.bsgi.chart_min_faces = 16
    result = export.export_scene(context.evaluated_depsgraph_get())
    assert result.objects[0].kind == "mesh" and len(result.objects[0].patches) == 64
    assert any("object 'Tiles'" in w and "several materials" in w for w in result.warnings)


def test_chart_bake_shows_the_spline_through_the_charts_uv_map_and_clears(context):
    floor = grid_floor()
    scenes.add_area_light()
    direct_light_setup(context, threshold=16)
    pipeline.solve_and_bake(context)
    mesh = floor.data
    assert list(mesh.uv_layers.keys()) == ["UVMap", bake.UV_NAME]
    np.testing.assert_array_equal(uv_data(mesh, bake.UV_NAME), uv_data(mesh, "UVMap"))
    material = floor.material_slots[0].material
    uv_node = next(n for n in material.node_tree.nodes if n.type == "UVMAP")
    assert uv_node.uv_map == bake.UV_NAME
    image = next(n.image for n in material.node_tree.nodes if n.type == "TEX_IMAGE")
    n = image.size[0]
    pixels = np.array(image.pixels[:], np.float32).reshape(n, n, 4)
    # The texel nearest a UV point holds the solved radiance there (closed form, as above).
    for u, v in [(0.5, 0.5), (0.3, 0.6)]:
        i, j = int(u * n), int(v * n)
        cu, cv = (i + 0.5) / n, (j + 0.5) / n
        e = polygon_irradiance([2 * cu - 1, 2 * cv - 1, 0], [0, 0, 1], LAMP, LAMP_RADIANCE)
        print(f"\nchart texel at ({u}, {v}): relative error {pixels[j, i, 0] / (0.5 / math.pi * e) - 1:.2e}")
        assert pixels[j, i, 0] == pytest.approx(0.5 / math.pi * e, rel=0.02)  # measured 1.13% at most
    before = pixels.copy()
    bake.rebake(floor)  # from the stored spline and the chart's UV map, no solve
    np.testing.assert_array_equal(np.array(image.pixels[:], np.float32).reshape(n, n, 4), before)
    bake.clear_bake(floor)
    assert list(mesh.uv_layers.keys()) == ["UVMap"]


def test_chart_solution_file_round_trip(context, tmp_path):
    from bsgi_addon import solution_file

    floor = grid_floor()
    scenes.add_area_light()
    direct_light_setup(context, threshold=16)
    pipeline.solve_and_bake(context)
    image = bpy.data.images["BSGI Floor"]
    before = np.array(image.pixels[:], np.float32)
    path = tmp_path / "chart.npz"
    assert solution_file.export_solution(context.scene, str(path)) == 1
    bake.clear_bake(floor)
    assert "BSGI Floor" not in bpy.data.images
    assert solution_file.import_solution(context.scene, str(path)) == [floor]
    np.testing.assert_array_equal(np.array(bpy.data.images["BSGI Floor"].pixels[:], np.float32), before)
    np.testing.assert_array_equal(uv_data(floor.data, bake.UV_NAME), uv_data(floor.data, "UVMap"))


def test_failed_solve_of_a_generated_chart_leaves_the_scene_as_it_was(context):
    from test_pipeline import _assert_clear_error

    floor = grid_floor(name="Plain")  # no light: the solve fails after the UV map was generated
    floor.data.uv_layers.remove(floor.data.uv_layers["UVMap"])
    context.scene.bsgi.chart_min_faces = 16
    meshes = sorted(bpy.data.meshes.keys())
    _assert_clear_error(context, "no emitter")  # compares objects, slots, UV maps, materials, images
    assert sorted(bpy.data.meshes.keys()) == meshes


@pytest.mark.slow
@pytest.mark.parametrize("uv_map", ["own", "generated"])
def test_baked_chart_sphere_matches_cycles_path_tracing(context, tmp_path, uv_map):
    """A UV sphere mesh (512 faces) solved and baked as one chart, over its own UV map or a
    generated one, rendered through the chart's UV map, against Cycles path tracing the original
    mesh over a floor (one bounce)."""
    from test_pipeline import lit_relative_difference, render_exr

    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.8, location=(0, 0, 0.9))
    sphere = bpy.context.object
    sphere.data.materials.append(scenes.diffuse_material("Clay", (0.6, 0.5, 0.4)))
    if uv_map == "generated":
        sphere.data.uv_layers.remove(sphere.data.uv_layers[0])
    grey = scenes.diffuse_material("Grey", (0.5, 0.5, 0.5))
    scenes.add_quad("Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], grey)
    scenes.add_area_light(location=(0, 0, 3), size=2.0, energy=300.0)
    context.scene.bsgi.preset = "PREVIEW"
    context.scene.bsgi.chart_min_faces = 64
    scenes.add_camera(tilt_degrees=70)
    reference = render_exr(context.scene, tmp_path / "reference.exr", samples=512, bounces=1)
    rep = pipeline.solve_and_bake(context)
    assert bake.stored_faces(sphere)[0][0] == "chart"
    baked = render_exr(context.scene, tmp_path / "baked.exr", samples=16, bounces=0)
    rel, lit = lit_relative_difference(baked, reference, 0.05)
    assert any("Smart UV Project" in w for w in rep["warnings"]) == (uv_map == "generated")
    print(f"\nchart sphere ({uv_map} UV map), baked vs Cycles (512 spp): mean relative difference {rel.mean():.4f} over {lit.sum()} "
          f"lit pixels; median {np.median(rel):.4f}")
    assert lit.sum() > 0.05 * lit.size
    assert rel.mean() <= 0.097  # measured 0.040 (own UV map) and 0.049 (generated)


def test_object_setting_forces_a_chart_or_faces(context):
    floor = grid_floor(cuts=4)  # 16 faces, under the default threshold of 64
    scenes.add_area_light()
    assert context.scene.bsgi.chart_min_faces == 64

    def kind():
        return export.export_scene(context.evaluated_depsgraph_get()).objects[0].kind

    assert kind() == "mesh"
    floor.bsgi.mesh_surfaces = "CHART"
    assert kind() == "chart"
    context.scene.bsgi.chart_min_faces = 8
    floor.bsgi.mesh_surfaces = "AUTO"
    assert kind() == "chart"
    floor.bsgi.mesh_surfaces = "FACES"
    assert kind() == "mesh"


def test_chart_problems_of_uv_triangles():
    from bsgi_addon import charts

    square = np.array([[[0.1, 0.1], [0.9, 0.1], [0.9, 0.9]], [[0.1, 0.1], [0.9, 0.9], [0.1, 0.9]]])
    assert charts.chart_problem(square) == ""  # sharing an edge is no overlap
    shifted = square.copy()
    shifted[1, :, 0] += 0.02  # across the shared diagonal: a sliver over the first triangle
    assert charts.chart_problem(shifted) == "its islands overlap"
    assert charts.chart_problem(square * 1.2) == "it leaves the square [0, 1]"
    flat = square.copy()
    flat[0, 2] = flat[0, 1]
    assert charts.chart_problem(flat) == "1 of its triangles have no UV area"
    # Many small triangles (a 300 x 300 grid) are tested in batches: a duplicated last one is found.
    x = np.linspace(0, 1, 301)
    cells = np.array([[[x[i], x[j]], [x[i + 1], x[j]], [x[i + 1], x[j + 1]]] for i in range(300) for j in range(300)])
    assert charts.chart_problem(cells) == ""
    assert charts.chart_problem(np.concatenate([cells, cells[-1:]])) == "its islands overlap"
