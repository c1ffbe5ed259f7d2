"""addon/tangents.py: Blender's default tangent of anisotropic BSDFs, against Cycles' own Tangent
node, and the solver's lobe turned onto it."""
import math

import bpy
import numpy as np
import pytest

import bsgi
from bsgi_addon import geometry, materials, tangents

SIZE = 16


def _tilted_rectangle():
    """A 2 x 1 rectangle (object space z = 0), moved, turned and scaled unevenly, UVs over it."""
    mesh = bpy.data.meshes.new("Brushed")
    corners = [(-1.0, -0.5, 0.0), (1.0, -0.5, 0.0), (1.0, 0.5, 0.0), (-1.0, 0.5, 0.0)]
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        x, y, _ = corners[loop.vertex_index]
        uv.data[loop.index].uv = ((x + 1) / 2, y + 0.5)
    obj = bpy.data.objects.new("Brushed", mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = (3.0, -1.0, 0.5)
    obj.rotation_euler = (math.radians(30), 0.0, math.radians(20))
    obj.scale = (1.5, 0.7, 1.0)
    bpy.context.view_layer.update()
    return obj, np.array(corners)


def _bake_tangent_node(obj) -> np.ndarray:
    """Cycles' Tangent node (radial about Z, the default of anisotropic BSDFs) baked as emission
    0.5 + 0.5 T into a float image: (SIZE, SIZE, 3) world-space tangents, rows along v."""
    m = bpy.data.materials.new("Tangent")
    m.use_nodes = True
    nodes, links = m.node_tree.nodes, m.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    emission = nodes.new("ShaderNodeEmission")
    tangent = nodes.new("ShaderNodeTangent")
    tangent.direction_type, tangent.axis = "RADIAL", "Z"
    half = nodes.new("ShaderNodeVectorMath")
    half.operation = "MULTIPLY_ADD"
    half.inputs[1].default_value = (0.5, 0.5, 0.5)
    half.inputs[2].default_value = (0.5, 0.5, 0.5)
    links.new(tangent.outputs[0], half.inputs[0])
    links.new(half.outputs[0], emission.inputs["Color"])
    links.new(emission.outputs[0], out.inputs["Surface"])
    image = bpy.data.images.new("tangent", SIZE, SIZE, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    node = nodes.new("ShaderNodeTexImage")
    node.image = image
    nodes.active = node
    obj.data.materials.append(m)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 1
    scene.render.bake.margin = 0
    for o in scene.objects:
        o.select_set(o == obj)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.bake(type="EMIT")
    pixels = np.array(image.pixels[:]).reshape(SIZE, SIZE, 4)[..., :3]
    return 2 * pixels - 1


def test_radial_tangent_is_cycles_tangent_node(context):
    obj, corners = _tilted_rectangle()
    baked = _bake_tangent_node(obj)
    g = (np.arange(SIZE) + 0.5) / SIZE
    u, v = np.meshgrid(g, g)  # pixel (row, column) = (v, u)
    local = np.stack([2 * u - 1, v - 0.5, np.zeros_like(u)], axis=-1).reshape(-1, 3)
    m = np.array(obj.matrix_world, float)
    world = local @ m[:3, :3].T + m[:3, 3]
    radial = tangents.RadialTangent(m, [tuple(c) for c in obj.bound_box]).at(world)
    normal = np.cross(m[:3, 0], m[:3, 1])
    normal /= np.linalg.norm(normal)
    expected = radial - np.outer(radial @ normal, normal)
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    got = baked.reshape(-1, 3)
    got /= np.linalg.norm(got, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", got, expected)), 0, 1)))
    print(f"\nradial tangent vs Cycles' Tangent node: max {angle.max():.3f} deg, mean {angle.mean():.3f} deg")
    # Half-float-free float image, one sample of an emission: only rounding is left.
    assert angle.max() < 0.26  # measured 0.132 degrees (mean 0.015)


def test_rotation_onto_tangents_in_the_frame():
    x = np.array([[1.0, 0, 0]] * 3)
    y = np.array([[0, 1.0, 0]] * 3)
    t = np.array([[0.0, 2.0, 0], [0.0, -1.0, 0.3], [0.1, 1.0, 0]])  # about +-90 degrees
    angle, spread = tangents.rotation_onto(t, x, y)
    assert abs(abs(angle) - math.pi / 2) < 0.05 and spread < 0.1
    assert tangents.rotation_onto(np.zeros((2, 3)), x[:2], y[:2]) == (0.0, 0.0)  # on the axis


def _lobe_width(bsdf, axis):
    """The GGX lobe's value at a fixed tilt of wi from the mirror direction along a local axis."""
    wo = np.array([[0.0, 0.0, 1.0]])
    tilt = 0.35
    wi = np.array([[tilt * axis[0], tilt * axis[1], 1.0]])
    wi /= np.linalg.norm(wi)
    return float(bsdf.eval(wo, wi)[0].mean())


def test_anisotropic_sphere_of_revolution_follows_blenders_parallels(context):
    # A NURBS sphere of revolution about Z: its u runs along the meridians, Blender's default
    # tangent along the parallels. Principled anisotropy widens the lobe along the tangent, so the
    # solved lobe must be wider along the frame's y (the parallels) than along x (ds/du).
    bpy.ops.surface.primitive_nurbs_surface_sphere_add(radius=1.0, location=(0.5, 0.2, 1.0))
    obj = bpy.context.active_object
    m = bpy.data.materials.new("Brushed")
    m.use_nodes = True
    node = next(n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    node.inputs["Metallic"].default_value = 1.0
    node.inputs["Roughness"].default_value = 0.5
    node.inputs["Anisotropic"].default_value = 0.8
    obj.data.materials.append(m)
    bpy.context.view_layer.update()
    warnings = []
    slots = materials.object_materials(obj, obj.matrix_world, warnings, obj.name, {})
    surface = geometry.nurbs_surface("sphere", obj.data.splines[0], obj.matrix_world)
    frames = surface.evaluate(np.array([[0.3, 0.2], [0.5, 0.7]]))
    parallel = np.cross([0.0, 0.0, 1.0], frames["position"] - np.array(obj.location))
    across = np.abs(np.einsum("ij,ij->i", frames["x"], parallel)) / np.linalg.norm(parallel, axis=1)
    assert across.max() < 0.1, "the test assumes ds/du along the meridians"
    bsdf = slots.for_surface(0, surface)["bsdf"]
    along_x, along_y = _lobe_width(bsdf, (1, 0)), _lobe_width(bsdf, (0, 1))
    print(f"\nGGX at a tilt along ds/du {along_x:.4f}, along the parallels {along_y:.4f}")
    assert along_y > 1.5 * along_x
    # Without the turn the lobe would be wider along ds/du: the test can tell the two apart.
    plain = slots.keywords[0]["bsdf"]
    assert _lobe_width(plain, (1, 0)) > 1.5 * _lobe_width(plain, (0, 1))
    assert not any("turns by up to" in w for w in warnings)
