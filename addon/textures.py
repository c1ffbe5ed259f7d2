"""Textured materials: node trees that drive a material's colour (a Principled BSDF's Base Color, a
Diffuse BSDF's Color, a Glossy BSDF's Color), its emission or its normal (a Normal Map or Bump node)
are evaluated by Blender itself, not by the add-on: a Cycles bake of the diffuse-colour pass (of the
glossy-colour pass for glossy surfaces, of the emission pass, and of the normal pass in object
space) onto a temporary copy of the object,
whose temporary UV map lays each solver surface's parameter square on a tile of a float image.
The tiles become the surfaces' albedo, emission and normal textures over their own (u, v)
(Scene.set_albedo_texture / set_emission_texture / set_specular_texture / set_normal_texture): the solve keeps irradiance
/ pi (a glossy surface: its reflected radiance per unit of its mean colour) in the spline and the
texture as its detail, the paper's decomposition (38) with the texture as the detail factor.

Everything made here (object, mesh, material copies, images) is removed afterwards; the user's
objects, meshes and materials are read only, and the render settings are put back."""
from __future__ import annotations

import math
import os
import time
from contextlib import contextmanager

import bpy
import numpy as np

from .errors import ExportError
from .materials import (AVERAGED_INPUTS, BUMPED_SHADERS, active_output, describe_material, dielectric_f0, linked_node,
                        socket_value, solved_diffuse, solver_material, user_slots)

BAKE_UV = "BSGI Texture Bake"
NURBS_UV = "UVMap"  # Blender's UV map of a NURBS surface's mesh: the normalized (u, v)
BAKE_SAMPLES = 4  # jittered per texel: about the texel's mean colour (cost: 1.5 us per texel and sample here)
PAD = 2  # texels between tiles, filled by the bake's margin
DEFAULT_TEXELS = 32


def texture_texels(scene) -> int:
    settings = getattr(scene, "bsgi", None)
    return settings.texture_texels if settings is not None else DEFAULT_TEXELS


def has_textures(obj) -> bool:
    """Whether any of the object's materials has node-driven colour, emission or normal."""
    return any(_slot_flags(obj))


def _slot_flags(obj):
    for m in user_slots(obj):
        yield _baked(solver_material(m, describe_material(m, []), []))


# What Cycles bakes for the solve, per slot that needs it (_flag): its colour, glossy colour,
# emission and normal passes.
PASSES = (("albedo", "DIFFUSE"), ("specular", "GLOSSY"), ("emission", "EMIT"), ("normal", "NORMAL"))


def _flag(material, which) -> bool:
    """Whether the slot's `which` pass is baked for it: its colour, glossy colour, emission or normal."""
    return material.bumped if which == "normal" else getattr(material, f"{which}_textured")


def _baked(material) -> bool:
    return any(_flag(material, which) for which, _ in PASSES)


def missing_images(material) -> list:
    """Names and paths of the images the material's Image Texture nodes cannot read (no file,
    not packed): Cycles renders them magenta, and so does the texture bake."""
    tree = getattr(material, "node_tree", None)
    found = []
    for node in (tree.nodes if tree is not None else ()):
        image = getattr(node, "image", None) if node.type == "TEX_IMAGE" else None
        if image is None or image.packed_file is not None or image.source not in {"FILE", "SEQUENCE", "TILED"}:
            continue
        path = bpy.path.abspath(image.filepath, library=image.library)
        if not os.path.exists(path) and not (image.source == "TILED" and image.has_data):
            found.append((image.name, image.filepath))
    return found


def apply_textures(depsgraph, scene, objects, warnings) -> dict:
    """Bakes the node-driven colour and emission of each exported object's materials into its
    surfaces' textures. Returns {"seconds", "texels"} of what was baked."""
    texels = texture_texels(depsgraph.scene)
    start, baked = time.perf_counter(), 0
    for exported in objects:
        obj = bpy.data.objects.get(exported.name)
        if obj is None:
            continue
        materials = [solver_material(m, describe_material(m, []), []) for m in user_slots(obj)]
        if not any(_baked(m) for m in materials):
            continue
        if exported.kind == "nurbs" and len(exported.patches) > 1:
            warnings.append(f"object '{exported.name}': its materials' node-driven colour or emission is solved with "
                            "the sockets' own values (textures are baked on NURBS objects of one spline; Blender "
                            "gives every spline the whole UV square)")
            continue
        baked += _bake_object(depsgraph, scene, obj, exported, materials, texels, warnings)
    return {"seconds": time.perf_counter() - start, "texels": baked}


