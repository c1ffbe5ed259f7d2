"""The view-dependent bake (addon/bake.py, view_radiance.py) against the core's own evaluation.

Renders of the baked scene (emission shaders only: one sample at the pixel centre suffices)
are compared pixel by pixel with the solved splines evaluated by the core for the same camera
rays: the rays are computed here from the camera, hit on the core's exact surfaces (RayCaster),
and each hit surface's SurfaceRadiance is evaluated at the hit's (u, v) along the direction to
the camera in the hit's frame (1)-(3). Pixels on silhouettes and face edges are left out: a
pixel counts only if the rays through its centre and its four corners all hit the same face
(a pixel straddling two faces blends them in neither a render nor a point evaluation)."""
import math
from dataclasses import dataclass

import bpy
import numpy as np
import OpenEXR
import pytest

import bsgi
import scenes
from bsgi_addon import bake, charts, geometry, pipeline
from subprocess_render import run_bpy

SIZE = 64
VIEWS = {"front": (0.0, -2.0, 2.0), "side": (1.5, -1.2, 1.6)}
TARGET = (0.0, -0.3, 0.1)  # the cameras look here


def _metal(name, roughness):
    return scenes.metal_material(name, roughness, (0.9, 0.8, 0.7))


def glossy_scene(context):
    """A glossy metal floor (a quad), a glossy triangle standing on it, a diffuse back wall, a
    glossy NURBS sphere, a lamp above."""
    floor = scenes.add_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], _metal("Steel", 0.5))
    scenes.add_quad("Wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 1.5), (-1, 1, 1.5)],
                    scenes.diffuse_material("Grey", (0.6, 0.6, 0.6)))
    wedge = bpy.data.meshes.new("Wedge")
    wedge.from_pydata([(-0.85, 0.1, 0.0), (-0.3, 0.45, 0.0), (-0.6, 0.3, 0.7)], [], [(0, 1, 2)])
    wedge.materials.append(_metal("Iron", 0.5))
    context.scene.collection.objects.link(bpy.data.objects.new("Wedge", wedge))
    bpy.ops.surface.primitive_nurbs_surface_sphere_add(radius=0.25, location=(0.45, 0.35, 0.3))
    ball = bpy.context.active_object
    ball.name = "Ball"
    ball.data.materials.append(_metal("Copper", 0.6))
    lamp = scenes.add_area_light(location=(0, 0, 1.2), size=0.6, energy=120.0)
    lamp.visible_camera = False  # the reference rays see the solved surfaces only
    context.scene.bsgi.preset = "DRAFT"
    return floor, ball


def camera_at(scene, location):
    cam = bpy.data.objects.get("Camera")
    if cam is None:
        cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        scene.collection.objects.link(cam)
    cam.location = location
    direction = np.subtract(TARGET, location)
    cam.rotation_euler = _look_rotation(direction)
    scene.camera = cam
    bpy.context.view_layer.update()
    return cam


def _look_rotation(direction):
    from mathutils import Vector
    return Vector(direction).to_track_quat("-Z", "Y").to_euler()


def camera_rays(scene, cam, offsets=((0.5, 0.5),)):
    """Per offset within the pixel, (origins, directions) of shape (SIZE * SIZE, 3), rows of the
    image from the top as the EXR stores them."""
    frame = [np.array(c) for c in cam.data.view_frame(scene=scene)]  # top right, bottom right, bottom left, top left
    right, top, depth = frame[0][0], frame[0][1], frame[0][2]
    left, bottom = frame[2][0], frame[2][1]
    m = np.array(cam.matrix_world)
    out = []
    for ox, oy in offsets:
        col, row = np.meshgrid(np.arange(SIZE) + ox, np.arange(SIZE) + oy)
        local = np.stack([left + col / SIZE * (right - left), top - row / SIZE * (top - bottom),
                          np.full(col.shape, depth)], axis=-1).reshape(-1, 3)
        d = local @ m[:3, :3].T
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        out.append((np.broadcast_to(m[:3, 3], d.shape).copy(), d))
    return out


