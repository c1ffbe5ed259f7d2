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
PROP_SPLINE_MATERIALS = "bsgi_spline_materials"  # SURFACE objects of several splines: a material per spline
PROP_SPLINE_INDICES = "bsgi_spline_material_indices"  # their splines' material indices before the bake
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


def bake_object(obj, faces, chart_uvs=None) -> list:
    """Bake one object: faces is, per polygon (per spline for a NURBS surface, one entry for a
    UV chart), (kind, splines) as face_splines gives; chart_uvs are a chart's UVs per loop (None:
    the UV map of an earlier bake). The splines are also stored on the object, so the bake can be
    redone without a solve. Returns warnings about what the bake approximates."""
    if obj.type == "SURFACE":
        return _bake_nurbs(obj, faces)
    if faces and faces[0][0] == "chart":
        return _bake_chart(obj, faces, chart_uvs)
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
    UV map Blender gives the surface's mesh."""
    if len(faces) != 1:
        return _bake_nurbs_splines(obj, faces)
    spline = faces[0][1][0]
    pixels = nurbs_pixels(spline)
    image = _radiance_image(f"BSGI {obj.name}", pixels.shape[1], pixels.shape[0], pixels)
    material = _baked_material(f"BSGI {obj.name}", image, NURBS_UV_NAME)
    _link_baked_material(obj, material)
    _store_splines(obj, faces)
    return _view_dependence_warning(obj, faces)


def chart_image_size(spline) -> int:
    """Side of a chart's image: four texels per coefficient (a chart's islands are smaller than
    the UV square they share), at least 64."""
    return max(64, 4 * max(axis.num_coeffs for axis in spline.axes[:2]))


def chart_pixels(spline) -> np.ndarray:
    """(n, n, 4) image of a chart's spline over its UV square, texel centres at (i + 0.5) / n as
    for NURBS. Texels outside the islands hold the spline's smooth continuation, so linear
    filtering at an island's border never mixes in a neighbour's light."""
    n = chart_image_size(spline)
    u, v = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n)
    pixels = np.ones((n, n, 4), np.float32)
    pixels[..., :3] = radiance_along_normal(spline, np.stack([u.ravel(), v.ravel()], axis=1)).reshape(n, n, 3)
    return pixels


def _bake_chart(obj, faces, chart_uvs) -> list:
    """A mesh solved as one UV chart: an image over the chart's UV square, shown through the UV
    map `BSGI Radiance`, which holds the chart's UVs (the user's UV map it came from, or the
    generated one); the user's own UV maps are not touched."""
    mesh = obj.data
    if chart_uvs is not None:
        if len(chart_uvs) != len(mesh.loops):
            raise ValueError(f"object '{obj.name}': its modifiers change its faces; apply them before baking")
        if mesh.uv_layers.get(UV_NAME) is None:
            mesh.uv_layers.new(name=UV_NAME, do_init=False)
        mesh.uv_layers[UV_NAME].data.foreach_set("uv", np.ascontiguousarray(chart_uvs, np.float32).ravel())
    elif mesh.uv_layers.get(UV_NAME) is None:
        # A solution file baked onto a cleared object: the chart came from the user's UV map if
        # that is a chart; a generated one cannot be recovered.
        from . import charts

        name, uvs = charts.suitable_uv_map(mesh, charts.loop_triangles(mesh)[1])
        if name is None:
            raise ValueError(f"object '{obj.name}': its chart's UV map '{UV_NAME}' is gone and none of its own UV "
                             "maps is a chart; solve again")
        return _bake_chart(obj, faces, uvs)
    pixels = chart_pixels(faces[0][1][0])
    image = _radiance_image(f"BSGI {obj.name}", pixels.shape[1], pixels.shape[0], pixels)
    material = _baked_material(f"BSGI {obj.name}", image, UV_NAME)
    _link_baked_material(obj, material)
    _store_splines(obj, faces)
    return _view_dependence_warning(obj, faces)


