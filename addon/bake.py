"""Solved radiance splines -> what Blender shows: per object a float image atlas (one tile per
face), a UV map laying the faces on their tiles, and an emission material showing it.

The user's materials stay on the mesh untouched: the baked material is linked to the object's
material slots (slot.link = 'OBJECT'), and switching the slots back to 'DATA' shows the originals."""
from __future__ import annotations

import math

import bpy
import numpy as np

import bsgi

UV_NAME = "BSGI Radiance"
PROP_SLOTS = "bsgi_slot_links"  # the slots' links before the bake, to restore them
PROP_ADDED_SLOT = "bsgi_added_slot"
PROP_MATERIAL = "bsgi_baked_material"
PROP_RADIANCE = "bsgi_radiance"  # the faces' splines, for re-baking and solution export
# The UV map Blender gives the mesh of a NURBS surface: normalized (u, v) parameters.
NURBS_UV_NAME = "UVMap"


def tile_size(spline) -> int:
    """Texels per face side: two per coefficient, so the image resolves the spline's knots."""
    return max(8, 2 * max(axis.num_coeffs for axis in spline.axes[:2]))


def radiance_along_normal(spline, uv: np.ndarray) -> np.ndarray:
    """(N, 3) radiance at the (u, v) rows of uv. A glossy (4D) spline is evaluated at the
    centre of the hemisphere's disc, (alpha, beta) = (0, 0), which the map (20)-(22) sends to
    the surface normal: until view-dependent baking exists, the bake shows the radiance seen
    head-on."""
    if spline.dims == 4:
        uv = np.concatenate([uv, np.zeros((len(uv), 2))], axis=1)
    return spline.evaluate(np.ascontiguousarray(uv, np.float64))


def _view_dependence_warning(obj, faces) -> list:
    if any(s.dims == 4 for _, splines in faces for s in splines):
        return [f"object '{obj.name}': glossy radiance is baked as seen along the surface normal (the bake is not "
                "view-dependent yet)"]
    return []


def _tile_parameters(kind: str, t: int) -> np.ndarray:
    """(u, v) of the surface at the tile's texel centres, shape (t*t, 2), rows of constant y.

    The face's UV corners sit on the centres of the tile's corner texels, so texel (i, j) is at
    x = i / (t - 1), y = j / (t - 1) in the face's UV square. Quads are bilinear: (u, v) = (x, y).
    Triangles lie in the half y <= x of the square with corners (0, 0), (1, 0), (1, 1); the
    collapsed-square parameterization gives u = x, v = y / x (texels above the diagonal repeat
    the diagonal, so texture filtering never mixes in another face)."""
    x, y = np.meshgrid(np.linspace(0, 1, t), np.linspace(0, 1, t))
    if kind == "quad":
        u, v = x, y
    else:
        u = x
        v = np.divide(y, x, out=np.full_like(y, 0.5), where=x > 0)
        v = np.clip(v, 0, 1)
    return np.stack([u.ravel(), v.ravel()], axis=1)


def _face_uvs(kind: str, tile_origin, t: int, size: int, corners: int):
    """UV coordinates of a face's loops on its tile, matching _tile_parameters."""
    if kind == "quad":
        square = [(0, 0), (1, 0), (1, 1), (0, 1)]
    else:
        square = [(0, 0), (1, 0), (1, 1)]
    ox, oy = tile_origin
    return [((ox + 0.5 + sx * (t - 1)) / size, (oy + 0.5 + sy * (t - 1)) / size) for sx, sy in square[:corners]]


def face_splines(exported, radiance) -> list:
    """Per polygon of an exported object: (kind, its splines) from a solution's radiance list."""
    return [(kind, [radiance[first + k] for k in range(count)]) for kind, first, count in exported.patches]