@dataclass
class Reference:
    radiance: np.ndarray  # (SIZE, SIZE, 3): the core's evaluation for each pixel's centre ray
    mask: np.ndarray  # pixels whose centre and corners hit one face
    surface: np.ndarray  # the face hit, -1 for none
    position: np.ndarray  # (SIZE, SIZE, 3): where


def core_reference(scene, cam, job, solution) -> Reference:
    surfaces, radiance = [], []
    for exported in job.export.objects:
        obj = bpy.data.objects[exported.name]
        for index, (kind, first, count) in enumerate(exported.patches):
            assert count == 1
            if kind == "nurbs":
                spline = next(s for s in obj.data.splines if s.type == "NURBS")
                surfaces.append(geometry.nurbs_surface(f"{obj.name}", spline, obj.matrix_world))
            elif kind == "chart":
                triangles, loops = charts.loop_triangles(obj.data)
                world = np.array([obj.matrix_world @ v.co for v in obj.data.vertices])
                surfaces.append(bsgi.MeshChart(obj.name, world, triangles, exported.chart_uvs[loops]))
            else:
                co = np.array([obj.matrix_world @ obj.data.vertices[v].co for v in obj.data.polygons[index].vertices])
                surfaces.append(bsgi.BilinearPatch(obj.name, co) if kind == "quad" else bsgi.TrianglePatch(obj.name, co))
            radiance.append(solution.surfaces[first])
    caster = bsgi.RayCaster(surfaces)
    rays = camera_rays(scene, cam, [(0.5, 0.5), (0, 0), (1, 0), (0, 1), (1, 1)])
    hits = [caster.closest_hit(o, d) for o, d in rays]
    same = np.all([h["surface"] == hits[0]["surface"] for h in hits[1:]], axis=0) & (hits[0]["surface"] >= 0)
    centre, d = hits[0], rays[0][1]
    values = np.zeros((len(d), 3))
    for s, r in enumerate(radiance):
        rows = centre["surface"] == s
        if rows.any():
            local = np.einsum("nij,nj->ni", centre["frame"][rows], -d[rows])  # rows x, y, normal: to the viewer
            values[rows] = r.evaluate(np.ascontiguousarray(centre["uv"][rows]), np.ascontiguousarray(local))
    return Reference(values.reshape(SIZE, SIZE, 3), same.reshape(SIZE, SIZE), centre["surface"].reshape(SIZE, SIZE),
                     centre["position"].reshape(SIZE, SIZE, 3))


def setup_render(scene):
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0
    scene.view_settings.gamma = 1
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"


def render_cycles(scene, path):
    setup_render(scene)
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
    scene.cycles.filter_width = 0.01  # every sample at the pixel centre, where the reference ray goes
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_exr(path)


def read_exr(path):
    return OpenEXR.File(str(path)).channels()["RGBA"].pixels[..., :3].astype(np.float64)


def relative_errors(shown, reference, mask):
    """Per-pixel relative error |shown - ref|_1 / |ref|_1 over the masked pixels that are lit
    (above 1% of the brightest reference pixel: relative error means nothing in the dark)."""
    level = reference.sum(axis=2)
    lit = mask & (level > 0.01 * level[mask].max())
    return np.abs(shown - reference).sum(axis=2)[lit] / level[lit], lit


def highlight(image, region):
    """The brightest 3% of the region's pixels: their centroid (row, column) and mask."""
    level = image.sum(axis=2)
    bright = region & (level >= np.percentile(level[region], 97))
    rows, cols = np.nonzero(bright)
    return np.array([rows.mean(), cols.mean()]), bright


# Bounds of check_view, about twice the figures measured (README, "What the bake shows"): mean
# relative error on the glossy and the diffuse pixels, the highlight's distance in pixels.
# Per face (Cycles and EEVEE): 0.69-0.77%, 0.05-0.08%, 0.14 px; one UV chart: 0.41-0.54%, 0.03%, 0.3 px.
FACES_BOUNDS = (0.016, 0.0016, 0.3)
CHART_BOUNDS = (0.011, 0.0007, 0.7)


