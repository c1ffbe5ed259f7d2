"""NURBS surfaces through export -> solve -> bake: exact surfaces in the scene, one image per
spline laid out in parameter space and shown through the UV map of Blender's own mesh."""
import math

import bpy
import numpy as np
import pytest

import scenes
from bsgi_addon import bake, export, geometry, pipeline


def add_sphere(location=(0.3, -0.2, 0.0), scale=(1.0, 1.2, 0.8)):
    bpy.ops.surface.primitive_nurbs_surface_sphere_add(radius=1.0, location=location)
    sphere = bpy.context.active_object
    sphere.scale = scale
    sphere.rotation_euler = (0.3, 0.0, 0.5)
    sphere.data.materials.append(scenes.diffuse_material("Clay", (0.6, 0.5, 0.4)))
    return sphere


def sphere_under_lamp(context):
    sphere = add_sphere()
    scenes.add_area_light(location=(0, 0, 3), size=2.0, energy=300.0)
    context.scene.bsgi.preset = "DRAFT"
    return sphere


def mesh_corners(obj):
    """(uv, world position) of the corners of Blender's mesh of the surface."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        uv = np.empty(2 * len(mesh.loops))
        mesh.uv_layers[bake.NURBS_UV_NAME].data.foreach_get("uv", uv)
        vi = np.empty(len(mesh.loops), np.int64)
        mesh.loops.foreach_get("vertex_index", vi)
        co = np.empty(3 * len(mesh.vertices))
        mesh.vertices.foreach_get("co", co)
        m = np.array(evaluated.matrix_world)
        world = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
        return uv.reshape(-1, 2), world[vi]
    finally:
        evaluated.to_mesh_clear()


def sample_linear_extend(pixels, uv):
    """A Linear, Extend image lookup as Blender's Image Texture does: texel centres at (i + 0.5) / size."""
    h, w = pixels.shape[:2]
    x, y = uv[:, 0] * w - 0.5, uv[:, 1] * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    cx = lambda i: np.clip(i, 0, w - 1)  # noqa: E731
    cy = lambda j: np.clip(j, 0, h - 1)  # noqa: E731
    p = pixels[..., :3]
    return ((1 - fy) * ((1 - fx) * p[cy(y0), cx(x0)] + fx * p[cy(y0), cx(x0 + 1)])
            + fy * ((1 - fx) * p[cy(y0 + 1), cx(x0)] + fx * p[cy(y0 + 1), cx(x0 + 1)]))


def test_surface_is_exported_exactly_in_world_space(context):
    sphere = sphere_under_lamp(context)
    result = export.export_scene(context.evaluated_depsgraph_get())
    (exported,) = result.objects
    assert exported.kind == "nurbs" and exported.patches == [("nurbs", 0, 1)]
    uv, world = mesh_corners(sphere)
    surface = geometry.nurbs_surface("check", sphere.data.splines[0], sphere.matrix_world)
    got = surface.evaluate(uv)["position"]
    assert np.abs(got - world).max() < 1e-5 * np.ptp(world, axis=0).max()
    # The scene's surface 0 is that surface: the same point at a parameter.
    p = result.scene.evaluate_surface(0, 0.3, 0.6)["position"]
    np.testing.assert_allclose(p, surface.evaluate(np.array([[0.3, 0.6]]))["position"][0], atol=1e-12)


