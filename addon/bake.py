"""Solved radiance -> what Blender shows: per object a float image atlas of its radiance (one
tile per face sized by its own spline, shelf-packed, a UV chart's square or a NURBS surface's parameter square), repeated for each
angular sample of a glossy surface's disc (20)-(22); two images of the surfaces' frames (1)-(3);
a UV map laying the faces on their tiles (a chart's own UVs; a NURBS surface's mesh has its
UVMap); and an emission material that looks the atlas up, through the node groups of
view_radiance.py, with the direction the point is seen from.

The user's materials stay on the mesh untouched: the baked material is linked to the object's
material slots (slot.link = 'OBJECT'), and switching the slots back to 'DATA' shows the originals."""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, field

import bpy
import numpy as np

import bsgi
from bsgi.split import Band, SplitRadiance

from . import charts, error_view, geometry, textures, view_radiance
from .materials import solved_diffuse, user_slots
from .user_materials import PROP_SLOTS, PROP_SPLINE_INDICES, UV_NAME, is_baked, user_spline_material_index

PROP_ADDED_SLOT = "bsgi_added_slot"
PROP_MATERIAL = "bsgi_baked_material"
PROP_SPLINE_MATERIALS = "bsgi_spline_materials"  # SURFACE objects of several splines: a material per spline
PROP_RADIANCE = "bsgi_radiance"  # the faces' radiance, for re-baking and solution export
# Slots of textured materials: a baked material of their own that shows the user's colour nodes
# times the irradiance spline (diffuse), or blending the radiance at f0 = 0 and 1 (a glossy colour),
# per slot ("" for the object's baked material).
PROP_SLOT_MATERIALS = "bsgi_slot_materials"
PROP_BAKED_IMAGE = "bsgi_baked"  # on the images a bake makes (the user's stay when it is cleared)
# The splines of a SurfaceRadiance (bakes before two-sided surfaces stored the first three, before
# textured glossy colour the first four).
SIDES = ("upper", "lower", "diffuse", "lower_diffuse", "tint_zero", "lower_tint_zero")
# The textures of a SurfaceRadiance (bakes before textured glossy colour stored the first two,
# before normal maps the first three),
# and the base of an albedo texture under a layered coat (bsgi.SurfaceRadiance.coat_share).
TEXTURES = ("albedo", "emission", "specular", "normals")
# Detail slots whose material blends two atlases by the user's colour (a glossy colour's f0, a
# base colour under a layered coat) instead of multiplying one.
BLENDED = ("specular", "coat")
COAT = ("coat_share", "coat_albedo")
# The UV map Blender gives the mesh of a NURBS surface: normalized (u, v) parameters.
NURBS_UV_NAME = "UVMap"
# Largest radiance atlas per object, in texels (256 MiB of float RGBA): past it the angular
# samples are thinned, with a warning.
MAX_ATLAS_TEXELS = 1 << 24


def tile_size(radiance) -> int:
    """Texels per face side: two per coefficient, so the image resolves the spline's knots, and
    at least the resolution of the face's textures."""
    return max(8, 2 * max(axis.num_coeffs for axis in _upper(radiance).axes[:2]), _texture_side(radiance))


def _texture_side(radiance) -> int:
    """The larger side of a textured surface's albedo, specular or emission texture (0 without)."""
    images = [getattr(radiance, t, None) for t in TEXTURES]
    return max((max(i.shape[:2]) for i in images if i is not None), default=0)


