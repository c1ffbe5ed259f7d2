"""Instances from the depsgraph (collection instances, geometry-nodes instances): solved at their
world matrices with their own materials (they cast shadows and reflect light), not baked (their
mesh is shared), with a warning naming the object and its instancer."""
import math

import bpy
import numpy as np
import pytest

import bsgi
import scenes
from bsgi_addon import bake, export, pipeline


def blocker_collection():
    """A 0.5 x 0.5 quad (material 'Red') in a collection that is not in the scene itself."""
    red = scenes.diffuse_material("Red", (0.8, 0.1, 0.1))
    mesh = bpy.data.meshes.new("Blocker")
    mesh.from_pydata([(-0.25, -0.25, 0), (0.25, -0.25, 0), (0.25, 0.25, 0), (-0.25, 0.25, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(red)
    blocker = bpy.data.objects.new("Blocker", mesh)
    collection = bpy.data.collections.new("Props")
    collection.objects.link(blocker)
    return collection, blocker


def collection_instance(collection, name, location):
    empty = bpy.data.objects.new(name, None)
    empty.instance_type = "COLLECTION"
    empty.instance_collection = collection
    empty.location = location
    bpy.context.scene.collection.objects.link(empty)
    return empty


def surfaces(result, prefix):
    return [i for i in range(len(result.scene)) if result.scene.name(i).startswith(prefix)]


def test_collection_instances_are_solved_at_their_world_matrix_and_named_in_a_warning(context):
    floor = scenes.floor_under_lamp()
    collection, _ = blocker_collection()
    collection_instance(collection, "Shelf", (0.3, -0.2, 0.5))
    result = export.export_scene(context.evaluated_depsgraph_get())
    ids = surfaces(result, "Blocker")
    assert len(ids) == 1 and result.scene.name(ids[0]) == "Blocker (instance 0 of 'Shelf'): face 0"
    np.testing.assert_allclose(result.scene.evaluate_surface(ids[0], 0.5, 0.5)["position"], [0.3, -0.2, 0.5],
                               atol=1e-12)
    assert result.scene.area(ids[0]) == pytest.approx(0.25)
    assert [o.name for o in result.objects] == [floor.name]  # the bake targets: real objects only
    text = "\n".join(result.warnings)
    assert "object 'Blocker': 1 instance from 'Shelf' is solved" in text and "not baked" in text


def test_instances_cast_shadows_and_are_not_baked(context):
    floor = scenes.floor_under_lamp()  # a 1 x 1 lamp at height 1 over a 2 x 2 floor
    context.scene.bsgi.preset = "CUSTOM"
    context.scene.bsgi.max_bounces = 0

    def floor_centre():
        job = pipeline.prepare(context)
        solution = pipeline.run(job)
        spline = solution.radiance[job.export.objects[0].patches[0][1]]
        return spline.evaluate(np.array([[0.5, 0.5]]))[0, 0]

    lit = floor_centre()
    collection, blocker = blocker_collection()
    collection_instance(collection, "Shelf", (0, 0, 0.5)).scale = (2, 2, 1)  # a 1 x 1 blocker half way up
    shadowed = floor_centre()
    # Its umbra on the floor is the square |x|, |y| <= 0.5 (the lamp seen past its edges from
    # there); the spline blurs the shadow's edge over a few knot spans, so the centre keeps a little.
    assert shadowed < 0.05 * lit
    rep = pipeline.solve_and_bake(context)
    assert bake.is_baked(floor) and not bake.is_baked(blocker) and rep["objects"] == 1
    assert any("'Blocker'" in w and "'Shelf'" in w for w in rep["warnings"])


def geometry_nodes_scatter(instanced, points):
    """A mesh of loose points with a geometry-nodes modifier instancing `instanced` on each."""
    mesh = bpy.data.meshes.new("Points")
    mesh.from_pydata(points, [], [])
    scatter = bpy.data.objects.new("Scatter", mesh)
    bpy.context.scene.collection.objects.link(scatter)
    tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    group_in, group_out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    on_points, info = tree.nodes.new("GeometryNodeInstanceOnPoints"), tree.nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = instanced
    tree.links.new(group_in.outputs[0], on_points.inputs["Points"])
    tree.links.new(info.outputs["Geometry"], on_points.inputs["Instance"])
    tree.links.new(on_points.outputs[0], group_out.inputs[0])
    scatter.modifiers.new("Scatter", "NODES").node_group = tree
    return scatter


def test_geometry_nodes_instances_carry_their_meshs_material(context):
    scenes.floor_under_lamp()
    _, blocker = blocker_collection()
    geometry_nodes_scatter(blocker, [(-0.5, 0, 0.4), (0.5, 0, 0.4)])
    result = export.export_scene(context.evaluated_depsgraph_get())
    ids = surfaces(result, "Scatter (instance")
    assert len(ids) == 2
    centres = sorted(tuple(result.scene.evaluate_surface(i, 0.5, 0.5)["position"]) for i in ids)
    np.testing.assert_allclose(centres, [(-0.5, 0, 0.4), (0.5, 0, 0.4)], atol=1e-12)
    assert any("object 'Scatter': 2 instances from 'Scatter'" in w for w in result.warnings)
    # The instances reflect the red of the instanced mesh's material: seen from below, lit by the
    # floor's grey, their red channel far above their green (the instancer has no material).
    context.scene.bsgi.preset = "DRAFT"
    solution = bsgi.solve(result.scene, context.scene.bsgi.solver_settings())
    lower = solution.radiance[ids[0]].evaluate(np.array([[0.5, 0.5]]))[0]
    assert lower[0] > 4 * lower[1] > 0


def test_particle_instances_are_solved(context):
    scenes.floor_under_lamp()
    _, blocker = blocker_collection()
    emitter = scenes.add_quad("Emitter", [(-1, -1, 0.3), (1, -1, 0.3), (1, 1, 0.3), (-1, 1, 0.3)])
    emitter.modifiers.new("Particles", "PARTICLE_SYSTEM")
    settings = emitter.particle_systems[0].settings
    settings.type = "HAIR"  # static positions, no simulation
    settings.count = 3
    settings.render_type = "OBJECT"
    settings.instance_object = blocker
    emitter.show_instancer_for_render = emitter.show_instancer_for_viewport = False
    result = export.export_scene(context.evaluated_depsgraph_get())
    ids = surfaces(result, "Blocker (instance")
    assert len(ids) == 3
    assert not surfaces(result, "Emitter")  # the instancer is not shown, so not solved
    heights = [result.scene.evaluate_surface(i, 0.5, 0.5)["position"][2] for i in ids]
    assert heights == pytest.approx([0.3] * 3, abs=1e-6)  # on the emitter's surface
    assert any("object 'Blocker': 3 instances from 'Emitter'" in w for w in result.warnings)


def test_instanced_nurbs_surface_is_solved_once_exactly(context):
    """Blender lists a SURFACE object's evaluated mesh beside it (also inside a collection
    instance): the surface is solved once, as its exact NURBS, not again as that mesh."""
    scenes.floor_under_lamp()
    bpy.ops.surface.primitive_nurbs_surface_surface_add(radius=0.3)
    patch = bpy.context.active_object
    collection = bpy.data.collections.new("Patches")
    collection.objects.link(patch)
    context.scene.collection.objects.unlink(patch)
    collection_instance(collection, "Holder", (0, 0, 0.5))
    result = export.export_scene(context.evaluated_depsgraph_get())
    names = [result.scene.name(i) for i in range(len(result.scene))]
    assert sorted(names) == ["Floor: face 0", "Lamp", "SurfPatch (instance 0 of 'Holder'): spline 0"]


def test_instances_made_real_are_baked_each_with_its_own_light(context):
    """What the warning advises: Make Instances Real gives objects sharing one mesh; each bakes
    its own image (the bake's UV layout depends on the mesh only), lit as its place is."""
    scenes.floor_under_lamp()
    collection, _ = blocker_collection()
    for name, x in (("Near", 0.0), ("Far", 1.5)):
        collection_instance(collection, name, (x, 0, 0.5)).rotation_euler = (math.pi, 0, 0)  # facing the floor
    holders = [bpy.data.objects["Near"], bpy.data.objects["Far"]]
    with context.temp_override(selected_editable_objects=holders, active_object=holders[0]):
        assert bpy.ops.object.duplicates_make_real() == {"FINISHED"}
    real = [o for o in context.scene.objects if o.type == "MESH" and o.name.startswith("Blocker")]
    assert len(real) == 2 and real[0].data == real[1].data
    context.scene.bsgi.preset = "DRAFT"
    rep = pipeline.solve_and_bake(context)
    assert not any("instance" in w for w in rep["warnings"])
    radiance = {o.name: bake.stored_faces(o)[0][1][0].upper.evaluate(np.array([[0.5, 0.5]]))[0, 0] for o in real}
    images = {o.name: o.material_slots[0].material.name for o in real}
    assert len(set(images.values())) == 2
    near = min(real, key=lambda o: abs(o.matrix_world.translation.x))
    far = max(real, key=lambda o: abs(o.matrix_world.translation.x))
    # Both see the floor below; the one right under the lamp sees it brightest.
    assert radiance[near.name] > radiance[far.name] > 0