def check_view(engine, view, shown, ref, job, bounds=FACES_BOUNDS):
    """The error figures and the floor's highlight of one rendered view, against `bounds`
    (glossy, diffuse, pixels); returns where on the floor the highlight is (world space)."""
    glossy_bound, diffuse_bound, pixels_bound = bounds
    glossy_ids, diffuse_ids, floor_id = _ids(job)
    err, lit = relative_errors(shown, ref.radiance, ref.mask)
    ids = ref.surface[lit]
    glossy, diffuse = np.isin(ids, glossy_ids), np.isin(ids, diffuse_ids)
    names = [e.name for e in job.export.objects for _ in e.patches]
    per_object = ", ".join(f"{names[g]} {err[ids == g].mean():.4f} ({(ids == g).sum()} px)" for g in glossy_ids if (ids == g).any())
    print(f"\n{engine}, view '{view}': mean relative error {err[glossy].mean():.4f} on {glossy.sum()} glossy pixels "
          f"(95th percentile {np.percentile(err[glossy], 95):.4f}), {err[diffuse].mean():.4f} on {diffuse.sum()} "
          f"diffuse pixels (95th percentile {np.percentile(err[diffuse], 95):.4f}); {(~ref.mask).sum()} "
          f"edge/background pixels left out; per glossy object: {per_object}")
    assert all((ids == g).sum() > 20 for g in glossy_ids)  # every glossy object is seen
    assert glossy.sum() > 300 and diffuse.sum() > 100
    assert err[glossy].mean() <= glossy_bound
    assert err[diffuse].mean() <= diffuse_bound
    on_floor = ref.mask & (ref.surface == floor_id)
    (shown_at, _), (solved_at, bright) = highlight(shown, on_floor), highlight(ref.radiance, on_floor)
    where = ref.position[bright].mean(axis=0)
    print(f"  floor highlight at pixel {shown_at.round(1)} shown, {solved_at.round(1)} solved; "
          f"on the floor at {where.round(2)}")
    # The highlight is where the core puts it.
    assert np.linalg.norm(shown_at - solved_at) <= pixels_bound
    return where


@pytest.fixture
def solved(context):
    floor, ball = glossy_scene(context)
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    setup_render(context.scene)  # the camera rays follow the render's resolution
    return job, solution, floor, ball


def _ids(job):
    names = [bpy.data.objects[e.name].name for e in job.export.objects for _ in e.patches]
    return ([i for i, n in enumerate(names) if n in ("Floor", "Ball", "Wedge")], [i for i, n in enumerate(names) if n == "Wall"],
            names.index("Floor"))


def test_cycles_shows_the_solved_view_dependent_radiance(solved, tmp_path):
    job, solution, floor, ball = solved
    scene = bpy.context.scene
    where = []
    for view, location in VIEWS.items():
        ref = core_reference(scene, camera_at(scene, location), job, solution)
        where.append(check_view("Cycles", view, render_cycles(scene, tmp_path / f"{view}.exr"), ref, job))
    # The mirror image of the lamp moves over the floor with the view (baked along the normal,
    # it would stay under the lamp).
    assert np.linalg.norm(where[0] - where[1]) > 0.3


def test_rebake_regenerates_the_view_dependent_images(solved):
    job, solution, floor, ball = solved
    names = [f"BSGI {o.name}{suffix}" for o in (floor, ball) for suffix in ("", " tangent", " normal")]
    first = {n: np.array(bpy.data.images[n].pixels[:], np.float32) for n in names}
    w, h = bpy.data.images["BSGI Floor"].size
    samples = bake.angular_samples(bake.stored_faces(floor))
    assert samples > 1 and w == h == samples * bake.tile_size(solution.surfaces[job.export.objects[0].patches[0][1]])
    for n in names:
        bpy.data.images[n].pixels.foreach_set(np.zeros(len(first[n]), np.float32))
    assert bpy.ops.bsgi.rebake() == {"FINISHED"}
    for n in names:
        np.testing.assert_array_equal(np.array(bpy.data.images[n].pixels[:], np.float32), first[n])


