"""Blender geometry -> the solver's surfaces: mesh faces as bilinear and triangle patches, meshes as
UV charts (their own UV map, or one generated and carried by their modifiers), SURFACE objects as
exact NURBS surfaces, and instances at their world matrices."""
from __future__ import annotations

from dataclasses import dataclass, field

import bpy
import numpy as np
from mathutils import Matrix

import bsgi

from . import charts
from .errors import ExportError
from .properties import object_setting
from .materials import THIN_SLAB_MAX_RATIO, GlassShape, ObjectMaterials, object_materials, surface_options, user_slots
from .user_materials import UV_NAME, user_spline_material_index

GEOMETRY_TYPES = {"MESH", "SURFACE", "CURVE", "FONT", "META"}


# Objects solved through their evaluated mesh (to_mesh) but not baked, by the name users know.
EVALUATED_ONLY = {"CURVE": "curve", "FONT": "text", "META": "metaball"}


@dataclass
class ExportedObject:
    """One Blender object's faces (in polygon order) or NURBS splines, as scene surfaces."""

    name: str
    polygon_count: int
    # Per polygon: ("quad" | "triangle" | "ngon", first scene index, number of patches);
    # for a SURFACE object per spline: ("nurbs", scene index, 1).
    patches: list = field(default_factory=list)
    kind: str = "mesh"  # "mesh" | "nurbs" | "chart" (one MeshChart: patches = [("chart", index, 1)])
    chart_uvs: object = None  # a chart's UV coordinates per loop of the user's mesh, (loops, 2), for the bake
    solve_uvs: object = None  # a chart's (u, v) per loop of the evaluated mesh it was solved on, (loops, 2)
    # Why the object is solved (it casts shadows and reflects light) but cannot be baked, or "".
    not_baked: str = ""


# Cycles shades a smooth face with its corner normals interpolated; so does the solver (the cosine
# of the light, a glossy lobe's frame and a glass's read the interpolated normal).
# Corner normals this close to their face's are a flat face (float32 normals differ by 0.03).
FLAT_FACE_DEGREES = 0.1


@dataclass
class CornerNormals:
    """A mesh's corner normals in world space (loops, 3), turned to the solver's winding of its
    faces (world corners in loop order), and the angle in degrees each face's turn from its own."""

    normals: np.ndarray
    turn: np.ndarray  # per polygon

    def smooth(self, polygon: int) -> bool:
        return bool(self.turn[polygon] > FLAT_FACE_DEGREES)

    def at(self, polygon: int, loops):
        """The normals of these corners of the polygon where it is smooth, else None (flat)."""
        return self.normals[list(loops)] if self.smooth(polygon) else None

    def of_mesh(self):
        """All corners' normals where any face is smooth (a chart's), else None."""
        return self.normals if self.turn.max(initial=0.0) > FLAT_FACE_DEGREES else None


def corner_normals(mesh, matrix=None) -> CornerNormals:
    corner = np.empty(len(mesh.loops) * 3)
    mesh.corner_normals.foreach_get("vector", corner)
    corner = corner.reshape(-1, 3)
    face = np.empty(len(mesh.polygons) * 3)
    mesh.polygons.foreach_get("normal", face)
    totals = np.empty(len(mesh.polygons), np.int64)
    mesh.polygons.foreach_get("loop_total", totals)
    starts = np.empty(len(mesh.polygons), np.int64)
    mesh.polygons.foreach_get("loop_start", starts)
    order = np.argsort(starts)  # each face's corners are the loops from its start on
    of_corner = np.repeat(order, totals[order])
    cosines = np.einsum("ij,ij->i", corner, face.reshape(-1, 3)[of_corner])
    turn = np.zeros(len(mesh.polygons))
    if len(cosines):
        np.maximum.at(turn, of_corner, np.degrees(np.arccos(np.clip(cosines, -1.0, 1.0))))
    if matrix is not None:
        # Normals go by the cofactor matrix det(M) M^-T: the inverse transpose, turned with the
        # winding of the world corners where M mirrors (the solver's front follows the winding),
        # and defined where M is singular (an object scaled flat, refused by name elsewhere).
        c = np.array(matrix, float)[:3, :3].T  # rows: the images of the axes
        cofactor = np.array([np.cross(c[1], c[2]), np.cross(c[2], c[0]), np.cross(c[0], c[1])])
        corner = corner @ cofactor
        length = np.linalg.norm(corner, axis=1, keepdims=True)
        collapsed = length[:, 0] <= 1e-12 * max(np.abs(cofactor).max(), 1e-300)
        corner /= np.where(length > 0, length, 1.0)
        if collapsed.any():  # no normal left: those faces flat
            turn[np.unique(of_corner[collapsed])] = 0.0
    return CornerNormals(corner, turn)