def _bake_nurbs_splines(obj, faces) -> list:
    """A SURFACE object of several splines. Blender gives every spline's mesh the whole UV square
    (UVMap = that spline's normalized parameters), so the splines' images cannot share one UV
    map; the one per-face choice a material sees is the material slot. Each spline gets its own
    image and material, in a slot of its own: while the bake is shown, spline k uses slot k (slots
    are added if there are fewer than splines). The user's material indices are recorded and put
    back when the originals are shown or the bake is cleared."""
    from .export import baked_splines

    splines = baked_splines(obj)
    if len(splines) != len(faces):
        raise ValueError(f"object '{obj.name}': it has {len(splines)} drawable splines, the solution {len(faces)}")
    names = []
    for k, (_, (spline,)) in enumerate(faces):
        pixels = nurbs_pixels(spline)
        image = _radiance_image(f"BSGI {obj.name} spline {k}", pixels.shape[1], pixels.shape[0], pixels)
        names.append(_baked_material(f"BSGI {obj.name} spline {k}", image, NURBS_UV_NAME).name)
    if PROP_SPLINE_INDICES not in obj:
        obj[PROP_SPLINE_INDICES] = [int(s.material_index) for s in obj.data.splines]
    added = 0
    if PROP_SLOTS not in obj:
        while len(obj.data.materials) < len(faces):
            obj.data.materials.append(None)
            added += 1
    obj[PROP_SPLINE_MATERIALS] = names
    _link_baked_material(obj, bpy.data.materials[names[0]])
    if added:
        obj[PROP_ADDED_SLOT] = int(obj.get(PROP_ADDED_SLOT, 0)) + added
    _store_splines(obj, faces)
    return _view_dependence_warning(obj, faces)


def user_spline_material_index(obj, k: int) -> int:
    """Spline k's material index as the user set it (the bake of several splines changes it)."""
    indices = obj.get(PROP_SPLINE_INDICES)
    return int(indices[k]) if indices is not None and k < len(indices) else int(obj.data.splines[k].material_index)


def _show_spline_materials(obj, baked: bool) -> None:
    """Spline k on slot k with its own baked material, or the user's material indices back."""
    from .export import baked_splines

    names = obj.get(PROP_SPLINE_MATERIALS)
    if names is None:
        return
    drawn = baked_splines(obj)
    for k, spline in enumerate(obj.data.splines):
        spline.material_index = (drawn.index(spline) if baked and spline in drawn
                                 else user_spline_material_index(obj, k))
    if baked:
        for k, slot in enumerate(obj.material_slots):
            slot.material = bpy.data.materials.get(names[min(k, len(names) - 1)])


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
    _show_spline_materials(obj, baked)


def clear_bake(obj) -> None:
    """Remove the bake from an object: its slots, UV maps and materials as before the bake."""
    if not is_baked(obj):
        return
    show_baked(obj, False)
    if obj.get(PROP_ADDED_SLOT):
        for _ in range(int(obj[PROP_ADDED_SLOT])):
            obj.data.materials.pop()
        del obj[PROP_ADDED_SLOT]
    names = [obj[PROP_MATERIAL], *obj.get(PROP_SPLINE_MATERIALS, [])]
    for prop in (PROP_SLOTS, PROP_MATERIAL, PROP_SPLINE_MATERIALS, PROP_SPLINE_INDICES):
        if prop in obj:
            del obj[prop]
    if PROP_RADIANCE in obj:
        del obj[PROP_RADIANCE]
    uv = obj.data.uv_layers.get(UV_NAME) if obj.type == "MESH" else None
    if uv is not None:
        obj.data.uv_layers.remove(uv)
    for name in dict.fromkeys(names):
        material = bpy.data.materials.get(name)
        if material is not None:
            image = next((n.image for n in material.node_tree.nodes if n.type == "TEX_IMAGE"), None)
            bpy.data.materials.remove(material)
            if image is not None:
                bpy.data.images.remove(image)
