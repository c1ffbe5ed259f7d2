"""Export -> solve -> bake on whole scenes (addon/pipeline.py, export.py, bake.py)."""
import math

import bpy
import numpy as np
import OpenEXR
import pytest

import bsgi
import scenes
from bsgi_addon import bake, pipeline
from bsgi_addon.errors import ExportError


def render_exr(scene, path, samples, bounces, seed=1):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = bounces
    scene.cycles.diffuse_bounces = bounces
    scene.cycles.sample_clamp_direct = 0
    scene.cycles.sample_clamp_indirect = 0
    scene.cycles.blur_glossy = 0.0  # Filter Glossy biases light reflected by glossy surfaces onto diffuse ones
    scene.cycles.seed = seed
    scene.render.resolution_x = scene.render.resolution_y = 96
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return OpenEXR.File(str(path)).channels()["RGBA"].pixels[..., :3].astype(np.float64)


def solve_floor_direct(context):
    """The add-on's solve (direct light only) of the scene: the spline of the object named
    'Floor', and the export."""
    context.scene.bsgi.preset = "CUSTOM"
    context.scene.bsgi.max_bounces = 0
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    floor = next(o for o in job.export.objects if o.name == "Floor")
    return solution.radiance[floor.patches[0][1]], job.export


def render_floor_from_above(context, path, samples):
    """Cycles' render (direct light only) of the 2 x 2 floor on z = 0 around the origin, straight
    from above through an orthographic camera that the floor just fills: the image (n x n x 3)
    and the floor points (n*n x 3) at its pixel centres, row-major."""
    cam = bpy.data.cameras.new("Top")
    cam.type, cam.ortho_scale = "ORTHO", 2.0
    camera = bpy.data.objects.new("Top", cam)
    camera.location = (0, 0, 3)
    context.scene.collection.objects.link(camera)
    context.scene.camera = camera
    image = render_exr(context.scene, path, samples=samples, bounces=0)
    n = image.shape[0]
    centres = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(centres, -centres)  # image rows run downwards
    return image, np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])


def lit_relative_difference(baked, reference, lit_fraction):
    """Per-pixel relative difference of two renders over the lit pixels (luminance above
    lit_fraction of the reference's 99th percentile); returns (differences, lit mask)."""
    luminance = reference.mean(axis=2)
    lit = luminance > lit_fraction * np.percentile(luminance, 99)
    return np.abs(baked - reference).sum(axis=2)[lit] / reference.sum(axis=2)[lit], lit


@pytest.mark.slow
def test_baked_cornell_box_matches_cycles_path_tracing(context, tmp_path):
    scene = scenes.cornell_box()
    scene.bsgi.preset = "CUSTOM"
    bounces = scene.bsgi.max_bounces
    scene.bsgi.tolerance = 0  # exactly max_bounces, like Cycles
    reference = render_exr(scene, tmp_path / "reference.exr", samples=1024, bounces=bounces)
    pipeline.solve_and_bake(context)
    baked = render_exr(scene, tmp_path / "baked.exr", samples=16, bounces=0)
    rel, lit = lit_relative_difference(baked, reference, 0.02)
    mean_rel = rel.mean()
    print(f"\nCornell box, baked vs Cycles ({bounces} bounces, 1024 spp): mean relative difference "
          f"{mean_rel:.4f} over {lit.sum()} lit pixels; median {np.median(rel):.4f}")
    assert lit.sum() > 0.5 * lit.size
    assert mean_rel <= 0.09  # measured 0.0451


def test_saved_blend_reopens_with_the_baked_result(context, tmp_path):
    floor = scenes.floor_under_lamp()
    pipeline.solve_and_bake(context)
    image = bpy.data.images[f"BSGI {floor.name}"]
    before = np.array(image.pixels[:], np.float32)
    assert before.reshape(-1, 4)[:, :3].max() > 0
    path = tmp_path / "solved.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert "Floor" not in bpy.data.objects
    bpy.ops.wm.open_mainfile(filepath=str(path))
    floor = bpy.data.objects["Floor"]
    image = bpy.data.images[f"BSGI Floor"]
    after = np.array(image.pixels[:], np.float32)
    np.testing.assert_array_equal(before, after)
    slot = floor.material_slots[0]
    assert slot.link == "OBJECT" and slot.material.name == "BSGI Floor"
    assert floor.data.materials[0].name == "Grey"  # the user's material is still on the mesh
    assert bake.UV_NAME in floor.data.uv_layers