def _add_mesh_object(scene, obj, mesh, matrix: Matrix, warnings, label: str | None = None,
                     pending_charts: list | None = None) -> ExportedObject:
    co = np.empty(len(mesh.vertices) * 3, np.float64)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    m = np.array(matrix, float)
    world = co @ m[:3, :3].T + m[:3, 3]
    modified = label is None and obj.type == "MESH" and pending_charts is not None and _modifiers_change_faces(obj, mesh)
    label = label or obj.name
    materials = object_materials(obj, matrix, warnings, label, surface_options(obj))
    normals = corner_normals(mesh, matrix)
    exported = ExportedObject(obj.name, len(mesh.polygons))
    if any(m.kind == "rough_dielectric" for m in materials.solver):
        thin = materials.use_glass(glass_shape(world, mesh), glass_choice(obj), warnings)
        if thin and thin >= _used_slots(mesh, len(materials.solver)):
            exported.not_baked = PANE_NOTE
        elif thin:
            warnings.append(f"object '{label}': its thin glass faces show no light in the bake; separate the glass "
                            "into an object of its own (Edit Mode: P > By Material) to see it through its glass "
                            "material")
    pane = exported.not_baked == PANE_NOTE  # per face: a pane needs no chart, it is not baked
    if modified and not pane:
        # The user's mesh shows the evaluated faces only through a UV map the modifiers carry
        # to them: one chart, or no bake.
        problem = _chart_refusal(obj, mesh, user_slots(obj))
        if not problem:
            pending_charts.append(_chart_job(exported, mesh, world, materials, label, normals, base=obj.original))
            return exported
        exported.not_baked = f"its modifiers ({modifier_names(obj)}) change its faces and {problem}; {APPLY_ADVICE}"
    elif not pane and pending_charts is not None and _wants_chart(obj, mesh, user_slots(obj), label, warnings):
        pending_charts.append(_chart_job(exported, mesh, world, materials, label, normals))
        return exported
    ngon_tris = {}
    if any(p.loop_total > 4 for p in mesh.polygons):
        mesh.calc_loop_triangles()
        for tri in mesh.loop_triangles:
            ngon_tris.setdefault(tri.polygon_index, []).append((tuple(tri.vertices), tuple(tri.loops)))
    for poly in mesh.polygons:
        name = f"{label}: face {poly.index}"
        verts = list(poly.vertices)
        first = len(scene)
        loops = list(range(poly.loop_start, poly.loop_start + poly.loop_total))
        if len(verts) <= 4:
            pieces, kind = [(name, verts, loops)], "quad" if len(verts) == 4 else "triangle"
        else:
            pieces, kind = [(f"{name} triangle {k}", list(tri), list(tri_loops))
                            for k, (tri, tri_loops) in enumerate(ngon_tris[poly.index])], "ngon"
        try:
            for piece, corners, corner_loops in pieces:
                surface = (bsgi.BilinearPatch if len(corners) == 4 else bsgi.TrianglePatch)(
                    piece, world[corners], normals=normals.at(poly.index, corner_loops))
                materials.add(scene, poly.material_index, surface)
        except ValueError as error:
            raise ExportError(str(error)) from None
        exported.patches.append((kind, first, len(pieces)))
    materials.warn(warnings)
    return exported


# A window pane has no spline: the renderer shows it with the user's own glass material.
PANE_NOTE = ("it is a thin glass pane, which has no radiance spline; its own glass material shows it as Material "
             "Preview and Cycles show glass (the outside through it, the room reflected in it, from the baked "
             "surfaces around)")


def glass_choice(obj) -> str:
    """The object's Glass setting (Object properties): AUTO, THIN or SOLID."""
    return object_setting(obj, "glass")


def _used_slots(mesh, slots: int) -> set:
    indices = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", indices)
    return {min(int(i), slots - 1) for i in np.unique(indices)}


