"""Generates furnished_interior.blend beside this file: issue 16's benchmark scene, a reading room
of shelf units full of books, tables with chairs and metal balls, lit by a sun and a sky through a
window (interior_layout.py says where everything stands). The object count is a parameter; the
default, 100 objects, is the committed example, other counts are written as
furnished_interior_<N>.blend (the benchmark makes them in a temporary folder):

    .venv/bin/python example_blends/make_furnished_interior.py [--objects N] [--if-missing] [--out-dir DIR]

Every object is its own mesh, as a modelled interior has them (books of different sizes are
different meshes); the room is one mesh seen from inside.
"""
from __future__ import annotations

import math
import pathlib
import sys

import bpy

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # scene_parts, also under runpy
import interior_layout  # noqa: E402
from make_textured_interior import uv_sphere_mesh  # noqa: E402
from scene_parts import camera, empty_scene, link, main, principled_material, render_settings  # noqa: E402

DEFAULT_OBJECTS = 100
SUN_STRENGTH = 3.0  # W/m^2, Blender's sun strength
SKY_STRENGTH = 0.3


def materials() -> dict:
    return {name: principled_material(name.title(), rgb, Metallic=metallic, Roughness=roughness)
            for name, (rgb, metallic, roughness) in interior_layout.MATERIALS.items()}


def mesh_object(name, quads_with_materials, slots):
    """One mesh object of quads [(material name, 4 corners)], its material slots in `slots`
    order."""
    verts, faces, indices = [], [], []
    names = list(dict.fromkeys(material for material, _ in quads_with_materials))
    for material, quad in quads_with_materials:
        faces.append(tuple(range(len(verts), len(verts) + 4)))
        verts.extend(quad)
        indices.append(names.index(material))
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    for material in names:
        mesh.materials.append(slots[material])
    mesh.polygons.foreach_set("material_index", indices)
    mesh.update()
    return link(bpy.data.objects.new(name, mesh))


def sky_world(sun_direction):
    """A Sky Texture world without its sun disc (the Sun light is the sun), as a sky light."""
    world = bpy.data.worlds.new("Sky")
    if world.node_tree is None:  # Blender 4.x
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    sky = nodes.new("ShaderNodeTexSky")
    if hasattr(sky, "sun_disc"):
        sky.sun_disc = False
    if hasattr(sky, "sun_elevation"):
        sky.sun_elevation = math.asin(sun_direction[2])
        sky.sun_rotation = math.atan2(sun_direction[1], sun_direction[0])
    links.new(sky.outputs["Color"], nodes["Background"].inputs["Color"])
    nodes["Background"].inputs["Strength"].default_value = SKY_STRENGTH
    return world


def build(objects: int = DEFAULT_OBJECTS):
    scene = empty_scene()
    interior = interior_layout.furnished_interior(objects)
    slots = materials()
    for thing in interior.things:
        if thing.name == "Room":
            mesh_object("Room", interior_layout.room_quads(interior), slots)
            continue
        if isinstance(thing.pieces[0], interior_layout.Ball):
            ball = thing.pieces[0]
            obj = link(bpy.data.objects.new(thing.name, uv_sphere_mesh(thing.name, ball.radius, 24, 12)))
            obj.location = ball.centre
            obj.data.materials.append(slots[ball.material])
            continue
        mesh_object(thing.name, [(box.material, quad) for box in thing.pieces
                                 for quad in interior_layout.box_quads(box)], slots)
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = SUN_STRENGTH
    sun.angle = math.radians(0.53)
    sun_object = link(bpy.data.objects.new("Sun", sun))
    # A sun shines along its local -z: point -z away from the sun direction.
    sun_object.rotation_euler = (0.0, math.pi / 2 - math.asin(interior.sun_direction[2]),
                                 math.atan2(interior.sun_direction[1], interior.sun_direction[0]))
    lx = interior.length / 2
    camera((lx - 0.6, -interior.width / 2 + 0.6, 1.7), (-lx + 1.0, interior.width / 4, 0.9), lens=16)
    render_settings(scene, (480, 320))
    scene.world = sky_world(interior.sun_direction)
    return scene


def builders(argv) -> dict:
    objects = int(argv[argv.index("--objects") + 1]) if "--objects" in argv else DEFAULT_OBJECTS
    name = "furnished_interior.blend" if objects == DEFAULT_OBJECTS else f"furnished_interior_{objects}.blend"
    return {name: lambda: build(objects)}


# The .blend files this script writes by default, and the function building each scene.
BUILDERS = builders([])

if __name__ == "__main__":
    main(builders(sys.argv[1:]))