def _bake_object(depsgraph, scene, obj, exported, materials, texels, warnings) -> int:
    with _temporary_copy(depsgraph, obj) as (copy, mesh):
        if exported.kind == "chart":
            side = 4 * texels
            uvs = exported.solve_uvs
            if uvs is None or len(uvs) != len(mesh.loops):
                raise ExportError(f"object '{exported.name}': its chart's UVs do not match its evaluated mesh")
            layout = _ChartLayout(side, uvs)
        elif exported.kind == "nurbs":
            # The mesh Blender makes of a NURBS surface has UVs = its normalized (u, v) parameters.
            uvs = np.empty(len(mesh.loops) * 2, np.float32)
            mesh.uv_layers[NURBS_UV].data.foreach_get("uv", uvs)
            layout = _ChartLayout(4 * texels, uvs.reshape(-1, 2))
        else:
            layout = _TileLayout(mesh, [kind for kind, _, _ in exported.patches], texels)
        for which, pass_type in PASSES:
            if not any(_flag(m, which) for m in materials):
                continue
            if which == "normal" and solved_diffuse(obj):
                warnings.append(f"object '{exported.name}': its materials' bumped normals are not solved (the object's "
                                "representation is set to diffuse; a bumped surface's radiance is 4D over its normal)")
                continue
            pixels = _bake(copy, mesh, layout, pass_type)
            _set_textures(scene, mesh, exported, layout, pixels, materials, which, warnings,
                          folded=solved_diffuse(obj), matrix=np.array(copy.matrix_world))
        return layout.width * layout.height