def texture_at(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """A surface texture (h, w, 3) at (u, v) rows, as the core's Texture::at: bilinear between
    texel centres (i + 0.5) / w, clamped at the edges."""
    h, w = image.shape[:2]
    x = np.clip(np.clip(uv[:, 0], 0, 1) * w - 0.5, 0, w - 1)
    y = np.clip(np.clip(uv[:, 1], 0, 1) * h - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    a, b = (x - x0)[:, None], (y - y0)[:, None]
    image = image.astype(np.float64)
    return (image[y0, x0] * (1 - a) + image[y0, x1] * a) * (1 - b) + (image[y1, x0] * (1 - a) + image[y1, x1] * a) * b


def _upper(radiance):
    return radiance.upper if isinstance(radiance, (bsgi.SurfaceRadiance, SplitRadiance)) else radiance


def _splines(radiance):
    return [s for s in (getattr(radiance, side, None) for side in SIDES) if s is not None]


def angular_samples(faces) -> int:
    """Angular samples per disc axis: three per knot span of the glossy splines' angular knot
    vectors (the knots and two points between), 1 where every face is diffuse. The bilinear
    blend between samples is second order: two per span left 5.9% mean error on a rough glass
    sheet's transmitted lamp (tests/blender/test_bake_view.py), three 2.9%, four 1.7%, at
    (4/3)^2 and 2^2 the texels of three."""
    samples = 1
    for _, radiances in faces:
        for r in radiances:
            for s in ([] if r is None else _splines(r)):
                for axis in s.axes[2:]:
                    samples = max(samples, 3 * (axis.num_coeffs - axis.degree) + 1)
    return samples


def _disc_radius(obj, faces, bumped: bool = False) -> float:
    """The disc radius of the object's view-dependent faces (bumped: of its bumped faces, whose
    splines span the scene's cap of bumped normals instead)."""
    radii = {r.disc_radius for _, radiances in faces for r in radiances
             if r is not None and r.kind != "diffuse" and (getattr(r, "normals", None) is not None) == bumped}
    if len(radii) > 1:
        raise ValueError(f"object '{obj.name}': its {'bumped' if bumped else 'glossy'} faces use different disc radii "
                         f"{sorted(radii)}; solve them together")
    return radii.pop() if radii else 1.0


def _sides(faces) -> int:
    """2 if a face has a back side (a lower-hemisphere spline: it transmits, paper 4.3, or it is
    opaque and lit from behind, which Cycles shades with the same BSDF), else 1."""
    return 2 if any(r is not None and r.lower is not None for _, radiances in faces for r in radiances) else 1


def _radiance_at(radiance, uv: np.ndarray, disc: np.ndarray, lower: bool, smooth: bool = False,
                 f0: float = 0.0) -> np.ndarray:
    """(len(disc), len(uv), 3): the radiance leaving the (u, v) rows of uv at each disc point
    (alpha, beta), on the upper or the lower side, as SurfaceRadiance::evaluate gives it along
    the direction that the map (20)-(22) sends (alpha, beta) to, mirrored below the surface
    (the lower spline's directions are those of the upper one with z turned over). No lower
    spline: black. With smooth, a textured surface's smooth factor (irradiance / pi), which its
    material multiplies by the user's own colour nodes, and a textured glossy colour's radiance at
    the constant f0 (0 or 1), which its material blends by the user's own colour nodes."""
    out = np.zeros((len(disc), len(uv), 3))
    if radiance is None:
        return out
    # A textured GGX f0 blends the radiance at f0 = 1 (upper, lower) and at f0 = 0 (tint_zero).
    specular = getattr(radiance, "specular", None)
    tint = None if specular is None else np.full((1, len(uv), 3), f0) if smooth else texture_at(specular, uv)[None]
    black = getattr(radiance, "lower_tint_zero" if lower else "tint_zero", None)
    splines = [radiance.lower, radiance.lower_diffuse] if lower else [radiance.upper, radiance.diffuse]
    for spline, weight in zip(splines + [black], [tint, None, None if tint is None else 1 - tint]):
        if spline is None:
            continue
        if spline.dims == 2:
            # A textured surface's diffuse spline holds irradiance / pi: its albedo texture is the detail.
            out += spline.evaluate(np.ascontiguousarray(uv, np.float64))[None] * _texels_seen(radiance, uv, disc, smooth, f0)
            continue
        points = np.concatenate([np.broadcast_to(uv[None], (len(disc), len(uv), 2)),
                                 np.broadcast_to(disc[:, None], (len(disc), len(uv), 2))], axis=2)
        glossy = spline.evaluate(np.ascontiguousarray(points.reshape(-1, 4))).reshape(len(disc), len(uv), 3)
        if getattr(radiance, "normals", None) is not None:
            # Over a bumped normal (bsgi.BumpedLambert): irradiance / pi where an albedo texture is the detail.
            glossy = glossy * _texels_seen(radiance, uv, disc, smooth, f0)
        out += glossy if weight is None else glossy * weight
    emission = None if lower and not getattr(radiance, "two_sided_emission", False) else getattr(radiance, "emission", None)
    if emission is not None:
        out += texture_at(emission, uv)[None]
    return out


def _texels_seen(radiance, uv: np.ndarray, disc: np.ndarray, smooth: bool, f0: float):
    """What multiplies a diffuse spline at the (u, v) rows seen from each disc point: 1 without
    an albedo texture (and, with smooth, where the material multiplies by the user's colour);
    the texture (the constant f0 with smooth), each texel layered under a coat as seen along
    the disc point's direction (SurfaceRadiance.coated_texels) where the surface has one."""
    albedo = getattr(radiance, "albedo", None)
    coat = getattr(radiance, "coat_share", None) is not None
    if albedo is None or (smooth and not coat):
        return 1.0
    texels = np.full((len(uv), 3), f0) if smooth else texture_at(albedo, uv)
    if not coat:
        return texels[None]
    mu = np.abs(bsgi.HemisphereMap(radiance.disc_radius).to_direction(np.ascontiguousarray(disc, np.float64))[:, 2])
    seen = radiance.coated_texels(np.ascontiguousarray(np.broadcast_to(texels, (len(disc), *texels.shape)).reshape(-1, 3)),
                                  np.repeat(mu, len(uv)))
    return seen.reshape(len(disc), len(uv), 3)


def _tile_parameters(kind: str, t: int) -> np.ndarray:
    """(u, v) of the surface at the tile's texel centres, shape (t*t, 2), rows of constant y.

    The face's UV corners sit on the centres of the tile's corner texels, so texel (i, j) is at
    x = i / (t - 1), y = j / (t - 1) in the face's UV square. Quads are bilinear: (u, v) = (x, y).
    Triangles lie in the half y <= x of the square with corners (0, 0), (1, 0), (1, 1); the
    collapsed-square parameterization gives u = x, v = y / x (texels above the diagonal repeat
    the diagonal, so texture filtering never mixes in another face). N-gons, solved as
    triangle fans, show the mean of their triangles at (0.5, 0.5) until charts land."""
    if kind == "ngon":
        return np.full((t * t, 2), 0.5)
    x, y = np.meshgrid(np.linspace(0, 1, t), np.linspace(0, 1, t))
    if kind == "quad":
        u, v = x, y
    else:
        u = x
        v = np.divide(y, x, out=np.full_like(y, 0.5), where=x > 0)
        v = np.clip(v, 0, 1)
    return np.stack([u.ravel(), v.ravel()], axis=1)


def _face_uvs(kind: str, tile_origin, t: int, size, corners: int):
    """UV coordinates of a face's loops on its tile, matching _tile_parameters; size = the
    atlas's (width, height)."""
    (ox, oy), (w, h) = tile_origin, size
    if kind == "ngon":
        return [((ox + t / 2) / w, (oy + t / 2) / h)] * corners
    square = [(0, 0), (1, 0), (1, 1), (0, 1)] if kind == "quad" else [(0, 0), (1, 0), (1, 1)]
    return [((ox + 0.5 + sx * (t - 1)) / w, (oy + 0.5 + sy * (t - 1)) / h) for sx, sy in square[:corners]]


def face_splines(exported, surfaces) -> list:
    """Per polygon of an exported object: (kind, its SurfaceRadiance list) from a solution's
    `surfaces` (None for a surface that only emits)."""
    return [(kind, [surfaces[first + k] for k in range(count)]) for kind, first, count in exported.patches]


@dataclass
class Layout:
    """Where each texel of an object's spatial atlas (height x width) lies: the face and the
    surface parameters (u, v), face -1 for unused texels; the core surfaces whose frames the
    texels show; the UV map the material reads."""
    face: np.ndarray  # (height, width) int
    uv: np.ndarray  # (height, width, 2)
    surfaces: list
    uv_map: str

    @property
    def shape(self):
        return self.face.shape


def _world_points(obj):
    """The evaluated mesh of obj (what the exporter solved): world vertex positions, per polygon
    its vertex indices and (n-gons) its triangles, and per polygon its corners' normals where it
    is smooth (else None), as the solve's faces had them."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        co = np.empty(len(mesh.vertices) * 3, np.float64)
        mesh.vertices.foreach_get("co", co)
        m = np.array(evaluated.matrix_world, float)
        world = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
        polygons = [list(p.vertices) for p in mesh.polygons]
        mesh.calc_loop_triangles()
        first_triangle = {}
        for tri in mesh.loop_triangles:
            first_triangle.setdefault(tri.polygon_index, list(tri.vertices))
        normals = geometry.corner_normals(mesh, evaluated.matrix_world)
        return world, polygons, first_triangle, [normals.at(p.index, p.loop_indices) for p in mesh.polygons]
    finally:
        evaluated.to_mesh_clear()


def _evaluated_chart(obj):
    """The chart as the exporter solved it: the evaluated mesh's world positions, triangles,
    their corners' UVs in the bake's UV map, which the modifiers carry from the user's mesh (the
    two differ when modifiers change the faces), and their corners' normals where it is smooth
    (else None)."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    try:
        co = np.empty(len(mesh.vertices) * 3, np.float64)
        mesh.vertices.foreach_get("co", co)
        m = np.array(evaluated.matrix_world, float)
        triangles, loops = charts.loop_triangles(mesh)
        normals = geometry.corner_normals(mesh, evaluated.matrix_world).of_mesh()
        return (co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3], triangles, charts.layer_uvs(mesh, UV_NAME)[loops],
                None if normals is None else normals[loops])
    finally:
        evaluated.to_mesh_clear()