def glass_shape(world: np.ndarray, mesh) -> GlassShape:
    """Whether a mesh (world vertex positions) is a pane: all faces in one plane, or a closed
    solid whose extent along its thinnest principal axis is small against the next one."""
    used = np.unique(np.fromiter((v for p in mesh.polygons for v in p.vertices), np.int64))
    points = world[used] - world[used].mean(axis=0)
    axes = np.linalg.svd(points, full_matrices=False)[2]
    extent = np.ptp(points @ axes.T, axis=0)  # along the principal axes, widest first
    if extent[2] <= 1e-6 * max(extent[0], 1e-12):
        return GlassShape("plane", "a single plane")
    edges: dict = {}
    for poly in mesh.polygons:
        for key in poly.edge_keys:
            edges[key] = edges.get(key, 0) + 1
    closed = all(count == 2 for count in edges.values())
    size = f"{extent[2]:.3g} thick, {extent[1]:.3g} wide"
    if not closed:
        return GlassShape("open", "an open surface not in one plane")
    if extent[2] < THIN_SLAB_MAX_RATIO * extent[1]:
        return GlassShape("slab", f"a thin closed slab ({size})")
    return GlassShape("thick", f"a closed solid ({size}: thicker than {THIN_SLAB_MAX_RATIO:g} of its width)")


def chart_min_faces(scene) -> int:
    settings = getattr(scene, "bsgi", None)
    return settings.chart_min_faces if settings is not None else 0


APPLY_ADVICE = "apply the modifiers (Object > Apply) to bake it"


def _modifiers_change_faces(obj, mesh) -> bool:
    """Whether the evaluated mesh has other faces than the user's mesh (Subdivision Surface,
    Mirror, Array, Solidify, Bevel...): then a bake per face of the user's mesh cannot show it."""
    data = obj.original.data
    return len(data.polygons) != len(mesh.polygons) or len(data.loops) != len(mesh.loops)


def modifier_names(obj) -> str:
    return ", ".join(m.name for m in obj.original.modifiers if m.show_viewport) or "none shown"


def _chart_refusal(obj, mesh, slots: list) -> str:
    """Why a mesh whose modifiers change its faces cannot be one chart, or ''."""
    if object_setting(obj, "mesh_surfaces") == "FACES":
        return "its Mesh Surfaces setting is Per Face"
    indices = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", indices)
    if len({slots[min(int(i), len(slots) - 1)] for i in np.unique(indices)}) > 1:
        return "it has several materials (a UV chart has one)"
    return ""


def _wants_chart(obj, mesh, slots: list, label: str, warnings) -> bool:
    """From the scene's face count (0: never) a mesh of one material becomes a UV chart, unless
    the object says otherwise; a chart is one surface with one BSDF, so a mesh of several
    materials stays per face."""
    choice = object_setting(obj, "mesh_surfaces")
    threshold = chart_min_faces(bpy.context.scene)
    if choice == "FACES" or (choice == "AUTO" and (not threshold or len(mesh.polygons) < threshold)):
        return False
    indices = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", indices)
    if len({slots[min(int(i), len(slots) - 1)] for i in np.unique(indices)}) > 1:
        warnings.append(f"object '{label}': {len(mesh.polygons)} faces of several materials are solved per face, "
                        "not as one UV chart (a chart has one material)")
        return False
    return True


@dataclass
class _ChartJob:
    """What a chart needs, read while the depsgraph is iterated; built after (a generated UV map
    needs a temporary object in the scene, which would disturb the iteration)."""

    exported: ExportedObject
    label: str
    world: np.ndarray  # (V, 3) world positions
    triangles: np.ndarray  # (T, 3) vertex indices
    triangle_loops: np.ndarray  # (T, 3) loop indices
    polygons: list  # vertex index tuples, for a generated UV map
    uvs: np.ndarray | None  # per loop, from a suitable UV map of the user's, or None
    materials: ObjectMaterials
    slot: int  # the chart's material (of its first face)
    uv_reasons: list
    # A mesh whose modifiers change its faces: the user's object, whose own mesh's loops get the
    # bake's UVs (the modifiers carry them to the evaluated faces).
    base: object = None
    base_uvs: np.ndarray | None = None  # per loop of the user's mesh, for the bake
    loop_count: int = 0  # of the evaluated mesh
    normals: np.ndarray | None = None  # per loop, world (smooth shading), or None: flat faces