class _TileLayout:
    """Per polygon a t x t tile on a grid of tiles with PAD texels between them. A quad's corners
    (u, v) = (0, 0), (1, 0), (1, 1), (0, 1) sit on its tile's outer corners, so texel (i, j) of
    the tile is the surface's texel over [i/t, (i+1)/t] x [j/t, (j+1)/t]; a triangle's corners
    at (0, 0), (1, 0), (1, 1) of the tile, where the collapsed square (u, v) lies at (u, u v)."""

    def __init__(self, mesh, kinds, t):
        self.t = t
        self.grid = max(1, math.ceil(math.sqrt(len(mesh.polygons))))
        self.width = self.height = self.grid * (t + PAD) + PAD
        uvs = np.zeros((len(mesh.loops), 2), np.float32)
        for poly, kind in zip(mesh.polygons, kinds):
            if kind == "ngon":
                continue
            ox, oy = self.origin(poly.index)
            square = [(0, 0), (1, 0), (1, 1), (0, 1)] if kind == "quad" else [(0, 0), (1, 0), (1, 1)]
            for loop, (sx, sy) in zip(poly.loop_indices, square):
                uvs[loop] = ((ox + sx * t) / self.width, (oy + sy * t) / self.height)
        self.uvs = uvs

    def origin(self, index):
        return (PAD + (index % self.grid) * (self.t + PAD), PAD + (index // self.grid) * (self.t + PAD))

    def texture(self, pixels, index, kind):
        """The (t, t, 3) texture over the surface's (u, v) cut from the baked image."""
        ox, oy = self.origin(index)
        tile = pixels[oy:oy + self.t, ox:ox + self.t]
        if kind == "quad":
            return tile.copy()
        c = (np.arange(self.t) + 0.5) / self.t
        u, v = np.meshgrid(c, c)
        return _bilinear(tile, u, u * v)


class _ChartLayout:
    """A UV chart's image over its UV square: the chart's (u, v) are its UVs."""

    def __init__(self, side, uvs):
        self.width = self.height = side
        self.uvs = np.asarray(uvs, np.float32)


def _bilinear(image, x, y):
    """image (h, w, 3) at (x, y) in [0, 1] (pixel centres at (i + 0.5) / w), clamped."""
    h, w = image.shape[:2]
    fx = np.clip(x * w - 0.5, 0, w - 1)
    fy = np.clip(y * h - 0.5, 0, h - 1)
    x0, y0 = np.minimum(fx.astype(int), w - 2).clip(0), np.minimum(fy.astype(int), h - 2).clip(0)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    a, b = (fx - x0)[..., None], (fy - y0)[..., None]
    return ((image[y0, x0] * (1 - a) + image[y0, x1] * a) * (1 - b)
            + (image[y1, x0] * (1 - a) + image[y1, x1] * a) * b).astype(np.float32)


def _set_textures(scene, mesh, exported, layout, pixels, materials, which, warnings, folded=False, matrix=None):
    """Gives the surfaces of the slots whose `which` ("albedo", "specular", "emission", "normal")
    is node-driven their texture cut from the baked pass. folded: the object is solved diffuse (a
    layered coat's albedo folded, SolverMaterial.folded_albedo). matrix: the object's (4, 4), for
    the normal pass's object-space normals."""
    slot_of = np.zeros(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", slot_of)
    if exported.kind in {"chart", "nurbs"}:  # one surface over the image
        surfaces = [(exported.patches[0][1], int(slot_of[0]), pixels)]
    else:
        surfaces = []
        for poly_index, (kind, first, count) in enumerate(exported.patches):
            slot = int(slot_of[poly_index])
            if kind == "ngon":
                material = materials[min(slot, len(materials) - 1)]
                if _flag(material, which):
                    warnings.append(f"object '{exported.name}': face {poly_index} has more than four corners; its "
                                    "node-driven colour and emission use the sockets' own values (triangulate it "
                                    "to bake them)")
                continue
            surfaces.append((first, slot, layout.texture(pixels, poly_index, kind)))
    for index, slot, image in surfaces:
        material = materials[min(slot, len(materials) - 1)]
        if not _flag(material, which):
            continue
        if which == "normal":
            normals = _world_normals(image, matrix)
            if normals is None:
                warnings.append(f"object '{exported.name}': surface {index}'s bumped normals did not bake; it is solved "
                                "with its own normals")
                continue
            scene.set_normal_texture(index, normals, bump_correction=material.bump_correction)
        elif which == "albedo":
            # The base colour (the pass Cycles evaluates is it under the specular lobe, seen along
            # the normal): under a layered coat the base itself (the core layers each texel),
            # else folded as the solve's albedo is, base (1 - E) + E.
            base = image / np.asarray(material.pass_weight, np.float32)
            lobe = np.zeros(3, np.float32) if material.kind == "diffuse_ggx" and not folded else \
                np.asarray(material.specular, np.float32)
            scene.set_albedo_texture(index, np.clip(base * (1 - lobe) + lobe, 0, 1))
        elif which == "specular":
            # Cycles' glossy-colour pass: the lobe's colour (a metal's base colour) along the normal.
            scene.set_specular_texture(index, np.clip(image, 0, 1))
        else:
            image = np.maximum(image, 0)
            scene.set_emission_texture(index, image)
            if image.max() > 0:  # Cycles' Emission shader emits from both sides of a mesh
                scene.set_two_sided_emission(index)


def _world_normals(image, matrix):
    """Unit world-space normals from Cycles' object-space normal pass (its (n + 1) / 2), turned
    by the inverse transpose of the object's matrix; a texel the bake left empty takes the mean
    of the others (None if all are)."""
    n = 2 * np.asarray(image, np.float64) - 1
    n = n @ np.linalg.inv(np.asarray(matrix, np.float64)[:3, :3])  # rows: n^T M^-1 = (M^-T n)^T
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    good = length[..., 0] > 1e-3
    if not good.any():
        return None
    n = np.where(good[..., None], n / np.maximum(length, 1e-12), 0)
    mean = n[good].mean(axis=0)
    n[~good] = mean / max(np.linalg.norm(mean), 1e-12)
    return n.astype(np.float32)


@contextmanager
def _temporary_copy(depsgraph, obj):
    """A temporary object with the evaluated mesh of obj (faces in the order the export solved
    them, the user's UV maps and attributes) and copies of its slot materials, at obj's matrix;
    removed afterwards with everything it used."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = bpy.data.meshes.new_from_object(evaluated, preserve_all_data_layers=True, depsgraph=depsgraph)
    copies = []
    copy = None
    try:
        # (Clearing the slots sets every face's material index to 0: they are put back after.)
        slots = np.zeros(len(mesh.polygons), np.int32)
        mesh.polygons.foreach_get("material_index", slots)
        mesh.materials.clear()
        for material in user_slots(obj):
            copies.append(material.copy() if material is not None else None)
            mesh.materials.append(copies[-1])
        mesh.polygons.foreach_set("material_index", slots)
        copy = bpy.data.objects.new(f"{BAKE_UV} {obj.name}", mesh)
        copy.matrix_world = evaluated.matrix_world
        depsgraph.scene.collection.objects.link(copy)
        yield copy, mesh
    finally:
        if copy is not None:
            bpy.data.objects.remove(copy)
        bpy.data.meshes.remove(mesh)
        for material in copies:
            if material is not None:
                bpy.data.materials.remove(material)


def _bake(copy, mesh, layout, kind) -> np.ndarray:
    """Cycles' diffuse colour ('DIFFUSE'), glossy colour ('GLOSSY'), emission ('EMIT') or shading
    normal in object space as (n + 1) / 2 ('NORMAL', bumps included) of the copy's materials over
    the layout's UVs: (height, width, 3)."""
    uv = mesh.uv_layers.new(name=BAKE_UV, do_init=False)
    if uv is None:
        raise ExportError(f"object '{copy.name}': no room for a UV map to bake its textures (8 at most)")
    mesh.uv_layers[BAKE_UV].data.foreach_set("uv", layout.uvs.ravel())
    image = bpy.data.images.new(f"{BAKE_UV} image", layout.width, layout.height, alpha=False, float_buffer=True)
    nodes = []
    try:
        image.colorspace_settings.name = "Non-Color"
        for material in mesh.materials:
            if material is None or material.node_tree is None:
                continue
            node = material.node_tree.nodes.new("ShaderNodeTexImage")
            node.image = image
            material.node_tree.nodes.active = node
            nodes.append(node)
        with _bake_settings(copy):
            options = dict(type=kind, uv_layer=BAKE_UV, margin=PAD, use_clear=True, target="IMAGE_TEXTURES")
            if kind in {"DIFFUSE", "GLOSSY"}:
                options["pass_filter"] = {"COLOR"}
            if kind == "NORMAL":
                options.update(normal_space="OBJECT", normal_r="POS_X", normal_g="POS_Y", normal_b="POS_Z")
            bpy.ops.object.bake(**options)
        pixels = np.empty(layout.width * layout.height * 4, np.float32)
        image.pixels.foreach_get(pixels)
        return pixels.reshape(layout.height, layout.width, 4)[..., :3].copy()
    finally:
        bpy.data.images.remove(image)
        mesh.uv_layers.remove(mesh.uv_layers[BAKE_UV])


@contextmanager
def _bake_settings(copy):
    """Cycles on the CPU with the bake's samples, only the copy selected and active; the scene's
    engine, samples, bake settings and the user's selection put back afterwards."""
    scene = bpy.context.scene
    view_layer = bpy.context.view_layer
    render, cycles, bake = scene.render, scene.cycles, scene.render.bake
    saved = {
        (render, "engine"): render.engine,
        (cycles, "samples"): cycles.samples,
        (cycles, "use_denoising"): cycles.use_denoising,
        (cycles, "device"): cycles.device,
        (bake, "margin"): bake.margin,
        (bake, "use_clear"): bake.use_clear,
        (bake, "target"): bake.target,
        **{(bake, name): getattr(bake, name) for name in ("normal_space", "normal_r", "normal_g", "normal_b")},
    }
    selected = [o for o in view_layer.objects if o.select_get()]
    active = view_layer.objects.active
    try:
        render.engine = "CYCLES"
        cycles.samples = BAKE_SAMPLES
        cycles.use_denoising = False
        cycles.device = "CPU"
        for o in selected:
            o.select_set(False)
        copy.select_set(True)
        view_layer.objects.active = copy
        yield
    finally:
        for (owner, name), value in saved.items():
            setattr(owner, name, value)
        copy.select_set(False)
        for o in selected:
            if o.name in view_layer.objects:
                o.select_set(True)
        view_layer.objects.active = active


def colour_source(material, folded: bool = False):
    """How the bake can show a textured diffuse material's own colour nodes (sharp, at their own
    resolution) instead of its baked texture: (node, colour input, diffuse weight, specular) when
    the material's output takes a Principled BSDF or a Diffuse BSDF whose colour is driven by nodes
    and the solve made it Lambertian with an albedo texture and no emission texture, so that its
    albedo is colour x weight + specular, or a layered coat over the colour (weight 1, specular
    0: the base colour itself; folded, with the object solved diffuse, as a Lambertian's); else
    None."""
    if material is None or material.node_tree is None:
        return None
    output = active_output(material.node_tree, "OUTPUT_MATERIAL")
    node = linked_node(output.inputs["Surface"]) if output is not None else None
    colour = {"BSDF_PRINCIPLED": "Base Color", "BSDF_DIFFUSE": "Color"}.get(getattr(node, "type", None))
    if colour is None or node.id_data != material.node_tree or not node.inputs[colour].is_linked:
        return None
    solved = solver_material(material, describe_material(material, []), [])
    if solved.kind not in {"lambert", "diffuse_ggx"} or not solved.albedo_textured or solved.emission_textured:
        return None
    if solved.kind == "diffuse_ggx" and not folded:  # the base colour under a layered coat (no metal, no transmission)
        return node, colour, 1.0, (0.0, 0.0, 0.0)
    weight = 1.0
    if node.type == "BSDF_PRINCIPLED":
        # The solved albedo is the colour layered under the specular lobe, colour (1 - E) + E;
        # metals and transmission mix in otherwise, and show the baked texture instead.
        if any(node.inputs[name].is_linked or socket_value(node, name) > 0 for name in ("Metallic", "Transmission Weight")):
            return None
        weight = 1 - max(solved.specular)
    return node, colour, weight, tuple(solved.specular)


def normal_source(material):
    """The shader node of the material's own tree whose Normal input the bake can show (the
    user's normal map or bump nodes, at their own resolution), when the material's output takes
    a Diffuse or Principled BSDF so driven and the solve made it a bumped Lambertian; else None."""
    if material is None or material.node_tree is None:
        return None
    output = active_output(material.node_tree, "OUTPUT_MATERIAL")
    node = linked_node(output.inputs["Surface"]) if output is not None else None
    if node is None or node.type not in BUMPED_SHADERS or node.id_data != material.node_tree:
        return None
    if not any(link.is_valid and not link.is_muted for link in node.inputs["Normal"].links):
        return None
    return node if solver_material(material, describe_material(material, []), []).bumped else None


def tint_source(material):
    """How the bake can show a textured glossy colour's own nodes (sharp, at their own resolution)
    instead of its baked f0 texture: (node, colour input, weight, offset), f0 = colour x weight +
    offset, when the material's output takes a Glossy BSDF whose Color, or a Principled BSDF whose
    Base Color, is driven by nodes, and the solve made it GGX with a specular texture: Cycles'
    glossy-colour pass, the solve's f0 texture, is then the Glossy BSDF's colour, and a Principled
    BSDF's metallic blend m colour + (1 - m) f0 of its dielectric lobe (checked against the pass
    to 3e-4), where Metallic, IOR, Specular IOR Level and Specular Tint are not node-driven, there
    is no coat, and below Metallic 1 the tint is white and nothing transmits. Else None: the
    baked texture is shown."""
    if material is None or material.node_tree is None:
        return None
    output = active_output(material.node_tree, "OUTPUT_MATERIAL")
    node = linked_node(output.inputs["Surface"]) if output is not None else None
    colour = {"BSDF_PRINCIPLED": "Base Color", "BSDF_GLOSSY": "Color", "BSDF_ANISOTROPIC": "Color"}.get(
        getattr(node, "type", None))
    # Inside a node group the shader's colour is the group's, which the material's copy cannot link.
    if colour is None or node.id_data != material.node_tree or not any(
            link.is_valid and not link.is_muted for link in node.inputs[colour].links):
        return None
    solved = solver_material(material, describe_material(material, []), [])
    if solved.kind != "ggx" or not solved.specular_textured:
        return None
    if node.type != "BSDF_PRINCIPLED":
        return node, colour, 1.0, (0.0, 0.0, 0.0)
    metallic = socket_value(node, "Metallic")
    fixed = ("Metallic", "IOR", "Specular IOR Level", "Specular Tint", "Coat Weight")
    if any(node.inputs[name].is_linked for name in fixed if name in node.inputs) or socket_value(node, "Coat Weight") > 0:
        return None
    if metallic < 1 and (tuple(node.inputs["Specular Tint"].default_value)[:3] != (1.0, 1.0, 1.0)
                         or node.inputs["Transmission Weight"].is_linked or socket_value(node, "Transmission Weight") > 0):
        return None
    return node, colour, metallic, ((1 - metallic) * dielectric_f0(node),) * 3


MEAN_TEXELS = 8  # per face side, for the mean of a node-driven roughness or metallic


def socket_means(depsgraph) -> dict:
    """(material name, node name, input name) -> the mean of each node-driven roughness or metallic input
    (materials.AVERAGED_INPUTS) over the mesh faces using its material, area-weighted, as
    Blender evaluates it: the input's own nodes baked as emission on a temporary copy of each
    mesh. The solve's BSDF has one roughness and metallic per material."""
    users: dict = {}  # material -> [(object, slot)]
    for obj in depsgraph.scene.objects:
        if obj.type == "MESH" and obj.visible_get():
            for slot, material in enumerate(user_slots(obj)):
                if _averaged_sockets(material):
                    users.setdefault(material, []).append((obj, slot))
    means = {}
    for material, where in users.items():
        for node, name in _averaged_sockets(material):
            total = area = 0.0
            for obj, slot in where:
                t, a = _socket_integral(depsgraph, obj, slot, node, name)
                total, area = total + t, area + a
            if area > 0:
                means[(material.name, node.name, name)] = total / area
    if users:
        depsgraph.update()  # the temporary copies are gone: the depsgraph the export iterates must know
    return means


def _averaged_sockets(material) -> list:
    if material is None or material.node_tree is None:
        return []
    return [(node, name) for node in material.node_tree.nodes for name in AVERAGED_INPUTS.get(node.type, ())
            if node.inputs.get(name) is not None and node.inputs[name].is_linked]


def _socket_integral(depsgraph, obj, slot, node, name):
    """(integral, area) over obj's faces of the slot of the input's value, from an emission bake
    of the nodes driving it on per-face tiles."""
    with _temporary_copy(depsgraph, obj) as (copy, mesh):
        slots = np.zeros(len(mesh.polygons), np.int32)
        mesh.polygons.foreach_get("material_index", slots)
        mine = np.flatnonzero(np.minimum(slots, len(mesh.materials) - 1) == slot)
        if not len(mine):
            return 0.0, 0.0
        tree = mesh.materials[slot].node_tree
        source = tree.nodes[node.name].inputs[name].links[0].from_socket
        emission = tree.nodes.new("ShaderNodeEmission")
        tree.links.new(source, emission.inputs["Color"])
        output = active_output(tree, "OUTPUT_MATERIAL")
        tree.links.new(emission.outputs[0], output.inputs["Surface"])
        kinds = [{3: "triangle", 4: "quad"}.get(p.loop_total, "ngon") for p in mesh.polygons]
        layout = _TileLayout(mesh, kinds, MEAN_TEXELS)
        pixels = _bake(copy, mesh, layout, "EMIT")
        c = (np.arange(MEAN_TEXELS) + 0.5) / MEAN_TEXELS
        u = np.meshgrid(c, c)[0][..., None]
        scale = abs(np.linalg.det(np.array(copy.matrix_world)[:3, :3])) ** (2 / 3)
        total = area = 0.0
        for index in mine:
            kind = kinds[index]
            if kind == "ngon":
                continue
            values = layout.texture(pixels, index, kind)[..., :1]
            # The collapsed square of a triangle: area element proportional to u.
            weights = np.ones_like(values) if kind == "quad" else u
            a = mesh.polygons[index].area * scale
            total += a * float((values * weights).sum() / weights.sum())
            area += a
        return total, area
