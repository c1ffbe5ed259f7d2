"""Cycles baking, the tool Blender users reach for, on the study's pairs: every object baked
(COMBINED: emission, direct and indirect light, diffuse, glossy and transmission) into one float
atlas at several sample counts, each bake timed, then the atlas looked up at each pair's point.

    python bench/study/cycles_bake.py scene.blend pairs.npz out.npz RESOLUTION SAMPLES...

A Cycles bake is view-independent: glossy surfaces are baked as seen along their normal, whatever
the direction a pair looks from. A bake sees each surface's front only: objects that pairs.npz
names in "two_sided" (optional; the validation scenes' planes lit and seen on both sides) are
baked a second time with their normals flipped, as a user would bake a plane's back side, and the
pairs seen from behind read that bake; a bake's time is the sum of both. The scene's copy in this
process is changed (atlas UV map, image nodes, NURBS objects turned into meshes), never saved."""
from __future__ import annotations

import json
import math
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import blend_scene  # noqa: E402

UV_NAME = "StudyBake"
MARGIN = 3  # pixels of bake margin around each tile (Cycles extends the edges into it)
FACE_TILES_MAX = 64  # objects with more polygons get a tile per connected part, over their own UV map


def bake_objects(context):
    """Mesh objects to bake, by original object name: SURFACE objects become meshes of their
    (refined) tessellation, as a user must do to bake them."""
    import bpy

    from bsgi_addon.geometry import GEOMETRY_TYPES

    out = {}
    for obj in list(context.scene.objects):
        if obj.type not in GEOMETRY_TYPES or obj.hide_render:
            continue
        if obj.type == "MESH":
            out[obj.name] = obj
            continue
        mesh = bpy.data.meshes.new_from_object(obj.evaluated_get(context.evaluated_depsgraph_get()))
        baked = bpy.data.objects.new(obj.name + " (mesh)", mesh)
        baked.matrix_world = obj.matrix_world
        context.scene.collection.objects.link(baked)
        obj.hide_render = True
        out[obj.name] = baked
    return out