def test_toggle_restores_the_users_materials_of_glossy_objects(solved):
    job, solution, floor, ball = solved
    scene = bpy.context.scene
    assert floor.active_material.name == "BSGI Floor" and ball.active_material.name == "BSGI Ball"
    assert bake.UV_NAME in floor.data.uv_layers and len(floor.data.uv_layers) == 1  # the bake's own, nothing else
    scene.bsgi.show_baked = False
    assert floor.material_slots[0].link == "DATA" and floor.active_material.name == "Steel"
    assert ball.material_slots[0].link == "DATA" and ball.active_material.name == "Copper"
    scene.bsgi.show_baked = True
    assert floor.active_material.name == "BSGI Floor"
    bpy.ops.bsgi.clear()
    assert floor.active_material.name == "Steel" and ball.active_material.name == "Copper"
    assert not [i.name for i in bpy.data.images if i.name.startswith("BSGI")]
    assert bake.UV_NAME not in floor.data.uv_layers


EEVEE_RENDER = """\
import sys
import bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[3])
scene = bpy.context.scene
engines = scene.render.bl_rna.properties["engine"].enum_items.keys()
scene.render.engine = "BLENDER_EEVEE" if "BLENDER_EEVEE" in engines else "BLENDER_EEVEE_NEXT"
scene.eevee.taa_render_samples = 1
scene.render.filter_size = 0.0
from mathutils import Vector
# One render per view (output, camera location): one start, one shader compile.
views = sys.argv[4:]
for k in range(0, len(views), 4):
    scene.camera.location = tuple(float(x) for x in views[k + 1:k + 4])
    scene.camera.rotation_euler = (Vector((0.0, -0.3, 0.1)) - scene.camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.render.filepath = views[k]
    bpy.ops.render.render(write_still=True)
result = scene.render.engine
"""


@pytest.mark.slow
def test_eevee_shows_the_solved_view_dependent_radiance(solved, tmp_path):
    job, solution, floor, ball = solved
    scene = bpy.context.scene
    camera_at(scene, VIEWS["front"])
    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    outputs = {view: tmp_path / f"eevee_{view}.exr" for view in VIEWS}
    run = run_bpy(EEVEE_RENDER, args=[str(blend)] + [str(x) for view, location in VIEWS.items()
                                                     for x in (outputs[view], *location)])
    assert run.ok, run.log
    where = []
    for view, location in VIEWS.items():
        ref = core_reference(scene, camera_at(scene, location), job, solution)
        where.append(check_view("EEVEE", view, read_exr(outputs[view]), ref, job))
    assert np.linalg.norm(where[0] - where[1]) > 0.3


