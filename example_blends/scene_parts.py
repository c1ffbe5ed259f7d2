"""Parts the example scene generators share: materials, quads and boxes, NURBS surfaces (of
revolution, swept tubes, Bézier patches), area lights, a camera, render settings, and the
command line every `make_*.py` script takes:

    .venv/bin/python example_blends/make_X.py [--if-missing] [--out-dir DIR]
"""
from __future__ import annotations

import math
import pathlib
import sys

import bpy
import numpy as np
from mathutils import Vector

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from shapes import box_quads, rectangle  # noqa: E402,F401  (re-exported for the make_*.py scripts)

HERE = pathlib.Path(__file__).resolve().parent
# Weight of the corner points of a rational quadratic arc of 90 degrees (Blender's NURBS circle).
CORNER_WEIGHT = math.sqrt(0.5)


def _node_tree(material):
    if material.node_tree is None:  # Blender 4.x: materials start without nodes
        material.use_nodes = True
    return material.node_tree


def _shader_material(name, node_type, rgb, inputs):
    m = bpy.data.materials.new(name)
    tree = _node_tree(m)
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    shader = tree.nodes.new(node_type)
    for key, value in inputs.items():
        shader.inputs[key].default_value = value
    tree.links.new(shader.outputs[0], out.inputs["Surface"])
    m.diffuse_color = (*rgb, 1.0)  # the viewport's Solid mode colour
    return m


def diffuse_material(name, rgb):
    return _shader_material(name, "ShaderNodeBsdfDiffuse", rgb, {"Color": (*rgb, 1.0)})


def principled_material(name, rgb, **inputs):
    """A Principled BSDF; inputs by socket name with spaces as underscores (Transmission_Weight=1)."""
    sockets = {key.replace("_", " "): value for key, value in inputs.items()}
    return _shader_material(name, "ShaderNodeBsdfPrincipled", rgb, {"Base Color": (*rgb, 1.0), **sockets})


def emission_material(name, rgb, strength):
    return _shader_material(name, "ShaderNodeEmission", rgb, {"Color": (*rgb, 1.0), "Strength": strength})


def wave_bump(tree, shader, scale, strength, distance):
    """Bumps `shader`'s normal by a Wave Texture's bands over the UVs (Bump node of that strength
    and distance): ribs, a rug's weave, planks."""
    coords = tree.nodes.new("ShaderNodeTexCoord")
    wave = tree.nodes.new("ShaderNodeTexWave")
    wave.inputs["Scale"].default_value = scale
    tree.links.new(coords.outputs["UV"], wave.inputs["Vector"])
    bump = tree.nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = strength
    bump.inputs["Distance"].default_value = distance
    tree.links.new(wave.outputs["Fac"], bump.inputs["Height"])
    tree.links.new(bump.outputs["Normal"], shader.inputs["Normal"])
    return bump


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def quad_object(name, quads, materials, material_of_quad):
    """A mesh object of quads given as 4 corners each, counter-clockwise seen from the lit side."""
    verts, faces = [], []
    for q in quads:
        faces.append(tuple(range(len(verts), len(verts) + 4)))
        verts.extend(q)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    for m in materials:
        mesh.materials.append(m)
    for poly, k in zip(mesh.polygons, material_of_quad):
        poly.material_index = k
    mesh.update()
    return link(bpy.data.objects.new(name, mesh))


def nurbs_object(name, points, order_u, order_v, material=None, *, endpoint=(True, True), bezier=(False, False),
                 cyclic=(False, False)):
    """A SURFACE object of one NURBS spline. points: (count_v, count_u, 4) rows of Cartesian
    (x, y, z) and weight, u fastest as Blender stores them. Blender's Python API cannot set a
    surface's point counts, so the spline is made as Blender's editor makes one: a row of
    count_u points extruded count_v - 1 times."""
    points = np.asarray(points, float)
    count_v, count_u = points.shape[:2]
    curve = bpy.data.curves.new(name, "SURFACE")
    curve.dimensions = "3D"
    spline = curve.splines.new("NURBS")
    spline.points.add(count_u - 1)
    obj = link(bpy.data.objects.new(name, curve))
    if count_v > 1:
        view_layer = bpy.context.view_layer
        previous = view_layer.objects.active
        view_layer.objects.active = obj
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.curve.select_all(action="SELECT")
        for _ in range(count_v - 1):
            bpy.ops.curve.extrude()
        bpy.ops.object.mode_set(mode="OBJECT")
        view_layer.objects.active = previous
    spline = curve.splines[0]
    if (spline.point_count_u, spline.point_count_v) != (count_u, count_v):
        raise RuntimeError(f"{name}: made {spline.point_count_u} x {spline.point_count_v} points, "
                           f"wanted {count_u} x {count_v}")
    spline.points.foreach_set("co", points.reshape(-1))
    spline.order_u, spline.order_v = order_u, order_v
    spline.use_endpoint_u, spline.use_endpoint_v = endpoint
    spline.use_bezier_u, spline.use_bezier_v = bezier
    spline.use_cyclic_u, spline.use_cyclic_v = cyclic
    spline.resolution_u = spline.resolution_v = 8
    spline.use_smooth = True
    for p in spline.points:
        p.select = False
    if material is not None:
        curve.materials.append(material)
    return obj


def join(name, objects):
    """One object of the objects' splines (or faces), as Blender's Join makes it; named name."""
    view_layer = bpy.context.view_layer
    for obj in view_layer.objects:
        obj.select_set(obj in objects)
    view_layer.objects.active = objects[0]
    bpy.ops.object.join()
    joined = view_layer.objects.active
    joined.name = joined.data.name = name
    joined.select_set(False)
    return joined


