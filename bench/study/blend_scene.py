"""What the study reads of a .blend with bpy, independently of the solver: triangulated world-space
geometry per object and polygon (NURBS surfaces tessellated finely), each material as Blender
describes it, and the area lights. The Mitsuba reference and the Cycles bake are built from this;
the solver gets the same file through the add-on's own export."""
from __future__ import annotations

import importlib.util
import math
import pathlib
import sys
from dataclasses import dataclass, field

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
# The tessellation of NURBS surfaces for the path tracer and the Cycles bake: fine enough that the
# facets lie within ~1e-4 of the exact surface on the example scenes.
NURBS_RESOLUTION = 32


def load_addon():
    """The add-on as the package `bsgi_addon`, registered (its export reads the materials)."""
    spec = importlib.util.spec_from_file_location("bsgi_addon_cli", ROOT / "addon" / "cli.py")
    cli = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(cli)
    addon = cli.load_addon()
    try:
        addon.register()
    except ValueError:
        pass  # already registered in this process
    return addon


def open_blend(path):
    import bpy

    load_addon()
    bpy.ops.wm.open_mainfile(filepath=str(pathlib.Path(path).resolve()))
    refine_nurbs()
    return bpy.context


def refine_nurbs():
    """Finer tessellation of NURBS surfaces in this session's copy of the scene (never saved)."""
    import bpy

    for curve in bpy.data.curves:
        for spline in curve.splines:
            spline.resolution_u = max(spline.resolution_u, NURBS_RESOLUTION)
            spline.resolution_v = max(spline.resolution_v, NURBS_RESOLUTION)


@dataclass
class Material:
    """A Blender material as its shader nodes state it (before the solver's single-BSDF choice)."""

    albedo: tuple
    specular: tuple
    roughness: float
    transmission: float
    ior: float
    emission: tuple
    # Anisotropic GGX as Cycles sets it up (see the add-on's SurfaceMaterial): alpha_x =
    # roughness^2 * stretch along the tangent turned by `rotation` radians about the normal.
    stretch: float = 1.0
    rotation: float = 0.0
    # The lobe's Fresnel in Cycles: Schlick's from `specular` (metals) or none (a Glossy BSDF's colour).
    schlick: bool = True
    # A lone dielectric Principled BSDF: `specular` is a coat over the base, layered as Cycles does.
    coat: bool = False
    # Cycles' Multiscatter GGX (the default distribution): the light between microfacets put back.
    multiscatter: bool = False


@dataclass
class ObjectMesh:
    name: str
    positions: np.ndarray  # (V, 3) world space
    triangles: np.ndarray  # (T, 3) vertex indices
    polygon: np.ndarray  # (T,) polygon index of each triangle
    material: np.ndarray  # (T,) index into materials
    materials: list = field(default_factory=list)
    tangent: np.ndarray = None  # (T, 3) Blender's default tangent per triangle (default_tangents)
    # (T, 3, 3) the shading normal at each triangle's corners as Cycles takes it: Blender's corner
    # normals, the face's on a flat face, interpolated on a smooth one (a NURBS surface's).
    normals: np.ndarray = None


@dataclass
class Light:
    name: str
    shape: str  # RECTANGLE (squares too) | DISK (ellipses too)
    matrix: np.ndarray  # 4x4 world matrix
    half_a: float
    half_b: float
    radiance: tuple  # Cycles' convention: power / (pi * area) times the colour


def describe(material) -> Material:
    from bsgi_addon.materials import describe_material

    d = describe_material(material, [])
    return Material(d.albedo, d.specular, d.roughness, d.transmission, d.ior, d.emission, d.stretch, d.rotation, d.schlick,
                    d.coat, d.multiscatter)


def default_tangents(world, triangles, radial):
    """The tangent Cycles gives an anisotropic BSDF whose Tangent input is not connected (the
    add-on's RadialTangent, checked against Cycles' Tangent node) at each triangle's centroid,
    projected onto its plane. Unit vectors, (T, 3)."""
    corners = world[triangles]
    t = radial.at(corners.mean(axis=1))
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    t -= n * np.einsum("ij,ij->i", t, n)[:, None]
    # On the axis the radial direction vanishes: any tangent does there (a set of measure zero).
    fallback = np.cross(n, np.where(np.abs(n[:, :1]) > 0.5, [[0, 1, 0]], [[1, 0, 0]]))
    t = np.where(np.linalg.norm(t, axis=1, keepdims=True) > 1e-12, t, fallback)
    return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)