def _components(mesh):
    """Connected parts of a mesh (union-find over polygon vertices): polygon -> part."""
    parent = list(range(len(mesh.vertices)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for poly in mesh.polygons:
        vs = list(poly.vertices)
        for v in vs[1:]:
            a, b = find(vs[0]), find(v)
            if a != b:
                parent[a] = b
    roots = [find(p.vertices[0]) for p in mesh.polygons]
    ids = {r: k for k, r in enumerate(dict.fromkeys(roots))}
    return [ids[r] for r in roots]


def _planar_uv(points):
    """Coordinates of a polygon's corners in its own plane (Newell normal), at true scale."""
    n = np.zeros(3)
    for a, b in zip(points, np.roll(points, -1, axis=0)):
        n += np.cross(a, b)
    n /= np.linalg.norm(n)
    e1 = points[1] - points[0]
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    q = points - points[0]
    return np.stack([q @ e1, q @ e2], axis=1)


def atlas_layout(objects, resolution):
    """One UV map per object over a shared atlas: a square tile per polygon (small meshes, their
    faces at true aspect) or per connected part (large ones, over their own UV map)."""
    charts = []  # (object, [(loop indices, 2D coordinates)])
    for obj in objects.values():
        mesh = obj.data
        co = np.array([v.co for v in mesh.vertices])
        if len(mesh.polygons) <= FACE_TILES_MAX:
            for poly in mesh.polygons:
                charts.append((obj, [(list(poly.loop_indices), _planar_uv(co[list(poly.vertices)]))]))
            continue
        if mesh.uv_layers:
            source = np.array([d.uv for d in mesh.uv_layers.active.data])
        else:  # Smart UV Project, as the add-on does for a mesh without a UV map
            from bsgi_addon import charts

            source = charts.generated_uvs(co, [tuple(p.vertices) for p in mesh.polygons], obj.name)
        parts = {}
        for poly, part in zip(mesh.polygons, _components(mesh)):
            loops = list(poly.loop_indices)
            parts.setdefault(part, []).append((loops, source[loops]))
        charts += [(obj, polys) for polys in parts.values()]
    grid = math.ceil(math.sqrt(len(charts)))
    tile = resolution / grid
    for obj in objects.values():
        if UV_NAME not in obj.data.uv_layers:
            obj.data.uv_layers.new(name=UV_NAME)
        obj.data.uv_layers.active = obj.data.uv_layers[UV_NAME]
    for k, (obj, polys) in enumerate(charts):
        row, col = divmod(k, grid)
        allc = np.concatenate([c for _, c in polys])
        lo, span = allc.min(0), max(np.ptp(allc, axis=0).max(), 1e-12)
        inner = (tile - 2 * MARGIN - 1) / resolution
        origin = np.array([col * tile + MARGIN + 0.5, row * tile + MARGIN + 0.5]) / resolution
        uv = obj.data.uv_layers[UV_NAME].data
        for loops, c in polys:
            for i, p in zip(loops, origin + (c - lo) / span * inner):
                uv[i].uv = p


def attach_image(objects, image):
    """An active Image Texture node with the atlas in every material the objects use (a default
    diffuse material, Blender's grey, where a slot or object has none)."""
    import bpy

    for obj in objects.values():
        if not obj.data.materials:
            obj.data.materials.append(None)
        for k, m in enumerate(obj.data.materials):
            if m is None:
                m = bpy.data.materials.new("Study default")
                obj.data.materials[k] = m
            node = m.node_tree.nodes.get("Study bake") or m.node_tree.nodes.new("ShaderNodeTexImage")
            node.name = "Study bake"
            node.image = image
            m.node_tree.nodes.active = node


def set_cycles(scene, samples):
    """Cycles as a path tracer without bias: many bounces, no clamping, no glossy filter, no denoiser."""
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_denoising = False
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = 32
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    scene.render.bake.margin = MARGIN
    scene.render.bake.use_clear = True
    scene.render.bake.target = "IMAGE_TEXTURES"


def bake(context, objects, image, resolution):
    """One COMBINED bake of the objects into the atlas: (its pixels (RGB), seconds, CPU seconds)."""
    import bpy

    for obj in context.scene.objects:
        obj.select_set(obj in objects.values())
    context.view_layer.objects.active = next(iter(objects.values()))
    start, cpu = time.perf_counter(), time.process_time()
    bpy.ops.object.bake(type="COMBINED", uv_layer=UV_NAME, margin=MARGIN, use_clear=True)
    seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu
    pixels = np.empty(resolution * resolution * 4, np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(resolution, resolution, 4)[..., :3].astype(float), seconds, cpu_seconds


def seen_from_behind(objects, pairs):
    """Mask of the pairs on the given objects whose eye is behind their polygon's normal."""
    out = np.zeros(len(pairs["point"]), bool)
    for j, (name, poly) in enumerate(zip(pairs["object"], pairs["polygon"])):
        obj = objects.get(str(name))
        if obj is not None:
            m = np.array(obj.matrix_world, float)
            normal = np.linalg.inv(m[:3, :3]).T @ np.array(obj.data.polygons[int(poly)].normal)
            out[j] = normal @ (pairs["eye"][j] - pairs["point"][j]) < 0
    return out


def lookup(objects, pixels, resolution, pairs):
    """The atlas bilinearly interpolated at each pair's point (found in its polygon's triangles)."""
    out = np.full((len(pairs["point"]), 3), np.nan)
    cache = {}
    for j, (name, poly, p) in enumerate(zip(pairs["object"], pairs["polygon"], pairs["point"])):
        obj = objects[str(name)]
        if obj.name not in cache:
            mesh = obj.data
            mesh.calc_loop_triangles()
            m = np.array(obj.matrix_world, float)
            co = np.array([v.co for v in mesh.vertices]) @ m[:3, :3].T + m[:3, 3]
            uv = np.array([d.uv for d in mesh.uv_layers[UV_NAME].data])
            tris = {}
            for t in mesh.loop_triangles:
                tris.setdefault(t.polygon_index, []).append((list(t.vertices), list(t.loops)))
            cache[obj.name] = (co, uv, tris)
        co, uv, tris = cache[obj.name]
        best = None
        for verts, loops in tris[int(poly)]:
            a, b, c = co[verts]
            # Barycentrics of p projected onto the triangle; the one p lies in (least outside).
            m2 = np.array([b - a, c - a]).T
            w, *_ = np.linalg.lstsq(m2, p - a, rcond=None)
            bary = np.array([1 - w.sum(), w[0], w[1]])
            if best is None or bary.min() > best[0]:
                best = (bary.min(), bary @ uv[loops])
        x, y = best[1] * resolution - 0.5
        i0, j0 = int(np.floor(x)), int(np.floor(y))
        fx, fy = x - i0, y - j0
        i0, j0 = np.clip([i0, j0], 0, resolution - 2)
        out[j] = ((1 - fx) * (1 - fy) * pixels[j0, i0] + fx * (1 - fy) * pixels[j0, i0 + 1]
                  + (1 - fx) * fy * pixels[j0 + 1, i0] + fx * fy * pixels[j0 + 1, i0 + 1])
    return out


def main():
    blend, pairs_npz, out_npz, resolution, *samples = blend_scene.main_argv()
    resolution = int(resolution)
    import bpy

    context = blend_scene.open_blend(blend)
    pairs = dict(np.load(pairs_npz))
    objects = bake_objects(context)
    atlas_layout(objects, resolution)
    image = bpy.data.images.new("Study atlas", resolution, resolution, float_buffer=True, alpha=False)
    image.colorspace_settings.name = "Non-Color"
    attach_image(objects, image)
    backs = {name: obj for name, obj in objects.items() if name in {str(n) for n in pairs.get("two_sided", ())}}
    behind = seen_from_behind(backs, pairs)
    results = {}
    for n in map(int, samples):
        set_cycles(context.scene, n)
        pixels, seconds, cpu_seconds = bake(context, objects, image, resolution)
        radiance = lookup(objects, pixels, resolution, pairs)
        if backs:
            for obj in backs.values():
                obj.data.flip_normals()
            pixels, back_seconds, back_cpu_seconds = bake(context, backs, image, resolution)
            for obj in backs.values():
                obj.data.flip_normals()
            radiance[behind] = lookup(objects, pixels, resolution, pairs)[behind]
            seconds, cpu_seconds = seconds + back_seconds, cpu_seconds + back_cpu_seconds
        results[f"radiance_{n}"] = radiance
        results[f"seconds_{n}"], results[f"cpu_seconds_{n}"] = seconds, cpu_seconds
        print(json.dumps({"samples": n, "seconds": seconds, "cpu_seconds": cpu_seconds}), flush=True)
    np.savez(out_npz, **results)


if __name__ == "__main__":
    main()