def _glass(name, roughness):
    m = bpy.data.materials.new(name)
    if m.node_tree is None:
        m.use_nodes = True
    node = next(n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    node.inputs["Transmission Weight"].default_value = 1.0
    node.inputs["Roughness"].default_value = roughness
    node.inputs["IOR"].default_value = 1.5
    return m


def test_seen_from_below_glass_shows_its_lower_hemisphere_and_metal_black(context, tmp_path):
    """Two sheets under a lamp, seen from below: the rough glass shows the light it transmits
    (its lower-hemisphere spline), the opaque metal its back, which the core evaluates as black."""
    scenes.add_quad("Glass", [(-1, -0.5, 0.5), (0, -0.5, 0.5), (0, 0.5, 0.5), (-1, 0.5, 0.5)], _glass("Frosted", 0.5))
    scenes.add_quad("Metal", [(0.05, -0.5, 0.5), (1.05, -0.5, 0.5), (1.05, 0.5, 0.5), (0.05, 0.5, 0.5)],
                    _metal("Steel", 0.5))
    scenes.add_area_light(location=(0, 0, 1.2), size=0.8, energy=120.0).visible_camera = False
    context.scene.bsgi.preset = "DRAFT"
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    setup_render(context.scene)
    glass, metal = (solution.surfaces[e.patches[0][1]] for e in job.export.objects)
    assert glass.lower is not None and metal.lower is None
    assert bpy.data.images["BSGI Glass"].size[1] == 2 * bpy.data.images["BSGI Glass"].size[0]  # both hemispheres

    scene = context.scene
    camera_at(scene, (0.3, -1.2, -1.0))
    ref = core_reference(scene, scene.camera, job, solution)
    shown = render_cycles(scene, tmp_path / "below.exr")
    seen_glass, seen_metal = ref.mask & (ref.surface == 0), ref.mask & (ref.surface == 1)
    assert seen_glass.sum() > 200 and seen_metal.sum() > 200
    err, lit = relative_errors(shown, ref.radiance, seen_glass)
    print(f"\nglass seen from below: mean relative error {err.mean():.4f} on {lit.sum()} pixels; "
          f"metal's back: largest value {shown[seen_metal].max():.2e} shown, {ref.radiance[seen_metal].max():.2e} solved, "
          f"glass up to {ref.radiance[seen_glass].max():.3f}")
    assert lit.sum() > 200 and err.mean() <= 0.05
    assert ref.radiance[seen_metal].max() == 0 and shown[seen_metal].max() == 0


def _glossy_radiance(rng, spatial=4, angular=12, radius=0.97):
    axes = [bsgi.KnotVector.clamped_uniform(spatial, 2)] * 2 + [bsgi.KnotVector.symmetric(angular, 2, radius)] * 2
    spline = bsgi.TensorSpline(axes)
    spline.coefficients[...] = rng.uniform(0.1, 1.0, spline.coefficients.shape)
    return bsgi.SurfaceRadiance("glossy", radius, spline)


def test_a_large_atlas_gets_fewer_angular_samples_with_a_warning(context, monkeypatch):
    """Without a solve: random glossy splines on a 3 x 3 grid of faces. Past the texel budget the
    angular grid is thinned, and the bake says so naming the object; the tiles still hold the
    splines at their (coarser) samples."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=3, y_subdivisions=3, size=2)
    grid = bpy.context.active_object
    rng = np.random.default_rng(3)
    faces = [("quad", [_glossy_radiance(rng)]) for _ in grid.data.polygons]
    t = bake.tile_size(faces[0][1][0])
    full = bake.angular_samples(faces)
    assert full == 3 * (12 - 2) + 1
    monkeypatch.setattr(bake, "MAX_ATLAS_TEXELS", (3 * t) ** 2 * 100)
    warnings = bake.bake_object(grid, faces)
    assert len(warnings) == 1 and f"'{grid.name}'" in warnings[0] and "10 x 10" in warnings[0], warnings
    image = bpy.data.images[f"BSGI {grid.name}"]
    assert image.size[:] == (10 * 3 * t, 10 * 3 * t)
    pixels = np.array(image.pixels[:], np.float32).reshape(30 * t, 30 * t, 4)
    # Face 4 (the middle tile), its corner (u, v) = (0, 0), at angular sample (i, j) = (2, 7).
    samples = np.linspace(-0.97, 0.97, 10)
    i, j, size = 2, 7, 3 * t
    expected = faces[4][1][0].upper.evaluate(np.array([[0.0, 0.0, samples[i], samples[j]]]))[0]
    np.testing.assert_allclose(pixels[j * size + t, i * size + t, :3], expected, rtol=1e-6)


def test_rebake_reads_splines_stored_before_view_dependent_baking(context):
    """Files baked by the add-on before this bake stored the upper spline alone per face."""
    floor = scenes.add_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    faces = [("quad", [_glossy_radiance(np.random.default_rng(5))])]
    bake.bake_object(floor, faces)
    first = np.array(bpy.data.images["BSGI Floor"].pixels[:], np.float32)
    arrays = bsgi.spline_to_arrays(faces[0][1][0].upper)
    arrays["degrees"] = arrays["degrees"].astype(np.int32)
    floor[bake.PROP_RADIANCE] = {"kinds": "quad", "0.0": arrays}
    bake.rebake(floor)
    np.testing.assert_array_equal(np.array(bpy.data.images["BSGI Floor"].pixels[:], np.float32), first)
    assert bake.stored_faces(floor)[0][1][0].kind == "glossy"


def test_cycles_shows_a_glossy_uv_chart(context, tmp_path):
    """A glossy floor of 6 x 6 faces solved as one UV chart (its own UV map): one spline, one
    atlas of angular tiles over the chart's UV square, seen through the chart's UVs."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=6, y_subdivisions=6, size=2)
    floor = bpy.context.active_object
    floor.name = "Floor"
    floor.data.materials.append(_metal("Steel", 0.5))
    floor.bsgi.mesh_surfaces = "CHART"
    scenes.add_quad("Wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 1.5), (-1, 1, 1.5)],
                    scenes.diffuse_material("Grey", (0.6, 0.6, 0.6)))
    scenes.add_area_light(location=(0, 0, 1.2), size=0.6, energy=120.0).visible_camera = False
    context.scene.bsgi.preset = "DRAFT"
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    setup_render(context.scene)
    assert job.export.objects[0].patches[0][0] == "chart"
    assert bake.angular_samples(bake.stored_faces(floor)) > 1
    scene = context.scene
    where = []
    for view, location in VIEWS.items():
        ref = core_reference(scene, camera_at(scene, location), job, solution)
        where.append(check_view("Cycles, UV chart", view, render_cycles(scene, tmp_path / f"{view}.exr"), ref, job,
                                CHART_BOUNDS))
    assert np.linalg.norm(where[0] - where[1]) > 0.3


def test_atlas_tiles_hold_the_decomposed_and_lower_radiance_along_their_directions(context):
    """Without a solve: a decomposed surface (D(u, v) + S(u, v, alpha, beta), (38)) and a
    transmitting one (a lower-hemisphere spline). Each angular tile holds what the core's
    SurfaceRadiance.evaluate gives along the direction the map sends its sample to (upper tiles),
    and along that direction mirrored below the surface (lower tiles)."""
    rng = np.random.default_rng(7)
    glossy = _glossy_radiance(rng)
    diffuse = bsgi.TensorSpline([bsgi.KnotVector.clamped_uniform(4, 2)] * 2)
    diffuse.coefficients[...] = rng.uniform(0.1, 1.0, diffuse.coefficients.shape)
    decomposed = bsgi.SurfaceRadiance("decomposed", glossy.disc_radius, glossy.upper, None, diffuse)
    transmitting = bsgi.SurfaceRadiance("glossy", glossy.disc_radius, glossy.upper, _glossy_radiance(rng).upper)
    hemisphere = bsgi.HemisphereMap(glossy.disc_radius)
    for name, radiance, sides in (("Plastic", decomposed, 1), ("Frosted", transmitting, 2)):
        quad = scenes.add_quad(name, [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
        faces = [("quad", [radiance])]
        bake.bake_object(quad, faces)
        t, a = bake.tile_size(radiance), bake.angular_samples(faces)
        pixels = np.array(bpy.data.images[f"BSGI {name}"].pixels[:], np.float32).reshape(sides * a * t, a * t, 4)
        grid = np.linspace(-glossy.disc_radius, glossy.disc_radius, a)
        for i, j in [(a // 2, a // 2), (a // 3, a // 2 + 3), (2 * a // 3, a // 4)]:
            assert math.hypot(grid[i], grid[j]) < glossy.disc_radius
            direction = hemisphere.to_direction(np.array([[grid[i], grid[j]]]))[0]
            for side in range(sides):
                d = direction * (1, 1, -1) if side else direction
                expected = radiance.evaluate(np.array([[1.0, 0.0]]), d[None])[0]
                shown = pixels[(side * a + j) * t, i * t + t - 1, :3]
                np.testing.assert_allclose(shown, expected, rtol=1e-6)