def _face_tile(radiances) -> int:
    """Side of a face's tile: the largest of its splines' tile_size (8 for a face that only emits)."""
    return max((tile_size(r) for r in radiances if r is not None), default=8)


def _shelf_rows(sides, width: int) -> list:
    """Tiles (side, index), tallest first, in rows filled left to right up to `width`:
    per row [(x, index)] and the row's height (its first tile's side)."""
    rows, x = [], width
    for side, index in sides:
        if x + side > width:
            rows.append(([], side))
            x = 0
        rows[-1][0].append((x, index))
        x += side
    return rows


def pack_tiles(sides) -> tuple:
    """Origins (x, y) of square tiles of the given sides on a shelf-packed atlas, and the atlas's
    (width, height): tiles sorted by side (stable, so equal tiles keep the faces' order), rows
    filled up to a width tried from the square root of the tiles' area upwards, keeping the
    smallest atlas (the squarer on a tie)."""
    order = sorted(((side, index) for index, side in enumerate(sides)), key=lambda s: -s[0])
    area = sum(side * side for side in sides)
    best = None
    for factor in np.linspace(1.0, 2.0, 21):
        width = max(order[0][0], math.ceil(math.sqrt(area) * factor))
        rows = _shelf_rows(order, width)
        used = max(x + sides[index] for row, _ in rows for x, index in row)
        height = sum(h for _, h in rows)
        key = (used * height, abs(used - height))
        if best is None or key < best[0]:
            best = (key, rows, used, height)
    _, rows, width, height = best
    origins = [None] * len(sides)
    y = 0
    for row, h in rows:
        for x, index in row:
            origins[index] = (x, y)
        y += h
    return origins, (width, height)