def bake_object(obj, faces) -> list:
    """Bake one object: faces is, per polygon (per spline for a NURBS surface), (kind, splines)
    as face_splines gives. The splines are also stored on the object, so the bake can be redone
    without a solve. Returns warnings about what the bake approximates."""
    if obj.type == "SURFACE":
        return _bake_nurbs(obj, faces)
    mesh = obj.data
    if len(mesh.polygons) != len(faces):
        raise ValueError(f"object '{obj.name}': its modifiers change its faces; apply them before baking")
    t = tile_size(faces[0][1][0])
    grid = math.ceil(math.sqrt(len(faces)))
    size = grid * t
    pixels = np.zeros((size, size, 4), np.float32)
    pixels[..., 3] = 1
    uvs = np.zeros((len(mesh.loops), 2), np.float32)
    for index, (kind, splines) in enumerate(faces):
        ox, oy = (index % grid) * t, (index // grid) * t
        poly = mesh.polygons[index]
        if kind == "ngon":
            # N-gons are solved as triangle fans; show their mean radiance until charts land.
            centre = np.full((1, 2), 0.5)
            pixels[oy:oy + t, ox:ox + t, :3] = np.mean([radiance_along_normal(s, centre)[0] for s in splines], axis=0)
            uvs[list(poly.loop_indices)] = ((ox + t / 2) / size, (oy + t / 2) / size)
            continue
        values = radiance_along_normal(splines[0], _tile_parameters(kind, t))
        pixels[oy:oy + t, ox:ox + t, :3] = values.reshape(t, t, 3)
        for loop, uv in zip(poly.loop_indices, _face_uvs(kind, (ox, oy), t, size, poly.loop_total)):
            uvs[loop] = uv

    uv_layer = mesh.uv_layers.get(UV_NAME) or mesh.uv_layers.new(name=UV_NAME, do_init=False)
    mesh.uv_layers[UV_NAME].data.foreach_set("uv", uvs.ravel())
    del uv_layer  # look layers up by name again after creating one

    image = _radiance_image(f"BSGI {obj.name}", size, size, pixels)
    material = _baked_material(f"BSGI {obj.name}", image, UV_NAME)
    _link_baked_material(obj, material)
    _store_splines(obj, faces)
    return _view_dependence_warning(obj, faces)


def nurbs_image_size(spline) -> tuple:
    """(width, height) of a NURBS surface's image: two texels per coefficient in u and v, at least 16."""
    return tuple(max(16, 2 * axis.num_coeffs) for axis in spline.axes[:2])


def nurbs_pixels(spline) -> np.ndarray:
    """(height, width, 4) image of a spline over the surface's parameter square. Blender's mesh
    of the surface has UVs = normalized (u, v), and a linear image lookup at UV x reads texel
    centres at (i + 0.5) / width: each texel holds the radiance at its centre's parameters, so
    the image interpolates the spline there."""
    w, h = nurbs_image_size(spline)
    u, v = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    pixels = np.ones((h, w, 4), np.float32)
    pixels[..., :3] = radiance_along_normal(spline, np.stack([u.ravel(), v.ravel()], axis=1)).reshape(h, w, 3)
    return pixels


def _bake_nurbs(obj, faces) -> list:
    """A SURFACE object of one spline: its image laid out in parameter space, shown through the
    UV map Blender gives the surface's mesh. Several splines share that UV map's square, so one
    image cannot show them all: they are solved (they light each other) but not baked yet."""
    if len(faces) != 1:
        return [f"object '{obj.name}': {len(faces)} NURBS splines are solved but not baked (they share one UV "
                "square; one spline per object is baked)"]
    spline = faces[0][1][0]
    pixels = nurbs_pixels(spline)
    image = _radiance_image(f"BSGI {obj.name}", pixels.shape[1], pixels.shape[0], pixels)
    material = _baked_material(f"BSGI {obj.name}", image, NURBS_UV_NAME)
    _link_baked_material(obj, material)
    _store_splines(obj, faces)
    return _view_dependence_warning(obj, faces)


def _store_splines(obj, faces) -> None:
    # ID properties from float64 arrays: exact, and saved in the .blend.
    group = {"kinds": ",".join(kind for kind, _ in faces)}
    for i, (_, splines) in enumerate(faces):
        for k, spline in enumerate(splines):
            arrays = bsgi.spline_to_arrays(spline)
            arrays["degrees"] = arrays["degrees"].astype(np.int32)  # ID property ints are 32-bit
            group[f"{i}.{k}"] = arrays
    obj[PROP_RADIANCE] = group


def stored_faces(obj) -> list:
    """The faces' splines stored by the last bake, as bake_object takes them."""
    group = obj.get(PROP_RADIANCE)
    if group is None:
        raise ValueError(f"object '{obj.name}': no stored radiance; solve first")
    faces = []
    for i, kind in enumerate(group["kinds"].split(",")):
        splines, k = [], 0
        while f"{i}.{k}" in group:
            arrays = {name: np.frombuffer(memoryview(value), _dtype(value)) if hasattr(value, "typecode") else value
                      for name, value in group[f"{i}.{k}"].items()}
            splines.append(bsgi.spline_from_arrays(_shaped(arrays)))
            k += 1
        faces.append((kind, splines))
    return faces


def _dtype(value):
    return np.float64 if memoryview(value).format == "d" else np.int32


def _shaped(arrays):
    """ID property arrays are flat: give the coefficients back their (n_0, ..., channels) shape."""
    degrees = arrays["degrees"].astype(int)
    shape = [len(arrays[f"knots{k}"]) - d - 1 for k, d in enumerate(degrees)]
    arrays["coefficients"] = arrays["coefficients"].reshape(*shape, -1)
    return arrays


def rebake(obj) -> list:
    """Regenerate an object's image from its stored splines (no solve)."""
    return bake_object(obj, stored_faces(obj))


def _radiance_image(name: str, width: int, height: int, pixels: np.ndarray):
    image = bpy.data.images.get(name)
    if image is not None and (image.size[0] != width or image.size[1] != height):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=False, float_buffer=True)
    # Radiance is scene-linear data: the colour space is set before the pixels, since
    # changing it afterwards discards them.
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(pixels.ravel())
    image.pack()
    return image