def test_sphere_bakes_its_spline_in_parameter_space(context):
    sphere = sphere_under_lamp(context)
    points = np.array([p.co[:] for p in sphere.data.splines[0].points])
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    spline = solution.radiance[job.export.objects[0].patches[0][1]]

    image = bpy.data.images["BSGI SurfSphere"]
    w, h = image.size
    assert (w, h) == bake.nurbs_image_size(spline)
    assert w >= max(16, 2 * spline.axes[0].num_coeffs) and h >= max(16, 2 * spline.axes[1].num_coeffs)
    pixels = np.array(image.pixels[:], np.float32).reshape(h, w, 4)
    assert pixels[..., :3].max() > 0
    # What a render shows at each corner of Blender's mesh (its UVMap is the normalized (u, v)) is the spline there.
    uv, world = mesh_corners(sphere)
    shown = sample_linear_extend(pixels, uv)
    solved = spline.evaluate(uv)
    error = np.abs(shown - solved).max(axis=1) / solved.max()
    # Between the texel centres the lookup interpolates the spline linearly (second order); in
    # the half-texel border the Extend lookup holds the edge texel (first order).
    inner = np.all((uv >= 0.5 / np.array([w, h])) & (uv <= 1 - 0.5 / np.array([w, h])), axis=1)
    print(f"\nNURBS sphere: image {w}x{h}; image vs spline at the mesh's UVs, of the peak: largest "
          f"{error[inner].max():.4f} inside the texel centres, {error[~inner].max():.4f} in the border")
    assert inner.sum() > 0.5 * len(uv)
    assert error[inner].max() < 0.01
    assert error[~inner].max() < 0.05
    # Lit from above: the top of the sphere is brighter than its bottom.
    top, bottom = np.argmax(world[:, 2]), np.argmin(world[:, 2])
    assert solved[top, 0] > 2 * solved[bottom, 0]

    # The material is linked at object level through the surface's own UV map; the user's data is as it was.
    slot = sphere.material_slots[0]
    assert slot.link == "OBJECT" and slot.material.name == "BSGI SurfSphere"
    uv_node = next(n for n in slot.material.node_tree.nodes if n.type == "UVMAP")
    assert uv_node.uv_map == "UVMap"
    assert sphere.data.materials[0].name == "Clay"
    np.testing.assert_array_equal(np.array([p.co[:] for p in sphere.data.splines[0].points]), points)

    context.scene.bsgi.show_baked = False
    assert sphere.material_slots[0].link == "DATA" and sphere.active_material.name == "Clay"
    context.scene.bsgi.show_baked = True
    image.pixels.foreach_set(np.zeros(w * h * 4, np.float32))
    assert bpy.ops.bsgi.rebake() == {"FINISHED"}
    np.testing.assert_array_equal(np.array(image.pixels[:], np.float32).reshape(h, w, 4), pixels)
    bpy.ops.bsgi.clear()
    assert sphere.active_material.name == "Clay"
    assert "BSGI SurfSphere" not in bpy.data.materials and "BSGI SurfSphere" not in bpy.data.images


def test_nurbs_patch_lights_a_floor_and_bakes_with_it(context):
    """A glossy NURBS patch between a floor and the lamp: both solve, both bake; the patch's
    bake is view-dependent (no warning), and its shadow darkens the floor's middle."""
    scenes.floor_under_lamp()
    bpy.ops.surface.primitive_nurbs_surface_surface_add(radius=0.3, location=(0, 0, 0.5))
    patch = bpy.context.active_object
    patch.rotation_euler = (0.2, 0.1, 0.3)
    mat = bpy.data.materials.new("Chrome")
    if mat.node_tree is None:
        mat.use_nodes = True
    node = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    node.inputs["Metallic"].default_value = 1.0
    node.inputs["Roughness"].default_value = 0.6
    patch.data.materials.append(mat)
    context.scene.bsgi.preset = "DRAFT"
    rep = pipeline.solve_and_bake(context)
    assert rep["representations"]["counts"] == {"diffuse": 1, "glossy": 1, "emitter": 1}
    assert not any("'SurfPatch'" in w and "view" in w for w in rep["warnings"])
    assert bake.is_baked(patch) and bake.is_baked(bpy.data.objects["Floor"])
    pixels = np.array(bpy.data.images["BSGI SurfPatch"].pixels[:], np.float32)
    assert pixels.reshape(-1, 4)[:, :3].max() > 0
    shadowed = bake.stored_faces(bpy.data.objects["Floor"])[0][1][0].upper.evaluate(np.array([[0.5, 0.5]]))[0, 0]
    bpy.data.objects.remove(patch)
    pipeline.solve_and_bake(context)  # a second solve reads the user's materials, not the baked ones
    lit = bake.stored_faces(bpy.data.objects["Floor"])[0][1][0].upper.evaluate(np.array([[0.5, 0.5]]))[0, 0]
    print(f"\nfloor middle: {shadowed:.3f} under the NURBS patch, {lit:.3f} without it")
    assert shadowed < 0.97 * lit  # a small patch (its cubic span is 0.3 wide) under a 1 x 1 lamp


def test_failed_nurbs_solve_leaves_the_scene_unchanged(context):
    from test_pipeline import _assert_clear_error

    add_sphere()  # no light
    _assert_clear_error(context, "no emitter")
    assert not bake.is_baked(bpy.data.objects["SurfSphere"])