def _mesh_layout(obj, faces):
    """Per face a t x t tile (t from its own splines' knots), shelf-packed (pack_tiles); writes
    the bake's UV map laying each face on its tile."""
    mesh = obj.data
    if len(mesh.polygons) != len(faces):
        raise ValueError(f"object '{obj.name}': its modifiers change its faces; apply them before baking")
    sides = [_face_tile(radiances) for _, radiances in faces]
    origins, (width, height) = pack_tiles(sides)
    face = np.full((height, width), -1)
    uv = np.zeros((height, width, 2))
    uvs = np.zeros((len(mesh.loops), 2), np.float32)
    world, polygons, first_triangle, corner_normals = _world_points(obj)
    surfaces = []
    for index, (kind, _) in enumerate(faces):
        (ox, oy), t = origins[index], sides[index]
        face[oy:oy + t, ox:ox + t] = index
        uv[oy:oy + t, ox:ox + t] = _tile_parameters(kind, t).reshape(t, t, 2)
        poly = mesh.polygons[index]
        for loop, corner in zip(poly.loop_indices, _face_uvs(kind, (ox, oy), t, (width, height), poly.loop_total)):
            uvs[loop] = corner
        corners = world[polygons[index] if kind != "ngon" else first_triangle[index]]
        name = f"{obj.name}: face {index}"
        normals = corner_normals[index] if kind != "ngon" else None  # (an n-gon's tile: its first triangle, flat)
        surfaces.append((bsgi.BilinearPatch if kind == "quad" else bsgi.TrianglePatch)(name, corners, normals=normals))
    if mesh.uv_layers.get(UV_NAME) is None:
        mesh.uv_layers.new(name=UV_NAME, do_init=False)
    mesh.uv_layers[UV_NAME].data.foreach_set("uv", uvs.ravel())  # looked up by name again after creating it
    return Layout(face, uv, surfaces, UV_NAME)


def nurbs_image_size(radiance) -> tuple:
    """(width, height) of a NURBS surface's image: two texels per coefficient in u and v, at least 16."""
    return tuple(max(16, 2 * axis.num_coeffs, _texture_side(radiance)) for axis in _upper(radiance).axes[:2])


def _nurbs_layout(obj, spline, radiance):
    """Blender's mesh of the surface has UVs = normalized (u, v), and a linear image lookup at
    UV x reads texel centres at (i + 0.5) / width: each texel holds the radiance at its
    centre's parameters, so the image interpolates the spline there."""
    w, h = nurbs_image_size(radiance)
    u, v = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
    surface = geometry.nurbs_surface(f"{obj.name}: spline", spline, obj.matrix_world)
    return Layout(np.zeros((h, w), int), np.stack([u, v], axis=2), [surface], NURBS_UV_NAME)


def chart_image_size(radiance) -> int:
    """Side of a chart's image: four texels per coefficient (a chart's islands are smaller than
    the UV square they share), at least 64."""
    return max(64, 4 * max(axis.num_coeffs for axis in _upper(radiance).axes[:2]), _texture_side(radiance))


def _chart_layout(obj, radiance):
    """A chart's image over its UV square, texel centres at (i + 0.5) / n as for NURBS. Texels
    outside the islands hold the spline's smooth continuation (and the frame of the nearest
    point of the chart), so filtering at an island's border never mixes in a neighbour's light."""
    n = chart_image_size(radiance)
    u, v = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n)
    world, triangles, corner_uvs, corner_normals = _evaluated_chart(obj)
    surface = bsgi.MeshChart(f"{obj.name}: chart 0", world, triangles, corner_uvs, corner_normals=corner_normals)
    return Layout(np.zeros((n, n), int), np.stack([u, v], axis=2), [surface], UV_NAME)


def frame_pixels(layout: Layout):
    """(tangent, normal) images, (height, width, 4) each: the frame (1)-(3) of the core's
    surface at each texel, x along s_u and z the normal."""
    tangent = np.zeros((*layout.shape, 4), np.float32)
    normal = np.zeros((*layout.shape, 4), np.float32)
    tangent[..., 3] = normal[..., 3] = 1
    for index, surface in enumerate(layout.surfaces):
        mask = layout.face == index
        frames = surface.evaluate(np.ascontiguousarray(layout.uv[mask]))
        # The radiance frame: the splines' directions are in the shading frame on smooth faces.
        tangent[mask, :3], normal[mask, :3] = frames["shading_x"], frames["shading_normal"]
    return tangent, normal


def atlas_pixels(layout: Layout, faces, samples: int, radius, sides: int, smooth=frozenset(),
                 f0: float = 0.0) -> np.ndarray:
    """(sides * A * height, A * width, 4): the spatial atlas once per angular sample, tile (i, j)
    at the disc point (alpha_i, beta_j) = -R + 2R (i, j) / (A - 1) (the centre for A = 1); the
    lower hemisphere's tiles in the rows above the upper ones'. Samples outside the disc hold
    the spline's own values there (its domain is the square [-R, R]^2), so blending towards
    the rim stays smooth. The faces in smooth hold their smooth factors (_radiance_at), a
    textured glossy colour's at f0. radius: the disc's, or one per face."""
    radii = radius if isinstance(radius, (list, tuple)) else [radius] * len(faces)

    def disc_points(r):
        grid = np.linspace(-r, r, samples) if samples > 1 else np.zeros(1)
        beta, alpha = np.meshgrid(grid, grid, indexing="ij")
        return np.stack([alpha.ravel(), beta.ravel()], axis=1)  # row j * A + i

    h, w = layout.shape
    values = np.zeros((sides, samples * samples, h, w, 3))
    for index, (_, radiances) in enumerate(faces):
        check_cancelled()
        mask = layout.face == index
        uv = layout.uv[mask]
        disc = disc_points(radii[index])
        for side in range(sides):
            values[side][:, mask] = np.mean([_radiance_at(r, uv, disc, side == 1, index in smooth, f0)
                                             for r in radiances], axis=0)
    values = values.reshape(sides, samples, samples, h, w, 3).transpose(0, 1, 3, 2, 4, 5)
    pixels = np.ones((sides * samples * h, samples * w, 4), np.float32)
    pixels[..., :3] = values.reshape(sides * samples * h, samples * w, 3)
    return pixels