def circle_points(radius):
    """Blender's exact NURBS circle (as in its NURBS sphere): 8 points of a cyclic quadratic
    curve in Bézier mode, counter-clockwise seen from +z from angle 180 degrees, (x, y, weight)."""
    rows = []
    for j in range(8):
        angle = math.pi + j * math.pi / 4
        r, w = (radius, 1.0) if j % 2 == 0 else (radius * math.sqrt(2), CORNER_WEIGHT)
        rows.append((r * math.cos(angle), r * math.sin(angle), w))
    return rows


def revolution_object(name, profile, material=None, *, centre=(0.0, 0.0, 0.0), order=3, bezier=True):
    """A surface of revolution about the vertical axis through centre (the object's origin): u
    runs along the profile, rows of (radius, height, weight), v around Blender's exact circle. A
    profile running upwards on the outside gives outward normals (Blender's face normal
    -(s_u x s_v))."""
    # The unit circle's points (corners at sqrt 2) scaled by each profile row's radius.
    points = [[(x * r, y * r, z, w * wc) for r, z, w in profile] for x, y, wc in circle_points(1.0)]
    obj = nurbs_object(name, points, order, 3, material, endpoint=(True, True), bezier=(bezier, True),
                       cyclic=(False, True))
    obj.location = centre
    return obj


def arc_profile(centre_z, radius, start_angle, end_angle, pieces):
    """A circular arc in the (radius, height) plane as rational quadratic Bézier rows
    (2 * pieces + 1 rows, the first included); angles from the upward vertical, clockwise
    towards +radius, in radians, each piece of (end - start) / pieces below 180 degrees."""
    step = (end_angle - start_angle) / pieces
    rows = []
    for k in range(pieces):
        a0, a1 = start_angle + k * step, start_angle + (k + 1) * step
        mid = (a0 + a1) / 2
        half = step / 2
        if k == 0:
            rows.append((radius * math.sin(a0), centre_z + radius * math.cos(a0), 1.0))
        d = radius / math.cos(half)  # the tangents' intersection
        rows.append((d * math.sin(mid), centre_z + d * math.cos(mid), math.cos(half)))
        rows.append((radius * math.sin(a1), centre_z + radius * math.cos(a1), 1.0))
    return rows


def tube_object(name, path, radius, material=None):
    """A tube of circular section swept along path ((n, 3) points of an open quadratic NURBS
    curve with end points, in the (x, z) plane): u along the path, v around the section, so the
    normals point outwards. The section's plane is spanned by the path's in-plane normal and y."""
    path = np.asarray(path, float)
    tangents = np.gradient(path, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    side = np.array([0.0, 1.0, 0.0])
    points = []
    for x, y, w in circle_points(radius):
        row = []
        for p, t in zip(path, tangents):
            normal = np.cross(side, t)  # in the path's plane, perpendicular to it
            q = p + x * normal + y * side
            row.append((*q, w))
        points.append(row)
    return nurbs_object(name, points, 3, 3, material, endpoint=(True, True), bezier=(False, True), cyclic=(False, True))


def object_settings(obj, **settings):
    """The add-on's per-object options (Object Properties > B-spline GI), e.g. angular_coeffs=12.
    They are the add-on's properties, so it is registered first (addon/cli.py loads it)."""
    sys.path.insert(0, str(HERE.parent / "addon"))
    import cli

    try:
        cli.load_addon().register()
    except ValueError:
        pass  # already registered in this session
    for key, value in settings.items():
        setattr(obj.bsgi, key, value)
    return obj


def area_light(name, location, energy, *, shape="RECTANGLE", size=0.5, size_y=None, rotation=(0.0, 0.0, 0.0),
               color=(1.0, 1.0, 1.0)):
    """An area light; Blender's emit along their local -z."""
    light = bpy.data.lights.new(name, "AREA")
    light.shape = shape
    light.size = size
    if size_y is not None:
        light.size_y = size_y
    light.energy = energy
    light.color = color
    obj = bpy.data.objects.new(name, light)
    obj.location = location
    obj.rotation_euler = rotation
    return link(obj)


def camera(location, target, lens=45.0):
    cam = bpy.data.cameras.new("Camera")
    cam.lens = lens
    obj = link(bpy.data.objects.new("Camera", cam))
    obj.location = location
    direction = Vector(target) - Vector(location)
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    bpy.context.scene.camera = obj
    return obj


def render_settings(scene, resolution=(512, 512)):
    """A black world (the examples are lit by their lamps alone, as the study's Mitsuba scenes), Cycles,
    the Standard view transform (baked radiance is shown as it is)."""
    world = bpy.data.worlds.new("Black")
    world.color = (0, 0, 0)
    if world.node_tree is not None:  # 5.x worlds start with a grey Background node
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 64
    scene.view_settings.view_transform = "Standard"
    scene.render.resolution_x, scene.render.resolution_y = resolution
    return scene


def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def save(path):
    """Saved compressed, with no packed images (image files are referenced relative to the scene), and no
    .blend1 backup."""
    bpy.context.preferences.filepaths.save_version = 0
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    if any(image.filepath for image in bpy.data.images):  # image files: found relative to the scene
        bpy.ops.file.make_paths_relative()
        bpy.ops.wm.save_mainfile(compress=True)
    print(f"wrote {path}")


def main(builders: dict, argv=None):
    """builders: .blend file name -> function building that scene. --if-missing skips files that
    exist; --out-dir writes elsewhere than beside the scripts."""
    argv = sys.argv[1:] if argv is None else argv
    out_dir = pathlib.Path(argv[argv.index("--out-dir") + 1]) if "--out-dir" in argv else HERE
    for file_name, build in builders.items():
        path = out_dir / file_name
        if "--if-missing" in argv and path.exists():
            continue
        build()
        save(path)
