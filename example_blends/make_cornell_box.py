"""Generates cornell_box.blend beside this file: a Cornell box of quads with diffuse coloured
materials, two boxes, one rectangular area light and a camera. Run with the `bpy` module:

    .venv/bin/python example_blends/make_cornell_box.py [--if-missing]
"""
from __future__ import annotations

import math
import pathlib
import sys

import bpy

HERE = pathlib.Path(__file__).resolve().parent
OUT = HERE / "cornell_box.blend"


def diffuse_material(name, rgb):
    m = bpy.data.materials.new(name)
    if m.node_tree is None:  # Blender 4.x: materials start without nodes
        m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*rgb, 1.0)
    m.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    m.diffuse_color = (*rgb, 1.0)
    return m


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
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def box_quads(cx, cy, sx, sy, h, angle):
    """A closed box standing on the floor, rotated by angle about z, outward normals."""
    c, s = math.cos(angle), math.sin(angle)

    def p(x, y, z):
        return (cx + c * x - s * y, cy + s * x + c * y, z)

    a, b = sx / 2, sy / 2
    bottom = [p(-a, -b, 0), p(-a, b, 0), p(a, b, 0), p(a, -b, 0)]
    top = [p(-a, -b, h), p(a, -b, h), p(a, b, h), p(-a, b, h)]
    sides = [
        [p(-a, -b, 0), p(a, -b, 0), p(a, -b, h), p(-a, -b, h)],
        [p(a, -b, 0), p(a, b, 0), p(a, b, h), p(a, -b, h)],
        [p(a, b, 0), p(-a, b, 0), p(-a, b, h), p(a, b, h)],
        [p(-a, b, 0), p(-a, -b, 0), p(-a, -b, h), p(-a, b, h)],
    ]
    return [bottom, top] + sides


def build():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    white = diffuse_material("White", (0.73, 0.73, 0.73))
    red = diffuse_material("Red", (0.63, 0.065, 0.05))
    green = diffuse_material("Green", (0.14, 0.45, 0.091))
    # Room: x, y in [-1, 1], z in [0, 2], open towards the camera at y = -1.
    room = [
        [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)],  # floor, normal +z
        [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)],  # ceiling, normal -z
        [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)],  # back, normal -y
        [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)],  # left, normal +x
        [(1, 1, 0), (1, -1, 0), (1, -1, 2), (1, 1, 2)],  # right, normal -x
    ]
    quad_object("Room", room, [white, red, green], [0, 0, 0, 1, 2])
    quad_object("TallBox", box_quads(-0.35, 0.35, 0.6, 0.6, 1.2, math.radians(-17)), [white], [0] * 6)
    quad_object("ShortBox", box_quads(0.35, -0.35, 0.6, 0.6, 0.6, math.radians(17)), [white], [0] * 6)

    light = bpy.data.lights.new("Light", "AREA")
    light.shape = "RECTANGLE"
    light.size, light.size_y = 0.5, 0.4
    light.energy = 30.0
    light_obj = bpy.data.objects.new("Light", light)
    light_obj.location = (0, 0, 1.98)  # emits along -z, just below the ceiling
    scene.collection.objects.link(light_obj)

    cam = bpy.data.cameras.new("Camera")
    cam.lens = 45
    cam_obj = bpy.data.objects.new("Camera", cam)
    cam_obj.location = (0, -3.6, 1.0)
    cam_obj.rotation_euler = (math.radians(90), 0, 0)
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj

    world = bpy.data.worlds.new("Black")
    world.color = (0, 0, 0)
    if world.node_tree is not None:  # 5.x worlds start with a grey Background node
        world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.view_settings.view_transform = "Standard"
    scene.render.resolution_x = scene.render.resolution_y = 512
    return scene


if __name__ == "__main__":
    if "--if-missing" in sys.argv and OUT.exists():
        sys.exit(0)
    build()
    bpy.ops.wm.save_as_mainfile(filepath=str(OUT))
    print(f"wrote {OUT}")