def _bake_layout(obj, name: str, layout: Layout, faces, detail=None):
    """The images and the material of one spatial layout: (material, warnings). detail:
    {slot: colour source}, and per face its slot (see _detail_slots), for textured slots that
    get a material of their own."""
    warnings = []
    samples, sides = angular_samples(faces), _sides(faces)
    h, w = layout.shape
    fitting = max(1, math.isqrt(MAX_ATLAS_TEXELS // (sides * h * w)))
    if samples > fitting:
        warnings.append(f"object '{obj.name}': its view-dependent radiance is baked at {fitting} x {fitting} "
                        f"directions instead of {samples} x {samples} (the image would pass "
                        f"{MAX_ATLAS_TEXELS} texels); glossy highlights are blurred")
        samples = fitting
    tangent, normal = frame_pixels(layout)
    sources, face_slots, bumps = detail or ({}, [], {})
    # A bumped surface's atlas is over its bumped normal, on the disc of the scene's bumped normals:
    # its slot's material looks it up along the user's normal nodes; the object's own along the
    # surface's normal (flat) where all its view-dependent faces are bumped, else along the view,
    # on the glossy faces' disc.
    bumped = [any(r is not None and getattr(r, "normals", None) is not None for r in radiances) for _, radiances in faces]
    glossy = [any(r is not None and r.kind != "diffuse" for r in radiances) for _, radiances in faces]
    all_bumped = any(bumped) and bumped == glossy
    radius, bumped_radius = _disc_radius(obj, faces), _disc_radius(obj, faces, bumped=True)
    if all_bumped:
        radius = bumped_radius
    shown_bumped = [b and (all_bumped or (i < len(face_slots) and face_slots[i] in bumps)) for i, b in enumerate(bumped)]
    if any(b and not shown for b, shown in zip(bumped, shown_bumped)):
        warnings.append(f"object '{obj.name}': its bumped faces show their radiance along the view where their "
                        "material's own normal nodes cannot be shown (give bumped and glossy faces separate objects)")
    face_radii = [bumped_radius if shown else radius for shown in shown_bumped]
    smooth = {i for i, slot in enumerate(face_slots) if slot in sources}
    # Textured glossy colours and bases under a layered coat: this atlas holds their radiance at
    # f0 (the base colour) = 0, a second one at 1 (black elsewhere), which their material blends
    # by the user's colour nodes (the radiance is affine in either).
    tinted = {i for i in smooth if sources[face_slots[i]][0] in BLENDED}
    atlas = atlas_pixels(layout, faces, samples, face_radii, sides, smooth)
    check_cancelled()
    images = (_radiance_image(name, atlas), _radiance_image(f"{name} tangent", tangent),
              _radiance_image(f"{name} normal", normal))
    white = None
    if tinted:
        only = [(kind, radiances if i in tinted else [None]) for i, (kind, radiances) in enumerate(faces)]
        white = _radiance_image(f"{name} f0 1", atlas_pixels(layout, only, samples, face_radii, sides, tinted, 1.0))
    elif bpy.data.images.get(f"{name} f0 1") is not None:  # an earlier bake's
        bpy.data.images.remove(bpy.data.images[f"{name} f0 1"])

    def made(material_name, with_detail=None, slot=None):
        tint = white if with_detail is not None and with_detail[1][0] in BLENDED else None
        bump = bumps.get(slot) if slot is not None else None
        return view_radiance.material(material_name, layout.uv_map, *images, spatial_size=(w, h),
                                      disc_radius=bumped_radius if bump is not None else radius,
                                      angular_samples=samples, sides=sides,
                                      detail=with_detail and (with_detail[0], with_detail[1][1]), tint=tint,
                                      bumped=bump if bump is not None else "flat" if all_bumped else None)

    material = made(name)
    slots = user_slots(obj)
    if sources or bumps:
        material[PROP_SLOT_MATERIALS] = [
            made(f"{name} slot {k}", (slots[k], sources[k]) if k in sources else None, k).name
            if k in sources or k in bumps else "" for k in range(len(slots))]
    elif PROP_SLOT_MATERIALS in material:
        del material[PROP_SLOT_MATERIALS]
    return material, warnings


def _detail_slots(obj, faces):
    """({slot: ("albedo", "coat" or "specular", colour source)}, slot per face, {slot: (material,
    shader)}) for the slots of a mesh whose material's colour nodes the bake can show
    (textures.colour_source, tint_source) and whose faces all carry that texture (and, for an
    albedo, no emission texture), and for those whose faces are all bumped and whose shader's
    Normal nodes the bake can show (textures.normal_source); ({}, [], {}) otherwise."""
    if not faces or obj.type not in {"MESH", "SURFACE"} or (obj.type == "SURFACE" and len(faces) != 1):
        return {}, [], {}
    slots = user_slots(obj)
    if obj.type == "SURFACE":  # one spline, shown through its mesh's UVMap like the user's nodes
        indices = [user_spline_material_index(obj, list(obj.data.splines).index(geometry.baked_splines(obj)[0]))]
    else:
        indices = [p.material_index for p in obj.data.polygons][:1 if faces[0][0] == "chart" else None]
    face_slots = [min(i, len(slots) - 1) for i in indices]
    if len(face_slots) != len(faces):
        return {}, [], {}
    sources, bumps = {}, {}
    folded = solved_diffuse(obj)
    for k, material in enumerate(slots):
        mine = [r for (_, radiances), slot in zip(faces, face_slots) if slot == k for r in radiances]
        source = textures.colour_source(material, folded)
        if source is not None and mine and all(r is not None and r.albedo is not None and r.emission is None
                                               for r in mine):
            coats = {getattr(r, "coat_share", None) is not None for r in mine}
            if len(coats) == 1:
                sources[k] = ("coat" if coats.pop() else "albedo", source)
        source = textures.tint_source(material)
        if source is not None and mine and all(r is not None and r.specular is not None for r in mine):
            sources[k] = ("specular", source)
        shader = textures.normal_source(material)
        if shader is not None and mine and all(r is not None and getattr(r, "normals", None) is not None for r in mine):
            bumps[k] = (material, shader)
    return sources, face_slots, bumps


def bake_object(obj, faces, chart_uvs=None) -> list:
    """Bake one object: faces is, per polygon (per spline for a NURBS surface, one entry for a
    UV chart), (kind, its SurfaceRadiance list) as face_splines gives; chart_uvs are a chart's
    UVs per loop (None: the UV map of an earlier bake). The radiance is also stored on the
    object, so the bake can be redone without a solve. Returns warnings about what the bake
    approximates."""
    check_cancelled()
    if obj.type == "SURFACE":
        return _bake_nurbs(obj, faces)
    if faces and faces[0][0] == "chart":
        return _bake_chart(obj, faces, chart_uvs)
    material, warnings = _bake_layout(obj, f"BSGI {obj.name}", _mesh_layout(obj, faces), faces,
                                      _detail_slots(obj, faces))
    _link_baked_material(obj, material)
    _store_splines(obj, faces)
    return warnings


def _bake_nurbs(obj, faces) -> list:
    """A SURFACE object of one spline: its images laid out in parameter space, shown through the
    UV map Blender gives the surface's mesh."""
    if len(faces) != 1:
        return _bake_nurbs_splines(obj, faces)
    spline = geometry.baked_splines(obj)[0]
    material, warnings = _bake_layout(obj, f"BSGI {obj.name}", _nurbs_layout(obj, spline, faces[0][1][0]), faces,
                                      _detail_slots(obj, faces))
    _link_baked_material(obj, material)
    _store_splines(obj, faces)
    return warnings


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
        name, uvs = charts.suitable_uv_map(mesh, charts.loop_triangles(mesh)[1])
        if name is None:
            raise ValueError(f"object '{obj.name}': its chart's UV map '{UV_NAME}' is gone and none of its own UV "
                             "maps is a chart; solve again")
        return _bake_chart(obj, faces, uvs)
    material, warnings = _bake_layout(obj, f"BSGI {obj.name}", _chart_layout(obj, faces[0][1][0]), faces,
                                      _detail_slots(obj, faces))
    _link_baked_material(obj, material)
    _store_splines(obj, faces)
    return warnings


def _bake_nurbs_splines(obj, faces) -> list:
    """A SURFACE object of several splines. Blender gives every spline's mesh the whole UV square
    (UVMap = that spline's normalized parameters), so the splines' images cannot share one UV
    map; the one per-face choice a material sees is the material slot. Each spline gets its own
    image and material, in a slot of its own: while the bake is shown, spline k uses slot k (slots
    are added if there are fewer than splines). The user's material indices are recorded and put
    back when the originals are shown or the bake is cleared."""
    splines = geometry.baked_splines(obj)
    if len(splines) != len(faces):
        raise ValueError(f"object '{obj.name}': it has {len(splines)} drawable splines, the solution {len(faces)}")
    names, warnings = [], []
    for k, face in enumerate(faces):
        layout = _nurbs_layout(obj, splines[k], face[1][0])
        material, spline_warnings = _bake_layout(obj, f"BSGI {obj.name} spline {k}", layout, [face])
        names.append(material.name)
        warnings += spline_warnings
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
    return warnings




def _show_spline_materials(obj, baked: bool) -> None:
    """Spline k on slot k with its own baked material, or the user's material indices back."""
    names = obj.get(PROP_SPLINE_MATERIALS)
    if names is None:
        return
    drawn = geometry.baked_splines(obj)
    for k, spline in enumerate(obj.data.splines):
        spline.material_index = (drawn.index(spline) if baked and spline in drawn
                                 else user_spline_material_index(obj, k))
    if baked:
        for k, slot in enumerate(obj.material_slots):
            slot.material = bpy.data.materials.get(names[min(k, len(names) - 1)])


def _store_splines(obj, faces) -> None:
    # ID properties from float64 arrays: exact, and saved in the .blend.
    group = {"kinds": ",".join(kind for kind, _ in faces)}
    for i, (_, radiances) in enumerate(faces):
        for k, r in enumerate(radiances):
            group[f"{i}.{k}"] = _radiance_entry(r)
    obj[PROP_RADIANCE] = group


def _radiance_entry(r) -> dict:
    if r is None:
        return {"kind": "emitter"}
    entry = {"kind": r.kind, "disc_radius": r.disc_radius}
    if isinstance(r, SplitRadiance):  # solved in pieces (bsgi.split): each piece's entry and its band
        entry["split"] = {str(k): {"piece": _radiance_entry(piece), "range": np.array([b.t0, b.t1]),
                                   "lower": np.asarray(b.lower, np.float64), "upper": np.asarray(b.upper, np.float64),
                                   "along_v": int(b.along_v)}
                          for k, (b, piece) in enumerate(zip(r.bands, r.pieces))}
        return entry
    for side in SIDES:
        spline = getattr(r, side)
        if spline is not None:
            arrays = bsgi.spline_to_arrays(spline)
            arrays["degrees"] = arrays["degrees"].astype(np.int32)  # ID property ints are 32-bit
            entry[side] = arrays
    for texture in TEXTURES:
        image = getattr(r, texture)
        if image is not None:  # float32 texels, flat, with their shape
            entry[texture] = {"texels": image.astype(np.float64).ravel(), "shape": np.array(image.shape, np.int32)}
    for name in COAT:
        if getattr(r, name) is not None:
            entry[name] = np.asarray(getattr(r, name), np.float64)
    return entry


def stored_faces(obj) -> list:
    """The faces' radiance stored by the last bake, as bake_object takes it."""
    group = obj.get(PROP_RADIANCE)
    if group is None:
        raise ValueError(f"object '{obj.name}': no stored radiance; solve first")
    faces = []
    for i, kind in enumerate(group["kinds"].split(",")):
        radiances, k = [], 0
        while f"{i}.{k}" in group:
            radiances.append(_stored_radiance(group[f"{i}.{k}"]))
            k += 1
        faces.append((kind, radiances))
    return faces


def _stored_radiance(entry):
    if "kind" not in entry:
        # Stored by the add-on before view-dependent baking: the upper spline alone, its angular
        # knots on [-R, R] (24).
        upper = _spline(entry)
        kind = "glossy" if upper.dims == 4 else "diffuse"
        return bsgi.SurfaceRadiance(kind, upper.axes[2].knots[-1] if upper.dims == 4 else 1.0, upper)
    if entry["kind"] == "emitter":
        return None
    if "split" in entry:
        parts = [entry["split"][str(k)] for k in range(len(entry["split"]))]
        floats = lambda value: np.frombuffer(memoryview(value), np.float64).copy()  # noqa: E731
        bands = [Band(*floats(p["range"]), floats(p["lower"]), floats(p["upper"]), bool(p["along_v"])) for p in parts]
        return SplitRadiance(bands, [_stored_radiance(p["piece"]) for p in parts])
    textures = {t: np.frombuffer(memoryview(entry[t]["texels"]), np.float64).reshape(
                    tuple(np.frombuffer(memoryview(entry[t]["shape"]), np.int32)))
                for t in TEXTURES if t in entry}
    coat = {name: np.frombuffer(memoryview(entry[name]), np.float64).copy() for name in COAT if name in entry}
    return bsgi.SurfaceRadiance(entry["kind"], entry["disc_radius"],
                                **{side: _spline(entry[side]) if side in entry else None for side in SIDES},
                                **textures, **coat)


def _spline(stored):
    arrays = {name: np.frombuffer(memoryview(value), _dtype(value)) if hasattr(value, "typecode") else value
              for name, value in stored.items()}
    return bsgi.spline_from_arrays(_shaped(arrays))


def _dtype(value):
    return np.float64 if memoryview(value).format == "d" else np.int32


def _shaped(arrays):
    """ID property arrays are flat: give the coefficients back their (n_0, ..., channels) shape."""
    degrees = arrays["degrees"].astype(int)
    shape = [len(arrays[f"knots{k}"]) - d - 1 for k, d in enumerate(degrees)]
    arrays["coefficients"] = arrays["coefficients"].reshape(*shape, -1)
    return arrays


def rebake(obj) -> list:
    """Regenerate an object's images from its stored radiance (no solve)."""
    return bake_object(obj, stored_faces(obj))


def _radiance_image(name: str, pixels: np.ndarray):
    height, width = pixels.shape[:2]
    image = bpy.data.images.get(name)
    if image is not None and (image.size[0] != width or image.size[1] != height):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=False, float_buffer=True)
    # Radiance and frames are scene-linear data: the colour space is set before the pixels,
    # since changing it afterwards discards them.
    image.colorspace_settings.name = "Non-Color"
    image[PROP_BAKED_IMAGE] = True
    try:
        image.pixels.foreach_set(pixels.ravel())
        pack(image)
    except (RuntimeError, MemoryError) as error:  # the transaction removes the image
        raise RuntimeError(f"the bake cannot write or pack its image '{name}' ({width} x {height}): {error}") from None
    return image


def pack(image) -> None:
    """Packs the image's pixels into the .blend (the bake's images have no file)."""
    image.pack()


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
    slot_materials = list(material.get(PROP_SLOT_MATERIALS, []))
    if slot_materials:
        obj[PROP_SLOT_MATERIALS] = slot_materials
    elif PROP_SLOT_MATERIALS in obj:
        del obj[PROP_SLOT_MATERIALS]
    show_baked(obj, True)






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
    if baked:
        for slot, name in zip(obj.material_slots, obj.get(PROP_SLOT_MATERIALS, [])):
            if name:
                slot.material = bpy.data.materials.get(name)
    _show_spline_materials(obj, baked)


def clear_bake(obj) -> None:
    """Remove the bake from an object: its slots, UV maps and materials as before the bake."""
    if not is_baked(obj):
        return
    error_view.show_error(obj, False)
    if error_view.PROP_ERROR in obj:
        del obj[error_view.PROP_ERROR]
    show_baked(obj, False)
    if obj.get(PROP_ADDED_SLOT):
        for _ in range(int(obj[PROP_ADDED_SLOT])):
            obj.data.materials.pop()
        del obj[PROP_ADDED_SLOT]
    names = [obj[PROP_MATERIAL], *obj.get(PROP_SPLINE_MATERIALS, []), *filter(None, obj.get(PROP_SLOT_MATERIALS, []))]
    for prop in (PROP_SLOTS, PROP_MATERIAL, PROP_SPLINE_MATERIALS, PROP_SPLINE_INDICES, PROP_SLOT_MATERIALS):
        if prop in obj:
            del obj[prop]
    if PROP_RADIANCE in obj:
        del obj[PROP_RADIANCE]
    uv = obj.data.uv_layers.get(UV_NAME) if obj.type == "MESH" else None
    if uv is not None:
        obj.data.uv_layers.remove(uv)
    images = set()
    for name in dict.fromkeys(names):
        material = bpy.data.materials.get(name)
        if material is not None:
            images |= {n.image.name for n in material.node_tree.nodes if n.type == "TEX_IMAGE" and n.image}
            bpy.data.materials.remove(material)
    for name in images:  # the bake's own (a textured slot's material also shows the user's images)
        image = bpy.data.images.get(name)
        if image is not None and (image.get(PROP_BAKED_IMAGE) or name.startswith("BSGI ")):
            bpy.data.images.remove(image)


# The progress whose cancel() stops the bake under way (transaction), checked between objects,
# faces and images.
_progress = None


def check_cancelled() -> None:
    if _progress is not None and _progress.cancelled:
        raise bsgi.SolveCancelled("bake cancelled")


@dataclass
class _Transaction:
    """What a bake changes, to undo it: the data-blocks there were before, and per object it
    touches the bake it had (its stored radiance and its chart's UVs), or None."""

    before: dict
    show_baked: bool
    touched: dict = field(default_factory=dict)  # object name -> (faces, chart uvs) of its earlier bake, or None

    def touch(self, obj) -> None:
        if obj.name in self.touched:
            return
        earlier = None
        if is_baked(obj) and PROP_RADIANCE in obj:
            uv = obj.data.uv_layers.get(UV_NAME) if obj.type == "MESH" else None
            uvs = None
            if uv is not None:
                uvs = np.empty(len(uv.data) * 2, np.float32)
                uv.data.foreach_get("uv", uvs)
            earlier = (stored_faces(obj), None if uvs is None else uvs.reshape(-1, 2))
        self.touched[obj.name] = earlier

    def undo(self) -> None:
        """Each touched object back to its earlier bake (or none), and the data-blocks the bake
        made removed."""
        global _progress
        _progress = None  # the undo itself is not cancelled
        for name, earlier in self.touched.items():
            obj = bpy.data.objects.get(name)
            if obj is None:
                continue
            if earlier is None:
                clear_bake(obj)
                # A bake stopped before it linked its material: what it wrote before that.
                uv = obj.data.uv_layers.get(UV_NAME) if obj.type == "MESH" else None
                if uv is not None:
                    obj.data.uv_layers.remove(uv)
                for prop in (PROP_RADIANCE, PROP_SPLINE_INDICES, PROP_ADDED_SLOT):
                    if prop in obj:
                        del obj[prop]
                if not obj.keys():  # the bake's properties leave an empty group behind
                    obj.id_properties_clear()
                continue
            faces, uvs = earlier
            bake_object(obj, faces, uvs if faces and faces[0][0] == "chart" else None)
            show_baked(obj, self.show_baked)
        for kind, names in self.before.items():
            collection = getattr(bpy.data, kind)
            for block in [b for b in collection if b.name not in names]:
                collection.remove(block)


_BAKED_KINDS = ("images", "materials", "node_groups")


@contextmanager
def transaction(progress=None):
    """Bakes in the block are undone if it raises (a cancel through progress.cancel() raises
    bsgi.SolveCancelled at the next object, face or image): the scene is then as it was. Call
    touch(obj) on the transaction before baking obj."""
    global _progress
    before = {kind: {b.name for b in getattr(bpy.data, kind)} for kind in _BAKED_KINDS}
    scene = bpy.context.scene
    record = _Transaction(before, bool(getattr(getattr(scene, "bsgi", None), "show_baked", False)))
    _progress = progress
    try:
        yield record
    except BaseException:
        record.undo()
        raise
    finally:
        _progress = None
