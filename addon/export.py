"""Blender scene -> bsgi.Scene: the only place that reads the user's scene for a solve.

Nothing of the user's data is changed here: meshes come from the evaluated depsgraph
(`to_mesh()` on evaluated objects, cleared afterwards)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import bpy
import numpy as np
from mathutils import Matrix

import bsgi

# Blender's look for a surface with no material: a light grey diffuse.
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
GEOMETRY_TYPES = {"MESH", "SURFACE", "CURVE", "FONT", "META"}


class ExportError(ValueError):
    """The scene cannot be solved as it is; the message names the object and the problem."""


@dataclass
class ExportedObject:
    """One Blender object's faces, in polygon order, as scene surfaces."""

    name: str
    polygon_count: int
    # Per polygon: ("quad" | "triangle" | "ngon", first scene index, number of patches).
    patches: list = field(default_factory=list)


@dataclass
class Export:
    scene: bsgi.Scene
    objects: list  # of ExportedObject, the bake targets
    warnings: list


@dataclass
class SurfaceMaterial:
    albedo: tuple
    emission: tuple


def _socket_color(node, name):
    sock = node.inputs.get(name)
    if sock is None:
        return None
    value = sock.default_value
    return tuple(value[:3]) if hasattr(value, "__len__") else (float(value),) * 3


def material_for(material, warnings) -> SurfaceMaterial:
    """Lambertian albedo and emitted radiance of a material's surface shader."""
    if material is None:
        return SurfaceMaterial(DEFAULT_ALBEDO, (0.0, 0.0, 0.0))
    tree = material.node_tree
    output = None
    if tree is not None:
        output = next((n for n in tree.nodes if n.type == "OUTPUT_MATERIAL" and n.is_active_output), None)
        output = output or next((n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"), None)
    if output is None or not output.inputs["Surface"].is_linked:
        return SurfaceMaterial(tuple(material.diffuse_color[:3]), (0.0, 0.0, 0.0))
    shader = output.inputs["Surface"].links[0].from_node
    textured = [s.name for s in shader.inputs if s.is_linked]
    if textured:
        warnings.append(f"material '{material.name}': inputs {', '.join(textured)} are linked to nodes; "
                        "their unlinked values are used")
    if shader.type == "BSDF_DIFFUSE":
        return SurfaceMaterial(_socket_color(shader, "Color"), (0.0, 0.0, 0.0))
    if shader.type == "EMISSION":
        strength = shader.inputs["Strength"].default_value
        return SurfaceMaterial((0.0, 0.0, 0.0), tuple(c * strength for c in _socket_color(shader, "Color")))
    if shader.type == "BSDF_PRINCIPLED":
        strength = shader.inputs["Emission Strength"].default_value
        emission = tuple(c * strength for c in _socket_color(shader, "Emission Color"))
        return SurfaceMaterial(_socket_color(shader, "Base Color"), emission)
    warnings.append(f"material '{material.name}': shader '{shader.bl_idname}' is approximated by its viewport colour")
    return SurfaceMaterial(tuple(material.diffuse_color[:3]), (0.0, 0.0, 0.0))


def _area_light(scene, obj, warnings):
    light = obj.data
    if light.shape not in {"SQUARE", "RECTANGLE"}:
        warnings.append(f"light '{obj.name}': {light.shape.lower()} area lights are not supported yet; skipped")
        return
    a = light.size / 2
    b = (light.size if light.shape == "SQUARE" else light.size_y) / 2
    m = obj.matrix_world
    # Blender area lights emit along their local -Z: order the corners so s_u x s_v points there.
    corners = np.array([m @ _v(-a, -b), m @ _v(-a, b), m @ _v(a, b), m @ _v(a, -b)], float)
    area = np.linalg.norm(np.cross(corners[1] - corners[0], corners[3] - corners[0]))
    if not area > 0:
        raise ExportError(f"light '{obj.name}': zero size")
    # Cycles: an area light of power P watts emits radiance P / (pi * A) (checked against a render).
    radiance = light.energy / (math.pi * area)
    emission = [c * radiance for c in light.color]
    scene.add_bilinear_patch(f"{obj.name}", corners, albedo=[0, 0, 0], emission=emission, receiver=False, occluder=False)


def _v(x, y):
    from mathutils import Vector

    return Vector((x, y, 0.0))


def _add_mesh_object(scene, obj, mesh, matrix: Matrix, warnings) -> ExportedObject:
    co = np.empty(len(mesh.vertices) * 3, np.float64)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    m = np.array(matrix, float)
    world = co @ m[:3, :3].T + m[:3, 3]
    materials = [SurfaceMaterial(DEFAULT_ALBEDO, (0.0, 0.0, 0.0))]
    if obj.material_slots:
        materials = [material_for(slot.material, warnings) for slot in obj.material_slots]
    exported = ExportedObject(obj.name, len(mesh.polygons))
    ngon_tris = {}
    if any(p.loop_total > 4 for p in mesh.polygons):
        mesh.calc_loop_triangles()
        for tri in mesh.loop_triangles:
            ngon_tris.setdefault(tri.polygon_index, []).append(tuple(tri.vertices))
    for poly in mesh.polygons:
        mat = materials[min(poly.material_index, len(materials) - 1)]
        name = f"{obj.name}: face {poly.index}"
        verts = list(poly.vertices)
        first = len(scene)
        try:
            if len(verts) == 4:
                scene.add_bilinear_patch(name, world[verts], albedo=mat.albedo, emission=mat.emission)
                exported.patches.append(("quad", first, 1))
            elif len(verts) == 3:
                scene.add_triangle(name, world[verts], albedo=mat.albedo, emission=mat.emission)
                exported.patches.append(("triangle", first, 1))
            else:
                for k, tri in enumerate(ngon_tris[poly.index]):
                    scene.add_triangle(f"{name} triangle {k}", world[list(tri)], albedo=mat.albedo, emission=mat.emission)
                exported.patches.append(("ngon", first, len(ngon_tris[poly.index])))
        except ValueError as error:
            raise ExportError(str(error)) from None
    return exported


def export_scene(depsgraph) -> Export:
    """Every visible geometry object's faces as patches, every area light as an emitter."""
    scene = bsgi.Scene()
    objects, warnings = [], []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == "LIGHT":
            if obj.data.type == "AREA":
                _area_light(scene, obj, warnings)
            else:
                warnings.append(f"light '{obj.name}': {obj.data.type.lower()} lights are not supported yet; skipped")
            continue
        if obj.type not in GEOMETRY_TYPES:
            continue
        if inst.is_instance:
            warnings.append(f"object '{obj.name}': instances are not baked yet; skipped")
            continue
        mesh = obj.to_mesh()
        try:
            if mesh is None or len(mesh.polygons) == 0:
                continue
            objects.append(_add_mesh_object(scene, obj, mesh, inst.matrix_world, warnings))
        finally:
            obj.to_mesh_clear()
    return Export(scene, objects, warnings)
