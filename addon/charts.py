"""Meshes of many faces as one UV chart (bsgi.MeshChart): one radiance spline over a UV map
instead of a patch per face.

The UV map must be a chart: inside [0, 1]^2, islands not overlapping (one spline value per UV
point) and with area. The user's first such UV map is used; without one, a UV map is generated
by Smart UV Project on a temporary copy of the mesh, never on the user's mesh."""
from __future__ import annotations

import bpy
import numpy as np

# Overlaps are looked for on a grid of this many texels per side: islands overlapping by less
# than a texel (1/512 of the UV square) pass.
OVERLAP_GRID = 512
# Smart UV Project: faces within this angle form one island; islands this far apart in UV.
UNWRAP_ANGLE_DEGREES = 66.0
UNWRAP_MARGIN = 0.02


class ChartUnavailable(ValueError):
    """No chart can be made for the mesh; the message says why."""


def loop_triangles(mesh):
    """(T, 3) vertex indices and (T, 3) loop indices of the mesh's triangulation, counter-clockwise
    seen from the front (Blender keeps the polygons' winding)."""
    mesh.calc_loop_triangles()
    count = len(mesh.loop_triangles)
    verts = np.empty(count * 3, np.int64)
    loops = np.empty(count * 3, np.int64)
    mesh.loop_triangles.foreach_get("vertices", verts)
    mesh.loop_triangles.foreach_get("loops", loops)
    return verts.reshape(-1, 3), loops.reshape(-1, 3)


def layer_uvs(mesh, name: str) -> np.ndarray:
    uv = np.empty(len(mesh.loops) * 2, np.float64)
    mesh.uv_layers[name].data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)


def chart_problem(corner_uvs: np.ndarray) -> str:
    """Why the (T, 3, 2) UV triangles are not a chart, or ''."""
    if not np.isfinite(corner_uvs).all():
        return "it has non-finite coordinates"
    if corner_uvs.min() < -1e-6 or corner_uvs.max() > 1 + 1e-6:
        return "it leaves the square [0, 1]"
    e1, e2 = corner_uvs[:, 1] - corner_uvs[:, 0], corner_uvs[:, 2] - corner_uvs[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    if not (area > 1e-12).all():
        return f"{int(np.sum(area <= 1e-12))} of its triangles have no UV area"
    return "its islands overlap" if _overlaps(corner_uvs) else ""


def _overlaps(corner_uvs: np.ndarray) -> bool:
    """Whether any texel centre of a fine grid lies inside two UV triangles (edges excluded, so
    triangles sharing an edge do not count). Triangles are tested a batch at a time, each batch
    as one flat array of (triangle, texel of its bounding box) candidates; the first overlap ends it."""
    n = OVERLAP_GRID
    lo = np.clip(np.floor(corner_uvs.min(axis=1) * n - 0.5), 0, n - 1).astype(np.int64)
    hi = np.clip(np.ceil(corner_uvs.max(axis=1) * n - 0.5), 0, n - 1).astype(np.int64)
    counts = (hi[:, 0] - lo[:, 0] + 1) * (hi[:, 1] - lo[:, 1] + 1)
    ends = np.cumsum(counts)
    cover = np.zeros(n * n, np.int64)
    start = 0
    while start < len(counts):
        # About CANDIDATES_PER_BATCH candidates per batch; a triangle is never split.
        stop = max(start + 1, int(np.searchsorted(ends, ends[start] - counts[start] + CANDIDATES_PER_BATCH, "right")))
        cover += _covered_texels(corner_uvs[start:stop], lo[start:stop], hi[start:stop], n)
        if cover.max() > 1:
            return True
        start = stop
    return False


CANDIDATES_PER_BATCH = 1 << 20


def _covered_texels(corner_uvs, lo, hi, n) -> np.ndarray:
    """How many of the triangles hold each texel centre, as a flat (n * n) count."""
    width, height = hi[:, 0] - lo[:, 0] + 1, hi[:, 1] - lo[:, 1] + 1
    counts = width * height
    tri = np.repeat(np.arange(len(corner_uvs)), counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    ix = lo[tri, 0] + local % width[tri]
    iy = lo[tri, 1] + local // width[tri]
    a, b, c = corner_uvs[tri, 0], corner_uvs[tri, 1], corner_uvs[tri, 2]
    px, py = (ix + 0.5) / n, (iy + 0.5) / n
    d = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    w1 = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (py - a[:, 1]) * (c[:, 0] - a[:, 0])) / d
    w2 = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (b[:, 1] - a[:, 1]) * (px - a[:, 0])) / d
    eps = 1e-9
    inside = (w1 > eps) & (w2 > eps) & (1 - w1 - w2 > eps)
    return np.bincount(iy[inside] * n + ix[inside], minlength=n * n)