def _chart_job(exported, mesh, world, materials, label, normals: CornerNormals, base=None) -> _ChartJob:
    triangles, loops = charts.loop_triangles(mesh)
    name, found = charts.suitable_uv_map(mesh, loops)
    if base is not None and name is not None and base.data.uv_layers.get(name) is None:
        # Made by the modifiers (geometry nodes): the bake cannot give it to the user's mesh.
        name, found = None, [f"UV map '{name}' is made by its modifiers"]
    indices = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", indices)
    polygons = [tuple(p.vertices) for p in mesh.polygons] if name is None else []
    # The user's UV map as their own mesh holds it: the modifiers carry it to the faces solved.
    base_uvs = charts.layer_uvs(base.data, name) if base is not None and name is not None else None
    return _ChartJob(exported, label, world, triangles, loops, polygons, found if name is not None else None,
                     materials, int(indices[0]), [] if name is not None else found, base, base_uvs, len(mesh.loops),
                     normals.of_mesh())


def build_chart(scene, job: _ChartJob, warnings) -> None:
    uvs = job.uvs
    if uvs is None and job.base is not None:
        uvs = _carried_generated_uvs(job, warnings)
        if uvs is None:  # not baked: any chart of the evaluated faces will do for the solve
            uvs = charts.generated_uvs(job.world, job.polygons, job.label)
    if uvs is None:
        uvs = charts.generated_uvs(job.world, job.polygons, job.label)
        why = "; ".join(job.uv_reasons) or "it has no UV map"
        if not job.exported.not_baked:  # a UV map only the solve sees needs no word
            warnings.append(f"object '{job.label}': solved as one UV chart over a UV map generated by Smart UV "
                            f"Project (no UV map of its own is a chart: {why}); the object's own UV maps are unchanged")
        problem = charts.chart_problem(uvs[job.triangle_loops])
        if problem:
            raise ExportError(f"object '{job.label}': the generated UV map is not a chart ({problem}); set its "
                              "Mesh Surfaces (Object Properties > B-spline GI) to Per Face")
    first = len(scene)
    try:
        chart = bsgi.MeshChart(f"{job.label}: chart 0", job.world, job.triangles, uvs[job.triangle_loops],
                               corner_normals=None if job.normals is None else job.normals[job.triangle_loops])
        job.materials.add(scene, job.slot, chart)
    except ValueError as error:
        raise ExportError(str(error)) from None
    job.materials.warn(warnings)
    job.exported.kind = "chart"
    bake_uvs = uvs if job.base is None else job.base_uvs
    job.exported.chart_uvs = None if job.exported.not_baked else bake_uvs.astype(np.float32)
    job.exported.solve_uvs = uvs.astype(np.float32)
    job.exported.patches = [("chart", first, 1)]


def _carried_generated_uvs(job: _ChartJob, warnings):
    """For a mesh whose modifiers change its faces and carry none of its UV maps as a chart: a
    UV map generated on a copy of the user's mesh, carried by the user's modifier stack (on a
    temporary object) to the evaluated faces. Returns the evaluated faces' UVs (the user's mesh
    gets the generated ones only at the bake), or None, and then the object is not baked."""
    data = job.base.data
    co = np.empty(len(data.vertices) * 3, np.float64)
    data.vertices.foreach_get("co", co)
    generated = charts.generated_uvs(co.reshape(-1, 3), [tuple(p.vertices) for p in data.polygons], job.label)
    # The map as generated, then squeezed into the left or the lower half of the UV square: a
    # modifier that mirrors or offsets its copies' UVs (Mirror's Mirror U / V, Array's UV offsets)
    # then lays the copies in the other half.
    problem = ""
    for scale in ((1.0, 1.0), (0.5, 1.0), (1.0, 0.5)):
        base_uvs = generated * scale
        carried = charts.carried_uvs(job.base, UV_NAME, base_uvs)
        if carried is None or len(carried) != job.loop_count:
            problem = "they do not carry UV maps"
            break
        problem = charts.chart_problem(carried[job.triangle_loops])
        if not problem:
            break
    why = "; ".join(job.uv_reasons) or "it has no UV map"
    if problem:
        job.exported.not_baked = (f"its modifiers ({modifier_names(job.base)}) change its faces, and neither its own "
                                  f"UV maps ({why}) nor one generated by Smart UV Project before them are a chart "
                                  f"after them ({problem}), even in half the UV square; {APPLY_ADVICE}, or let "
                                  "their copies' UVs move (Mirror U / V, Array's UV offsets)")
        return None
    warnings.append(f"object '{job.label}': solved as one UV chart over a UV map generated by Smart UV Project and "
                    f"carried by its modifiers (no UV map of its own is a chart after them: {why}); the bake adds it "
                    f"as the UV map '{UV_NAME}', the object's own UV maps are unchanged")
    job.base_uvs = base_uvs
    return carried