def corner_normals(mesh, matrix) -> np.ndarray:
    """Blender's corner normals of the mesh's loop triangles, in world space: (T, 3, 3)."""
    normals = np.empty(len(mesh.loops) * 3)
    mesh.corner_normals.foreach_get("vector", normals)
    loops = np.empty(len(mesh.loop_triangles) * 3, np.int64)
    mesh.loop_triangles.foreach_get("loops", loops)
    world = normals.reshape(-1, 3) @ np.linalg.inv(matrix[:3, :3])  # normals transform by the inverse transpose
    world /= np.maximum(np.linalg.norm(world, axis=1, keepdims=True), 1e-300)
    return world[loops].reshape(-1, 3, 3)


def object_meshes(context) -> list:
    """Every visible geometry object as triangles (the evaluated mesh, as Cycles sees it)."""
    from bsgi_addon.geometry import GEOMETRY_TYPES
    from bsgi_addon.tangents import RadialTangent

    depsgraph = context.evaluated_depsgraph_get()
    out = []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type not in GEOMETRY_TYPES or inst.is_instance:
            continue
        mesh = obj.to_mesh()
        try:
            if mesh is None or not len(mesh.polygons):
                continue
            co = np.empty(len(mesh.vertices) * 3)
            mesh.vertices.foreach_get("co", co)
            m = np.array(inst.matrix_world, float)
            world = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
            mesh.calc_loop_triangles()
            n = len(mesh.loop_triangles)
            tris = np.empty(n * 3, np.int64)
            mesh.loop_triangles.foreach_get("vertices", tris)
            poly = np.empty(n, np.int64)
            mesh.loop_triangles.foreach_get("polygon_index", poly)
            mat = np.empty(n, np.int64)
            mesh.loop_triangles.foreach_get("material_index", mat)
            slots = [s.material for s in obj.original.material_slots] or [None]
            mat = np.minimum(mat, len(slots) - 1)
            tris = tris.reshape(-1, 3)
            out.append(ObjectMesh(obj.name, world, tris, poly, mat, [describe(s) for s in slots],
                                  default_tangents(world, tris, RadialTangent(m, [tuple(c) for c in obj.bound_box])),
                                  corner_normals(mesh, m)))
        finally:
            obj.to_mesh_clear()
    return out


def lights(context) -> list:
    depsgraph = context.evaluated_depsgraph_get()
    out = []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != "LIGHT" or obj.data.type != "AREA":
            continue
        light = obj.data
        m = np.array(inst.matrix_world, float)
        a = light.size / 2
        b = (light.size_y if light.shape in {"RECTANGLE", "ELLIPSE"} else light.size) / 2
        disk = light.shape in {"DISK", "ELLIPSE"}
        area = np.linalg.norm(np.cross(m[:3, 0] * a, m[:3, 1] * b)) * (math.pi if disk else 4)
        radiance = tuple(c * light.energy / (math.pi * area) for c in light.color)
        out.append(Light(obj.name, "DISK" if disk else "RECTANGLE", m, a, b, radiance))
    return out


def main_argv():
    """Arguments after `--` (when run by Blender) or after the script name."""
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]


def describe_blend(blend) -> dict:
    """The scene as plain data (for processes without bpy): {"objects": [...], "lights": [...]}."""
    context = open_blend(blend)
    return {"objects": object_meshes(context), "lights": lights(context)}


if __name__ == "__main__":
    # python blend_scene.py scene.blend out.pickle: the description, for the Mitsuba process
    # (Mitsuba's LLVM and Blender's libraries are kept in separate processes).
    import pickle

    import blend_scene  # this file as a module, so the pickle names its classes importably

    blend, out = main_argv()
    pathlib.Path(out).write_bytes(pickle.dumps(blend_scene.describe_blend(blend)))
