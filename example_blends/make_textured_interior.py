"""Generates textured_interior.blend beside this file: a room made the usual way in Blender, lit by
an HDRI sky with a sun through a window. Everything issue-prone at once: the room is one mesh with
outward normals (Add > Cube, scaled, and a window cut in one wall: it is seen and lit from inside,
its back side), the floor has a Checker Texture and a bump, a painting on the wall an Image Texture, a ball is
a rough metal, and the world is an Environment Texture (an HDR image with a bright sun spot) that
lights the room only through the window. The images are written beside the scene, in textures/:

    .venv/bin/python example_blends/make_textured_interior.py [--if-missing] [--out-dir DIR]
"""
from __future__ import annotations

import math
import pathlib
import sys

import bpy
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # scene_parts, also under runpy
from scene_parts import HERE, camera, link, principled_material, render_settings, empty_scene, main, wave_bump  # noqa: E402

TEXTURES = HERE / "textures"
HDRI = TEXTURES / "sky_with_sun.exr"
PAINTING = TEXTURES / "painting.png"
# The sun: from the +x side (through the window in the wall at x = 2), 35 degrees above the horizon.
SUN_DIRECTION = np.array([math.cos(math.radians(35)) * math.cos(math.radians(-20)),
                          math.cos(math.radians(35)) * math.sin(math.radians(-20)), math.sin(math.radians(35))])
SUN_RADIANCE = 4000.0  # over a few texels: a few W/m^2 of irradiance, like a Blender sun of strength 3-4
HDRI_SIZE = (256, 128)
# The room: x, y in [-2, 2], z in [0, 3]; the window in the wall x = 2.
ROOM = 2.0
HEIGHT = 3.0
WINDOW = (-0.7, 0.7, 1.0, 2.2)  # y0, y1, z0, z1


def equirectangular_texel(direction, size):
    """The texel (column, row from the bottom) of an equirectangular image Blender's Environment
    Texture shows along a world direction: u = 0.5 - atan2(y, x) / (2 pi) (the image's centre is
    +x), v = 0.5 + asin(z) / pi."""
    x, y, z = direction / np.linalg.norm(direction)
    u = 0.5 - math.atan2(y, x) / (2 * math.pi)
    v = 0.5 + math.asin(z) / math.pi
    return int(u * size[0]) % size[0], min(int(v * size[1]), size[1] - 1)


def sky_pixels(size=HDRI_SIZE) -> np.ndarray:
    """(rows, columns, 4) linear RGBA, row 0 at the bottom: a blue sky brightening to the
    horizon, a grey ground, and a sun of 2 x 2 texels."""
    w, h = size
    elevation = (np.arange(h) + 0.5) / h * math.pi - math.pi / 2
    sky = np.where(elevation[:, None] > 0,
                   np.array([0.35, 0.55, 1.0]) * (0.6 + 0.6 * np.exp(-4 * np.maximum(elevation, 0)))[:, None],
                   np.array([0.25, 0.22, 0.2]))
    pixels = np.ones((h, w, 4), np.float32)
    pixels[..., :3] = sky[:, None, :]
    column, row = equirectangular_texel(SUN_DIRECTION, size)
    pixels[row:row + 2, column:column + 2, :3] = SUN_RADIANCE * np.array([1.0, 0.95, 0.85])
    return pixels


def painting_pixels(size=128) -> np.ndarray:
    """(rows, columns, 4) sRGB-encoded RGBA in [0, 1]: coloured bands crossed by a disc."""
    t = (np.arange(size) + 0.5) / size
    x, y = np.meshgrid(t, t)
    rgb = np.stack([0.5 + 0.4 * np.sin(6 * x), 0.4 + 0.3 * np.cos(5 * y), 0.3 + 0.2 * np.sin(9 * (x + y))], -1)
    disc = (x - 0.6) ** 2 + (y - 0.45) ** 2 < 0.06
    rgb[disc] = (0.9, 0.75, 0.2)
    return np.concatenate([rgb, np.ones((size, size, 1))], -1).astype(np.float32)


def write_image(path, pixels, float_buffer):
    """Writes pixels through Blender's image writer: EXR (linear, as 'Non-Color' so nothing is
    encoded) or PNG (8-bit sRGB), then forgets the image."""
    h, w = pixels.shape[:2]
    image = bpy.data.images.new(path.stem, w, h, alpha=True, float_buffer=float_buffer)
    if float_buffer:
        image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(pixels.ravel())
    image.filepath_raw = str(path)
    image.file_format = "OPEN_EXR" if float_buffer else "PNG"
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save()
    bpy.data.images.remove(image)


def write_textures(out_dir: pathlib.Path) -> None:
    write_image(out_dir / "textures" / HDRI.name, sky_pixels(), True)
    write_image(out_dir / "textures" / PAINTING.name, painting_pixels(), False)