def nurbs_surface(name: str, spline, matrix: Matrix) -> "bsgi.NurbsSurface":
    """A Blender SURFACE spline as the exact rational surface, control points in world space.
    Points are Cartesian with the weight beside them, so the affine transform commutes with the
    rational combination: transforming the points transforms the surface."""
    co = np.empty(len(spline.points) * 4, np.float64)
    spline.points.foreach_get("co", co)
    co = co.reshape(-1, 4)
    m = np.array(matrix, float)
    co[:, :3] = co[:, :3] @ m[:3, :3].T + m[:3, 3]
    return bsgi.NurbsSurface(name, co, spline.point_count_u, spline.point_count_v, spline.order_u, spline.order_v,
                             spline.use_endpoint_u, spline.use_endpoint_v, spline.use_bezier_u, spline.use_bezier_v,
                             spline.use_cyclic_u, spline.use_cyclic_v)


def _nurbs_problem(spline) -> str:
    """Why Blender draws nothing for a spline (its knot rule cannot use the point counts), or ''."""
    return (bsgi.blender_nurbs_problem(spline.point_count_u, spline.order_u, spline.use_endpoint_u, spline.use_bezier_u,
                                       spline.use_cyclic_u)
            or bsgi.blender_nurbs_problem(spline.point_count_v, spline.order_v, spline.use_endpoint_v,
                                          spline.use_bezier_v, spline.use_cyclic_v))


def baked_splines(obj) -> list:
    """The splines of a SURFACE object that are solved and baked: NURBS ones Blender draws."""
    return [s for s in obj.data.splines if s.type == "NURBS" and not _nurbs_problem(s)]


def _add_nurbs_object(scene, obj, matrix: Matrix, warnings, label: str | None = None) -> ExportedObject | None:
    """One exact NURBS surface per spline of a SURFACE object (not its tessellation)."""
    original = obj.original
    label = label or obj.name
    if original.modifiers:
        warnings.append(f"object '{obj.name}': modifiers of NURBS surfaces are ignored (the splines are solved exactly)")
    materials = object_materials(original, matrix, warnings, label, surface_options(obj))
    exported = ExportedObject(obj.name, 0, kind="nurbs")
    if any(m.kind == "rough_dielectric" for m in materials.solver):
        if materials.use_glass(GlassShape("open", "a NURBS surface"), glass_choice(obj), warnings):
            exported.not_baked = PANE_NOTE
    drawn = baked_splines(original)
    for k, spline in enumerate(original.data.splines):
        if spline.type != "NURBS":
            continue
        if spline not in drawn:
            warnings.append(f"object '{obj.name}': spline {k} is skipped, Blender draws nothing for it "
                            f"({_nurbs_problem(spline)})")
            continue
        first = len(scene)
        index = user_spline_material_index(original, k)
        try:
            surface = nurbs_surface(f"{label}: spline {k}", spline, matrix)
            materials.add(scene, index, surface)
        except ValueError as error:
            raise ExportError(str(error)) from None
        exported.patches.append(("nurbs", first, 1))
    materials.warn(warnings)
    return exported if exported.patches else None


def own_geometry(inst) -> bool:
    """Whether an instance is the evaluated mesh of a curve, surface, text or metaball object,
    which Blender lists beside the object itself (also inside collection instances): the object
    is exported already. (Geometry-nodes instances made by such an object look the same and are
    skipped too.)"""
    obj = inst.object
    return inst.is_instance and obj.type == "MESH" and obj.original.type in {"SURFACE", "CURVE", "FONT", "META"}


def add_object(scene, obj, matrix: Matrix, warnings, label: str | None, pending_charts: list) -> ExportedObject | None:
    """One evaluated geometry object (a real object or an instance) at its world matrix."""
    if obj.type == "SURFACE":
        return _add_nurbs_object(scene, obj, matrix, warnings, label)
    mesh = obj.to_mesh()
    try:
        if mesh is None or len(mesh.polygons) == 0:
            return None
        return _add_mesh_object(scene, obj, mesh, matrix, warnings, label, pending_charts)
    finally:
        obj.to_mesh_clear()