def test_nurbs_solution_file_round_trip(context, tmp_path):
    sphere_under_lamp(context)
    pipeline.solve_and_bake(context)
    image = bpy.data.images["BSGI SurfSphere"]
    first = np.array(image.pixels[:], np.float32)
    path = tmp_path / "sphere.npz"
    assert bpy.ops.bsgi.export_solution(filepath=str(path)) == {"FINISHED"}
    bpy.ops.bsgi.clear()
    assert "BSGI SurfSphere" not in bpy.data.images
    assert bpy.ops.bsgi.import_solution(filepath=str(path)) == {"FINISHED"}
    np.testing.assert_array_equal(np.array(bpy.data.images["BSGI SurfSphere"].pixels[:], np.float32), first)


@pytest.mark.slow
def test_baked_nurbs_sphere_matches_cycles_path_tracing(context, tmp_path):
    """The bake seen through Blender's own mesh and UV map in a render, against Cycles path
    tracing the original sphere: checks the parameter layout, the front side and the light."""
    from test_pipeline import lit_relative_difference, render_exr

    sphere_under_lamp(context)
    context.scene.bsgi.preset = "PREVIEW"
    scenes.add_camera(tilt_degrees=65)
    reference = render_exr(context.scene, tmp_path / "reference.exr", samples=512, bounces=1)
    pipeline.solve_and_bake(context)
    baked = render_exr(context.scene, tmp_path / "baked.exr", samples=16, bounces=0)
    rel, lit = lit_relative_difference(baked, reference, 0.05)
    print(f"\nNURBS sphere, baked vs Cycles (512 spp): mean relative difference {rel.mean():.4f} over {lit.sum()} "
          f"lit pixels; median {np.median(rel):.4f}")
    assert lit.sum() > 0.05 * lit.size
    assert rel.mean() <= 0.064  # measured 0.032


def two_patch_surface(context):
    """One SURFACE object of two flat patches (joined primitives) side by side at z = 0, facing the
    lamp above, with one material slot (both splines use it)."""
    clay = scenes.diffuse_material("Clay", (0.6, 0.5, 0.4))
    parts = []
    for x in (-0.5, 0.5):
        bpy.ops.surface.primitive_nurbs_surface_surface_add(radius=0.5, location=(x, 0, 0))
        parts.append(bpy.context.active_object)
    for part in parts:
        part.select_set(True)
    context.view_layer.objects.active = parts[0]
    bpy.ops.object.join()
    surface = context.view_layer.objects.active
    for spline in surface.data.splines:  # the primitive is a bump: flatten it onto z = 0
        for point in spline.points:
            x, y, _, w = point.co
            point.co = (x, y, 0.0, w)
    surface.data.materials.append(clay)
    assert len(surface.data.splines) == 2
    return surface