def room_mesh():
    """A cube scaled to the room, as Blender's Add > Cube makes it (outward normals), with the wall
    at x = ROOM made of four quads around the window opening."""
    r, hz = ROOM, HEIGHT
    y0, y1, z0, z1 = WINDOW
    quads = [
        [(-r, -r, 0), (-r, r, 0), (r, r, 0), (r, -r, 0)],  # floor, normal -z (outwards)
        [(-r, -r, hz), (r, -r, hz), (r, r, hz), (-r, r, hz)],  # ceiling, +z
        [(-r, -r, 0), (r, -r, 0), (r, -r, hz), (-r, -r, hz)],  # wall y = -r, -y
        [(r, r, 0), (-r, r, 0), (-r, r, hz), (r, r, hz)],  # wall y = r, +y
        [(-r, r, 0), (-r, -r, 0), (-r, -r, hz), (-r, r, hz)],  # wall x = -r, -x
        # the window wall x = r, +x: below, above, and either side of the opening
        [(r, -r, 0), (r, r, 0), (r, r, z0), (r, -r, z0)],
        [(r, -r, z1), (r, r, z1), (r, r, hz), (r, -r, hz)],
        [(r, -r, z0), (r, y0, z0), (r, y0, z1), (r, -r, z1)],
        [(r, y1, z0), (r, r, z0), (r, r, z1), (r, y1, z1)],
    ]
    verts, faces = [], []
    for q in quads:
        faces.append(tuple(range(len(verts), len(verts) + 4)))
        verts.extend(q)
    mesh = bpy.data.meshes.new("Room")
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def uv_sphere_mesh(name, radius, segments, rings):
    """A UV sphere as Add > UV Sphere makes it (quads between rings, triangles at the poles,
    outward normals), built here so that the same script always writes the same faces."""
    verts = [(0.0, 0.0, radius)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        verts += [(radius * math.sin(theta) * math.cos(2 * math.pi * j / segments),
                   radius * math.sin(theta) * math.sin(2 * math.pi * j / segments), radius * math.cos(theta))
                  for j in range(segments)]
    verts.append((0.0, 0.0, -radius))
    ring = lambda i, j: 1 + (i - 1) * segments + j % segments  # noqa: E731
    faces = [(0, ring(1, j), ring(1, j + 1)) for j in range(segments)]
    faces += [(ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1))
              for i in range(1, rings - 1) for j in range(segments)]
    faces += [(ring(rings - 1, j + 1), ring(rings - 1, j), len(verts) - 1) for j in range(segments)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def textured_material(name, texture_type):
    """A Principled BSDF whose Base Color is a new texture node of that type; returns both."""
    m = principled_material(name, (0.8, 0.8, 0.8), Roughness=1.0)
    bsdf = next(n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    texture = m.node_tree.nodes.new(texture_type)
    m.node_tree.links.new(texture.outputs["Color"], bsdf.inputs["Base Color"])
    return m, texture


def checker_material():
    """A Checker Texture over the floor's UVs, ribbed by a Bump node over a Wave Texture's bands
    (a rug's weave)."""
    m, checker = textured_material("Checker Floor", "ShaderNodeTexChecker")
    checker.inputs["Color1"].default_value = (0.75, 0.72, 0.68, 1)
    checker.inputs["Color2"].default_value = (0.12, 0.1, 0.09, 1)
    checker.inputs["Scale"].default_value = 8.0
    tree = m.node_tree
    coords = tree.nodes.new("ShaderNodeTexCoord")
    tree.links.new(coords.outputs["UV"], checker.inputs["Vector"])
    wave_bump(tree, next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"), scale=12.0, strength=0.5, distance=0.005)
    return m


def painting_material():
    m, texture = textured_material("Painting", "ShaderNodeTexImage")
    texture.image = bpy.data.images.load(str(PAINTING), check_existing=True)
    return m


def add_uvs(mesh, per_face_uvs):
    layer = mesh.uv_layers.new(name="UVMap")
    for poly, uvs in zip(mesh.polygons, per_face_uvs):
        for loop, uv in zip(poly.loop_indices, uvs):
            layer.data[loop].uv = uv


def hdri_world():
    world = bpy.data.worlds.new("Sky")
    if world.node_tree is None:  # Blender 4.x
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    background = nodes["Background"]
    environment = nodes.new("ShaderNodeTexEnvironment")
    environment.image = bpy.data.images.load(str(HDRI), check_existing=True)
    links.new(environment.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = 1.0
    return world


def build():
    scene = empty_scene()
    write_textures(HERE)  # saved as paths relative to the scene (scene_parts.save)
    room = link(bpy.data.objects.new("Room", room_mesh()))
    room.data.materials.append(principled_material("Plaster", (0.8, 0.78, 0.74), Roughness=1.0))

    floor_mesh = bpy.data.meshes.new("Floor")
    r = ROOM - 0.01  # a rug-like floor just above the room's floor, so the checker has UVs of its own
    floor_mesh.from_pydata([(-r, -r, 0.01), (r, -r, 0.01), (r, r, 0.01), (-r, r, 0.01)], [], [(0, 1, 2, 3)])
    add_uvs(floor_mesh, [[(0, 0), (1, 0), (1, 1), (0, 1)]])
    floor_mesh.materials.append(checker_material())
    link(bpy.data.objects.new("Floor", floor_mesh))

    painting_mesh = bpy.data.meshes.new("Painting")
    y = ROOM - 0.01  # on the wall y = ROOM, facing into the room
    painting_mesh.from_pydata([(-1.3, y, 1.0), (0.1, y, 1.0), (0.1, y, 2.1), (-1.3, y, 2.1)], [], [(0, 1, 2, 3)])
    add_uvs(painting_mesh, [[(0, 0), (1, 0), (1, 1), (0, 1)]])
    painting_mesh.materials.append(painting_material())
    link(bpy.data.objects.new("Painting", painting_mesh))

    ball = link(bpy.data.objects.new("Ball", uv_sphere_mesh("Ball", 0.45, 16, 8)))
    ball.location = (-0.6, 0.9, 0.46)
    ball.data.materials.append(principled_material("Steel", (0.8, 0.8, 0.82), Metallic=1.0, Roughness=0.5))

    camera((-1.85, -1.85, 1.7), (0.6, 0.6, 0.7), lens=18)
    render_settings(scene, (480, 360))
    scene.world = hdri_world()
    return scene


# The .blend files this script writes, and the function building each scene.
BUILDERS = {"textured_interior.blend": build}

if __name__ == "__main__":
    main(BUILDERS)