def suitable_uv_map(mesh, loops: np.ndarray) -> tuple:
    """(name, per-loop UVs) of the mesh's first UV map that is a chart (the active render map
    first), or (None, reasons) naming why each is not."""
    layers = sorted(mesh.uv_layers, key=lambda layer: not layer.active_render)
    reasons = []
    for layer in layers:
        uv = layer_uvs(mesh, layer.name)
        problem = chart_problem(uv[loops])
        if not problem:
            return layer.name, np.clip(uv, 0.0, 1.0)
        reasons.append(f"UV map '{layer.name}': {problem}")
    return None, reasons


def generated_uvs(positions: np.ndarray, polygons: list, label: str) -> np.ndarray:
    """Per-loop UVs by Smart UV Project on a temporary mesh built from positions and polygons
    (a copy: the user's mesh is never unwrapped). The temporary object is linked to the scene
    only while the operator runs, then removed with its mesh; the active object and the selection
    are restored."""
    context = bpy.context
    if context.mode != "OBJECT":
        raise ChartUnavailable(f"object '{label}': a UV map must be generated for it; switch to Object Mode to solve")
    data = bpy.data.meshes.new("BSGI unwrap")
    data.from_pydata(positions.tolist(), [], polygons)
    tmp = bpy.data.objects.new("BSGI unwrap", data)
    collection = context.scene.collection
    collection.objects.link(tmp)
    layer = context.view_layer
    active = layer.objects.active
    # Edit mode takes every selected mesh along: only the copy may be selected meanwhile.
    selected = [o for o in layer.objects if o.select_get()]
    try:
        for o in selected:
            o.select_set(False)
        tmp.select_set(True)
        layer.objects.active = tmp
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.mesh.select_all(action="SELECT")
        # Every option given: an operator otherwise reuses the values of its last call.
        bpy.ops.uv.smart_project(angle_limit=np.radians(UNWRAP_ANGLE_DEGREES), margin_method="SCALED",
                                 rotate_method="AXIS_ALIGNED_Y", island_margin=UNWRAP_MARGIN, area_weight=0.0,
                                 correct_aspect=True, scale_to_bounds=False)
        bpy.ops.object.mode_set(mode="OBJECT")
        if not data.uv_layers:
            raise ChartUnavailable(f"object '{label}': Smart UV Project made no UV map")
        return np.clip(layer_uvs(data, data.uv_layers[0].name), 0.0, 1.0)
    finally:
        if tmp.mode != "OBJECT":
            bpy.ops.object.mode_set(mode="OBJECT")
        layer.objects.active = active
        for o in selected:
            o.select_set(True)
        collection.objects.unlink(tmp)
        bpy.data.objects.remove(tmp)
        bpy.data.meshes.remove(data)


def carried_uvs(obj, name: str, base_uvs: np.ndarray):
    """Per-loop UVs of obj's evaluated mesh if its own mesh had the per-loop base_uvs in a UV map
    called name: evaluated on a temporary copy of the object (same modifiers) over a copy of its
    mesh, both removed afterwards; the user's object and mesh are not touched. None if the
    modifiers drop the UV map (e.g. Remesh)."""
    context = bpy.context
    data = obj.data.copy()
    tmp = obj.copy()
    tmp.data = data
    if data.uv_layers.get(name) is None and data.uv_layers.new(name=name, do_init=False) is None:
        bpy.data.objects.remove(tmp)
        bpy.data.meshes.remove(data)
        raise ChartUnavailable(f"object '{obj.name}': it has the most UV maps a mesh can hold; remove one to bake it")
    data.uv_layers[name].data.foreach_set("uv", np.ascontiguousarray(base_uvs, np.float32).ravel())
    context.scene.collection.objects.link(tmp)
    try:
        evaluated = tmp.evaluated_get(context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        try:
            return layer_uvs(mesh, name) if mesh.uv_layers.get(name) is not None else None
        finally:
            evaluated.to_mesh_clear()
    finally:
        context.scene.collection.objects.unlink(tmp)
        bpy.data.objects.remove(tmp)
        bpy.data.meshes.remove(data)