def faces_per_spline(obj):
    """Per polygon of Blender's mesh of the surface: its material index, and its corners' (uv, world)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        index = np.empty(len(mesh.polygons), np.int64)
        mesh.polygons.foreach_get("material_index", index)
        loop_face = np.repeat(np.arange(len(mesh.polygons)), [p.loop_total for p in mesh.polygons])
        return index, loop_face
    finally:
        evaluated.to_mesh_clear()


def test_surface_of_several_splines_bakes_each_spline_through_its_own_slot(context):
    """Blender gives each spline's mesh the whole UV square, so each spline is shown through its
    own material slot: the value Blender's mesh shows at each corner (its face's slot's image at
    the corner's UV) is the closed-form direct light there; the user's slots and material indices
    come back when the originals are shown and when the bake is cleared."""
    import sys

    sys.path.insert(0, str(scenes.ROOT / "tests" / "core"))
    from closed_forms import polygon_irradiance

    surface = two_patch_surface(context)
    scenes.add_area_light(location=(0, 0, 1), size=1.0, energy=50.0)
    context.scene.bsgi.preset = "CUSTOM"
    context.scene.bsgi.max_bounces = 0
    rep = pipeline.solve_and_bake(context)
    assert not any("not baked" in w for w in rep["warnings"]), rep["warnings"]
    assert [s.material_index for s in surface.data.splines] == [0, 1]
    assert len(surface.material_slots) == 2
    names = [slot.material.name for slot in surface.material_slots]
    assert names == ["BSGI SurfPatch spline 0", "BSGI SurfPatch spline 1"]

    index, loop_face = faces_per_spline(surface)
    uv, world = mesh_corners(surface)
    assert set(index) == {0, 1}
    lamp = [(-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)]
    worst = 0.0
    for k, name in enumerate(names):
        image = next(n.image for n in bpy.data.materials[name].node_tree.nodes if n.type == "TEX_IMAGE")
        w, h = image.size
        pixels = np.array(image.pixels[:], np.float32).reshape(h, w, 4)
        corners = index[loop_face] == k
        shown = sample_linear_extend(pixels, uv[corners])[:, 0]
        want = np.array([0.6 / math.pi * polygon_irradiance(p, [0, 0, 1], lamp, 50.0 / math.pi)
                         for p in world[corners]])
        worst = max(worst, float(np.max(np.abs(shown - want)) / want.max()))
    print(f"\ntwo-spline surface: shown vs closed form, max difference {worst:.4f} of the maximum")
    assert worst < 0.017  # measured 0.0083

    surface_state = lambda: ([s.material_index for s in surface.data.splines],  # noqa: E731
                             [(slot.link, slot.material.name if slot.material else None)
                              for slot in surface.material_slots])
    context.scene.bsgi.show_baked = False
    assert surface_state() == ([0, 0], [("DATA", "Clay"), ("DATA", None)])
    context.scene.bsgi.show_baked = True
    assert surface_state()[0] == [0, 1]
    bake.clear_bake(surface)
    assert surface_state() == ([0, 0], [("DATA", "Clay")])
    assert not any(m.name.startswith("BSGI") for m in bpy.data.materials)


def floor_with_a_block_through_it(context):
    """A diffuse NURBS floor (Blender's surface patch, 4 x 4 points) with a cube pushed through
    it, turned so its sides are oblique to the floor's parameters, under a lamp."""
    bpy.ops.surface.primitive_nurbs_surface_surface_add(radius=1.0, location=(0, 0, 0))
    floor = bpy.context.active_object
    floor.scale = (2.0, 2.0, 1.0)
    for point in floor.data.splines[0].points:  # flat (the primitive's middle points stand up)
        point.co.z = 0.0
    floor.data.materials.append(scenes.diffuse_material("Plaster", (0.7, 0.7, 0.7)))
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0.2, 0.1, 0.1), rotation=(0.0, 0.0, 0.5))
    bpy.context.active_object.data.materials.append(scenes.diffuse_material("Clay", (0.6, 0.4, 0.3)))
    scenes.add_area_light(location=(-0.5, -0.8, 2.5), size=1.0, energy=400.0)
    context.scene.bsgi.preset = "DRAFT"
    return floor


def test_floor_split_where_a_block_passes_through_bakes_its_pieces(context, tmp_path):
    """The floor is solved in pieces split along the block's sides (bsgi.split) and baked as one
    image: each texel its piece's radiance; the report names the floor once; re-baking from the
    stored pieces and a solution file's round trip give the same image."""
    floor = floor_with_a_block_through_it(context)
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    index = job.export.objects[[o.name for o in job.export.objects].index(floor.name)].patches[0][1]
    assert solution.split.get(index, 0) >= 3
    assert [r["name"] for r in solution.reports].count(job.export.scene.name(index)) == 1
    image = bpy.data.images[f"BSGI {floor.name}"]
    w, h = image.size
    pixels = np.array(image.pixels[:], np.float32).reshape(h, w, 4)
    u, v = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    texels = np.column_stack([u.ravel(), v.ravel()])
    solved = solution.radiance[index].evaluate(texels).reshape(h, w, 3)
    assert np.abs(pixels[..., :3] - solved).max() <= 1e-6 * solved.max()
    # Inside the block's foot the floor is hidden: its texels dark, those beside it lit.
    assert pixels[..., 0].min() < 0.2 * pixels[..., 0].max()

    image.pixels.foreach_set(np.zeros(w * h * 4, np.float32))
    assert bpy.ops.bsgi.rebake() == {"FINISHED"}
    np.testing.assert_array_equal(np.array(image.pixels[:], np.float32).reshape(h, w, 4), pixels)

    from bsgi_addon import solution_file

    path = tmp_path / "split.npz"
    solution_file.export_solution(context.scene, str(path))
    image.pixels.foreach_set(np.zeros(w * h * 4, np.float32))
    solution_file.import_solution(context.scene, str(path))
    np.testing.assert_array_equal(np.array(bpy.data.images[f"BSGI {floor.name}"].pixels[:], np.float32).reshape(h, w, 4),
                                  pixels)