def _baked_material(name: str, image, uv_map: str):
    material = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    material.use_fake_user = True  # kept in the .blend while the originals are shown
    tree = material.node_tree
    if tree is None:
        material.use_nodes = True
        tree = material.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    emission = tree.nodes.new("ShaderNodeEmission")
    tex = tree.nodes.new("ShaderNodeTexImage")
    uv = tree.nodes.new("ShaderNodeUVMap")
    uv.uv_map = uv_map
    tex.image = image
    tex.interpolation = "Linear"
    tex.extension = "EXTEND"
    tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    tree.links.new(tex.outputs["Color"], emission.inputs["Color"])
    tree.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    uv.location, tex.location, emission.location, out.location = (-600, 0), (-350, 0), (-50, 0), (200, 0)
    return material


def _link_baked_material(obj, material) -> None:
    if PROP_SLOTS not in obj:
        if not obj.material_slots:
            obj.data.materials.append(None)
            obj[PROP_ADDED_SLOT] = True
        # Each slot's link and its object-level material, which the bake's link replaces.
        saved = []
        for slot in obj.material_slots:
            link = slot.link
            slot.link = "OBJECT"
            saved.append([link, slot.material.name if slot.material else ""])
            slot.link = link
        obj[PROP_SLOTS] = saved
    obj[PROP_MATERIAL] = material.name
    show_baked(obj, True)


def is_baked(obj) -> bool:
    return PROP_SLOTS in obj


def user_materials(obj) -> list:
    """The user's material in each slot, whether or not the bake is shown: a solve must read
    these, never the baked emission materials."""
    if not is_baked(obj):
        return [slot.material for slot in obj.material_slots]
    data = obj.data.materials
    return [(data[i] if link == "DATA" else bpy.data.materials.get(object_material))
            for i, (link, object_material) in enumerate(obj[PROP_SLOTS])]


def show_baked(obj, baked: bool) -> None:
    """Switch an object between its baked radiance and the user's own materials."""
    if not is_baked(obj):
        return
    material = bpy.data.materials.get(obj[PROP_MATERIAL])
    for slot, (link, object_material) in zip(obj.material_slots, obj[PROP_SLOTS]):
        slot.link = "OBJECT"
        slot.material = material if baked else bpy.data.materials.get(object_material)
        if not baked:
            slot.link = link


def clear_bake(obj) -> None:
    """Remove the bake from an object: its slots, UV maps and materials as before the bake."""
    if not is_baked(obj):
        return
    show_baked(obj, False)
    if obj.get(PROP_ADDED_SLOT):
        obj.data.materials.pop()
        del obj[PROP_ADDED_SLOT]
    name = obj[PROP_MATERIAL]
    del obj[PROP_SLOTS]
    del obj[PROP_MATERIAL]
    if PROP_RADIANCE in obj:
        del obj[PROP_RADIANCE]
    uv = obj.data.uv_layers.get(UV_NAME) if obj.type == "MESH" else None
    if uv is not None:
        obj.data.uv_layers.remove(uv)
    material = bpy.data.materials.get(name)
    if material is not None:
        image = next((n.image for n in material.node_tree.nodes if n.type == "TEX_IMAGE"), None)
        bpy.data.materials.remove(material)
        if image is not None:
            bpy.data.images.remove(image)