def test_baked_values_are_the_solved_radiance(context):
    floor = scenes.floor_under_lamp()
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    image = bpy.data.images[f"BSGI {floor.name}"]
    size = image.size[0]
    pixels = np.array(image.pixels[:], np.float32).reshape(size, size, 4)
    spline = solution.radiance[job.export.objects[0].patches[0][1]]
    # Corner texels of the tile are the face's corners: (u, v) = (0, 0) and (1, 1).
    t = bake.tile_size(spline)
    ends = spline.evaluate(np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.5]]))
    np.testing.assert_allclose(pixels[0, 0, :3], ends[0], rtol=1e-6)
    np.testing.assert_allclose(pixels[t - 1, t - 1, :3], ends[1], rtol=1e-6)
    # The floor under a centred lamp is brightest in its middle.
    assert pixels[t // 2, t // 2, 0] > pixels[0, 0, 0]


def test_show_baked_toggles_back_to_the_users_materials(context):
    floor = scenes.floor_under_lamp()
    grey = floor.data.materials[0]
    pipeline.solve_and_bake(context)
    assert floor.active_material.name == "BSGI Floor"
    context.scene.bsgi.show_baked = False
    assert floor.material_slots[0].link == "DATA"
    assert floor.active_material == grey
    context.scene.bsgi.show_baked = True
    assert floor.active_material.name == "BSGI Floor"
    bpy.ops.bsgi.clear()
    assert floor.active_material == grey
    assert bake.UV_NAME not in floor.data.uv_layers
    assert "BSGI Floor" not in bpy.data.materials


def _coordinates(mesh):
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    return co


def _scene_state():
    """What a failed solve must leave as it was."""
    return {
        obj.name: (
            [(s.link, s.material.name if s.material else None) for s in obj.material_slots],
            [uv.name for uv in obj.data.uv_layers] if obj.type == "MESH" else None,
            _coordinates(obj.data).tobytes() if obj.type == "MESH" else None,  # bytes: NaN equals itself
        )
        for obj in bpy.data.objects
    } | {"materials": sorted(m.name for m in bpy.data.materials), "images": sorted(i.name for i in bpy.data.images)}


def _assert_clear_error(context, *words):
    before = _scene_state()
    with pytest.raises((ExportError, ValueError)) as info:
        pipeline.solve_and_bake(context)
    for w in words:
        assert w in str(info.value), str(info.value)
    assert _scene_state() == before
    # The operator reports the same error; called from Python, Blender raises the report.
    with pytest.raises(RuntimeError) as info:
        bpy.ops.bsgi.solve()
    assert words[-1] in str(info.value)
    assert _scene_state() == before


def test_scene_without_emitter_is_refused(context):
    scenes.add_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    _assert_clear_error(context, "no emitter")


def test_zero_area_face_is_refused_by_name(context):
    scenes.floor_under_lamp()
    scenes.add_quad("Sliver", [(0, 0, 0.5), (1, 0, 0.5), (1, 0, 0.5), (0, 0, 0.5)])
    _assert_clear_error(context, "Sliver", "zero area")


def test_nan_vertex_is_refused_by_name(context):
    scenes.floor_under_lamp()
    bad = scenes.add_quad("Broken", [(0, 0, 0.5), (0.2, 0, 0.5), (0.2, 0.2, 0.5), (0, 0.2, 0.5)])
    bad.data.vertices[2].co.x = math.nan
    _assert_clear_error(context, "Broken", "NaN")


def test_cancelled_solve_leaves_the_scene_as_it_was(context):
    import bsgi

    scenes.cornell_box()
    before = _scene_state()
    job = pipeline.prepare(context)
    job.progress.cancel()  # what Esc does in the modal operator
    with pytest.raises(bsgi.SolveCancelled):
        pipeline.run(job)
    assert _scene_state() == before


def _image_pixels(name):
    return np.array(bpy.data.images[name].pixels[:], np.float32)


def test_rebake_from_stored_splines_equals_the_first_bake(context, tmp_path):
    scenes.cornell_box()
    pipeline.solve_and_bake(context)
    first = {o.name: _image_pixels(f"BSGI {o.name}") for o in context.scene.objects if bake.is_baked(o)}
    assert len(first) == 3
    # Through a save and reopen: the splines travel in the .blend.
    path = tmp_path / "solved.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    for name in first:
        bpy.data.images[f"BSGI {name}"].pixels.foreach_set(np.zeros(len(first[name]), np.float32))
    assert bpy.ops.bsgi.rebake() == {"FINISHED"}
    for name, pixels in first.items():
        np.testing.assert_array_equal(_image_pixels(f"BSGI {name}"), pixels)


def test_solution_file_round_trip_through_blender(context, tmp_path):
    import bsgi

    scenes.cornell_box()
    pipeline.solve_and_bake(context)
    first = {o.name: _image_pixels(f"BSGI {o.name}") for o in context.scene.objects if bake.is_baked(o)}
    path = tmp_path / "cornell.npz"
    assert bpy.ops.bsgi.export_solution(filepath=str(path)) == {"FINISHED"}
    stored = bsgi.load_solution(path)
    assert len(stored.radiance) == 5 + 6 + 6 and stored.names[0] == "Room: face 0"
    bpy.ops.bsgi.clear()
    assert not any(bake.is_baked(o) for o in context.scene.objects)
    assert bpy.ops.bsgi.import_solution(filepath=str(path)) == {"FINISHED"}
    for name, pixels in first.items():
        np.testing.assert_array_equal(_image_pixels(f"BSGI {name}"), pixels)


def test_glossy_quad_bakes_its_radiance_per_angular_sample(context):
    floor = scenes.floor_under_lamp()
    floor.data.materials[0] = scenes.metal_material("Steel", 0.5)
    context.scene.bsgi.preset = "DRAFT"
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    rep = pipeline.report(job, solution, 0.0, 0.0)
    assert rep["representations"]["counts"] == {"glossy": 1, "emitter": 1}
    assert rep["representations"]["largest"]["name"] == "Floor: face 0"
    assert "1 glossy" in pipeline.summary_text(rep)
    assert not [w for w in rep["warnings"] if "'Floor'" in w]

    index = job.export.objects[0].patches[0][1]
    surface = solution.surfaces[index]
    assert surface.upper.dims == 4
    image = bpy.data.images["BSGI Floor"]
    t = bake.tile_size(surface)
    a = bake.angular_samples(bake.face_splines(job.export.objects[0], solution.surfaces))
    # Three samples per angular knot span.
    assert a == 3 * (surface.upper.axes[2].num_coeffs - surface.upper.axes[2].degree) + 1
    assert image.size[:] == (a * t, a * t)
    pixels = np.array(image.pixels[:], np.float32).reshape(a * t, a * t, 4)
    # Angular tile (i, j) holds the radiance leaving towards the direction the map (20)-(22)
    # sends (alpha_i, beta_j) to: compare with the core's evaluation along that direction
    # (at samples inside the disc; outside it the tiles hold the spline's own extension).
    hemisphere = bsgi.HemisphereMap(surface.disc_radius)
    grid = np.linspace(-surface.disc_radius, surface.disc_radius, a)
    uv = np.array([[0.0, 0.0], [1.0, 1.0]])
    for i, j in [(a // 2, a // 2), (a // 2 + 2, a // 2 - 1), (a // 4, 3 * a // 4)]:
        assert math.hypot(grid[i], grid[j]) < surface.disc_radius
        direction = np.asarray(hemisphere.to_direction(np.array([[grid[i], grid[j]]])))[0]
        solved = surface.evaluate(uv, np.tile(direction, (2, 1)))
        texels = pixels[[j * t, j * t + t - 1], [i * t, i * t + t - 1], :3]
        np.testing.assert_allclose(texels, solved, rtol=1e-5)
    # The lamp straight above the middle: a metal seen head-on there reflects it brightly.
    head_on = surface.evaluate(np.array([[0.0, 0.0], [0.5, 0.5]]), np.tile([0.0, 0.0, 1.0], (2, 1)))
    assert head_on[1, 0] > 5 * head_on[0, 0] > 0
    # Re-baking from the stored (4D) splines gives the same image.
    bpy.ops.bsgi.rebake()
    np.testing.assert_array_equal(np.array(image.pixels[:], np.float32).reshape(a * t, a * t, 4), pixels)


def test_a_second_solve_reads_the_users_materials_not_the_baked_ones(context):
    floor = scenes.floor_under_lamp()
    first = pipeline.solve_and_bake(context)
    pixels = _image_pixels("BSGI Floor")
    for show in (True, False):  # whether the bake or the originals are shown
        context.scene.bsgi.show_baked = show
        again = pipeline.solve_and_bake(context)
        assert again["representations"] == first["representations"]
        assert not any("BSGI" in w for w in again["warnings"])
        np.testing.assert_array_equal(_image_pixels("BSGI Floor"), pixels)
    assert floor.data.materials[0].name == "Grey"


@pytest.mark.parametrize("preset", ["DRAFT", "PREVIEW", "FINAL", "REFERENCE"])
def test_quality_preset_is_the_cores_preset(context, preset):
    import bsgi

    settings = context.scene.bsgi
    settings.preset = preset
    settings.spatial_coeffs = 5  # the individual settings are used by Custom only
    got, expected = settings.solver_settings(), bsgi.SolverSettings.preset(preset.lower())
    for name in ("spatial_coeffs", "adaptive_knots", "angular_resolution", "hemisphere_nodes_theta", "tolerance",
                 "final_gather", "max_bounces", "discontinuity_knots", "near_contact_knots", "final_spatial_factor",
                 "final_integration_factor"):
        assert getattr(got, name) == getattr(expected, name), name


def test_quality_numbers_a_blend_stores_keep_their_meaning(context):
    # A .blend stores the Quality's number: Reference, added after Custom, took the next one, so
    # a scene saved with Custom (3) before opens with Custom; every item but Custom names a preset
    # of the core (an unknown name would fail at a user's solve).
    import bsgi

    items = context.scene.bsgi.bl_rna.properties["preset"].enum_items
    assert {i.identifier: i.value for i in items} == {"DRAFT": 0, "PREVIEW": 1, "FINAL": 2, "CUSTOM": 3, "REFERENCE": 4}
    for item in items:
        if item.identifier != "CUSTOM":
            bsgi.SolverSettings.preset(item.identifier.lower())


def test_custom_preset_uses_the_individual_settings(context):
    settings = context.scene.bsgi
    assert settings.preset == "PREVIEW"  # the default
    settings.preset = "CUSTOM"
    settings.spatial_coeffs, settings.max_bounces, settings.hemisphere_nodes = 7, 3, 5
    got = settings.solver_settings()
    assert (got.spatial_coeffs, got.max_bounces, got.hemisphere_nodes_theta, got.hemisphere_nodes_phi) == (7, 3, 5, 10)
    assert not got.final_gather


def test_adaptive_coefficients_give_a_small_box_fewer_than_the_floor(context):
    # A 0.2 m cube on a 2 m floor under the lamp: with Adaptive Coefficients the cube's faces get
    # fewer coefficients than the preset's (the floor, the largest, keeps them); Off turns it off,
    # As the Quality follows the preset (Preview adapts, Draft does not).
    scenes.floor_under_lamp()
    bpy.ops.mesh.primitive_cube_add(size=0.2, location=(0.5, 0.5, 0.1))
    settings = context.scene.bsgi
    settings.preset = "DRAFT"
    assert settings.adaptive_coefficients == "QUALITY" and not settings.solver_settings().coeffs_from_size
    uniform = pipeline.solve_and_bake(context)
    settings.adaptive_coefficients, settings.detail_tolerance = "TOLERANCE", 0.01
    got = settings.solver_settings()
    assert got.coeffs_from_size and got.detail_tolerance == pytest.approx(0.01) and got.spatial_coeffs == 8
    adaptive = pipeline.solve_and_bake(context)
    for rep in (uniform, adaptive):
        assert rep["representations"]["largest"]["name"] == "Floor: face 0"
        assert rep["representations"]["largest"]["shape"] == [16, 16]  # draft's 8, doubled by the final gather
    # The cube's six faces (five lit, one resting on the floor) at 16 x 16 each without it.
    assert adaptive["coefficients"] < 0.75 * uniform["coefficients"]
    settings.preset, settings.adaptive_coefficients = "PREVIEW", "QUALITY"
    got = settings.solver_settings()
    assert got.coeffs_from_size and got.detail_tolerance == pytest.approx(0.005)
    settings.adaptive_coefficients = "OFF"
    got = settings.solver_settings()
    assert not got.coeffs_from_size and got.detail_tolerance == 0


def test_refine_to_error_solves_again_and_reports_it(context):
    floor = scenes.floor_under_lamp()
    # A wall beside the floor: light bounces between them (a lone floor's estimate is its
    # unknown bounce tail, which refinement leaves alone).
    scenes.add_quad("Wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], floor.data.materials[0])
    settings = context.scene.bsgi
    settings.preset = "DRAFT"
    settings.refine_to_error, settings.refine_passes = 1e-4, 1  # a target no solve meets: one more pass
    assert settings.solver_settings().refine_to_error == 0  # the draft quality's: read only with To Error
    settings.refinement = "TO_ERROR"
    got = settings.solver_settings()
    assert (got.refine_to_error, got.refine_passes, got.spatial_coeffs) == (pytest.approx(1e-4), 1, 8)
    rep = pipeline.solve_and_bake(context)
    assert rep["refinement"]["passes"] == 1 and rep["refinement"]["stopped"] == "passes"
    assert rep["refinement"]["refined"] >= 1 and "Floor: face 0" in rep["refinement"]["over_target"]
    assert " surfaces refined in 1 more solves (2 still over the target, stopped by the passes budget)" in pipeline.summary_text(rep)
    assert rep["refinement"]["trimmed"] == []
    # A pass the cost budget trimmed (tests/core/test_refine.py solves one) reads so in the status bar.
    trimmed = dict(rep, refinement=dict(rep["refinement"], stopped=None, trimmed=["cost"]))
    assert "(2 still over the target, the worst refined first within the cost budget)" in pipeline.summary_text(trimmed)
    settings.refine_cost = 2.5
    assert settings.solver_settings().refine_cost == pytest.approx(2.5)


def test_refinement_follows_the_quality_unless_set(context):
    """Refinement As the Quality: Final's (the core's preset: 1%, a budget of 5), none at the others;
    Off: none at Final either; To Error: the panel's target, passes and budget at any quality."""
    settings = context.scene.bsgi
    assert settings.refinement == "QUALITY"
    final = bsgi.SolverSettings.preset("final")
    assert final.refine_to_error > 0  # what As the Quality passes on
    settings.preset = "FINAL"
    got = settings.solver_settings()
    assert (got.refine_to_error, got.refine_passes, got.refine_cost) == (
        final.refine_to_error, final.refine_passes, final.refine_cost)
    for preset in ("DRAFT", "PREVIEW", "REFERENCE", "CUSTOM"):
        settings.preset = preset
        assert settings.solver_settings().refine_to_error == 0, preset
    settings.preset, settings.refinement = "FINAL", "OFF"
    assert settings.solver_settings().refine_to_error == 0
    settings.refinement = "TO_ERROR"
    settings.refine_to_error, settings.refine_passes, settings.refine_cost = 0.03, 1, 1.5
    got = settings.solver_settings()
    assert (got.refine_to_error, got.refine_passes, got.refine_cost) == (pytest.approx(0.03), 1, pytest.approx(1.5))
    settings.preset = "DRAFT"
    assert settings.solver_settings().refine_to_error == pytest.approx(0.03)


def test_object_panel_and_options_are_registered(context):
    assert hasattr(bpy.types, "BSGI_PT_object")
    floor = scenes.floor_under_lamp()
    assert (floor.bsgi.representation, floor.bsgi.spatial_coeffs, floor.bsgi.angular_coeffs) == ("AUTO", 0, 0)


def test_solve_operator_reports_the_representations(context, capfd):
    floor = scenes.floor_under_lamp()
    floor.data.materials[0] = scenes.metal_material("Steel", 0.5)
    context.scene.bsgi.preset = "DRAFT"
    assert bpy.ops.bsgi.solve() == {"FINISHED"}
    out = capfd.readouterr()
    text = out.out + out.err
    assert "1 glossy, 1 emitter; largest 'Floor: face 0'" in text, text[-2000:]
    assert "not view-dependent" not in text  # glossy surfaces are baked view-dependently
