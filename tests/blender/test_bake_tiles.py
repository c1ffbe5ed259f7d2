"""The bake's atlas grows with the solved coefficients (issue #16, item 2): each face's tile is
sized by its own spline and the tiles are shelf-packed, instead of a square grid of tiles all
the size of the object's largest face. Checked against the old layout's size (computed here from
its formula), the tiles' total area, and the solved splines at each face's texel centres."""
import math

import bpy
import numpy as np

import scenes
from bsgi_addon import bake, pipeline

GREY = (0.5, 0.5, 0.5)


def add_mesh(name, quads, material):
    """One mesh object of the given quads (4 corners each)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(c) for q in quads for c in q], [], [tuple(range(4 * k, 4 * k + 4)) for k in range(len(quads))])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def box_quads(centre, size):
    """The six faces of an axis-aligned box, outward normals (counter-clockwise seen from outside)."""
    c, h = np.asarray(centre, float), np.asarray(size, float) / 2
    corner = lambda sx, sy, sz: tuple(c + h * (sx, sy, sz))  # noqa: E731
    return [[corner(-1, -1, -1), corner(-1, 1, -1), corner(1, 1, -1), corner(1, -1, -1)],  # bottom
            [corner(-1, -1, 1), corner(1, -1, 1), corner(1, 1, 1), corner(-1, 1, 1)],  # top
            [corner(-1, -1, -1), corner(1, -1, -1), corner(1, -1, 1), corner(-1, -1, 1)],  # front
            [corner(1, 1, -1), corner(-1, 1, -1), corner(-1, 1, 1), corner(1, 1, 1)],  # back
            [corner(-1, 1, -1), corner(-1, -1, -1), corner(-1, -1, 1), corner(-1, 1, 1)],  # left
            [corner(1, -1, -1), corner(1, 1, -1), corner(1, 1, 1), corner(1, -1, 1)]]  # right


def side(radiance):
    """A face's tile side by the rule the bake documents: two texels per coefficient, at least 8."""
    return max(8, 2 * max(axis.num_coeffs for axis in radiance.upper.axes[:2]))


def old_size(sides):
    """The atlas side before this change: a square grid of ceil(sqrt(faces)) tiles a side, each
    tile the largest face's."""
    return math.ceil(math.sqrt(len(sides))) * max(sides)


def solve(context, coeffs_from_size, preset="CUSTOM"):
    """Solve and bake: CUSTOM at 16 coefficients and one bounce, or a preset."""
    s = context.scene.bsgi
    s.preset = preset
    s.spatial_coeffs = 16
    s.max_bounces = 1
    job = pipeline.prepare(context)
    job.settings.coeffs_from_size = coeffs_from_size
    solution = pipeline.run(job)
    pipeline.finish(context, job, solution)
    return job, solution


def check_tiles(obj, job, solution):
    """Each face's loops in the UV map sit on the centres of its tile's corner texels, the tiles do
    not overlap, and the image holds the face's solved spline at every texel of its tile. Returns
    the tiles' sides and the image's (width, height)."""
    exported = next(e for e in job.export.objects if e.name == obj.name)
    image = bpy.data.images[f"BSGI {obj.name}"]
    w, h = image.size
    pixels = np.array(image.pixels[:], np.float32).reshape(h, w, 4)[..., :3]
    uvs = np.empty(2 * len(obj.data.loops))
    obj.data.uv_layers[bake.UV_NAME].data.foreach_get("uv", uvs)
    uvs = uvs.reshape(-1, 2)
    owner = np.full((h, w), -1)
    sides = []
    for poly, (kind, first, _) in zip(obj.data.polygons, exported.patches):
        assert kind == "quad"
        radiance = solution.surfaces[first]
        t = side(radiance)
        sides.append(t)
        corners = uvs[list(poly.loop_indices)] * (w, h) - 0.5  # texel indices of the face's corners
        np.testing.assert_allclose(corners - corners[0], [(0, 0), (t - 1, 0), (t - 1, t - 1), (0, t - 1)], atol=1e-3)
        x, y = np.rint(corners[0]).astype(int)
        assert x >= 0 and y >= 0 and x + t <= w and y + t <= h
        assert (owner[y:y + t, x:x + t] == -1).all(), "tiles overlap"
        owner[y:y + t, x:x + t] = poly.index
        g = np.arange(t) / (t - 1)
        u, v = np.meshgrid(g, g)  # image rows are v, columns u
        solved = solution.radiance[first].evaluate(np.stack([u.ravel(), v.ravel()], 1)).reshape(t, t, 3)
        np.testing.assert_allclose(pixels[y:y + t, x:x + t], solved, rtol=1e-5, atol=1e-7)
    return sides, (w, h)


def report(label, sides, size):
    before = old_size(sides)
    print(f"\n{label}: {len(sides)} faces, tiles {sorted(sides, reverse=True)}: atlas {before} x {before} "
          f"({before * before * 16 / 1024:.0f} KiB float RGBA) -> {size[0]} x {size[1]} "
          f"({size[0] * size[1] * 16 / 1024:.0f} KiB)")


def test_tiles_follow_each_faces_coefficients(context):
    """A room's floor and a box standing on it in one mesh, solved with coeffs_from_size: the
    floor's tile is large, the box's faces' small; the atlas is close to their total area."""
    grey = scenes.diffuse_material("Grey", GREY)
    floor = [[(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)]]
    room = add_mesh("Room", floor + box_quads((0.5, 0.3, 0.25), (0.5, 0.4, 0.5)), grey)
    scenes.add_area_light(location=(0, 0, 2), energy=200.0)
    job, solution = solve(context, coeffs_from_size=True)
    sides, (w, h) = check_tiles(room, job, solution)
    assert len(set(sides)) > 1 and sides[0] == max(sides) > 2 * min(sides), sides
    area = sum(t * t for t in sides)
    assert area <= w * h <= 1.3 * area, (w, h, area)
    assert w * h < 0.3 * old_size(sides) ** 2
    assert max(w, h) <= 2 * min(w, h)
    report("floor + box in one mesh (coeffs_from_size)", sides, (w, h))


def test_furnished_box_and_cube_atlas_sizes(context):
    """At the preview preset (whose final gather doubles the coefficients): a box of a furnished
    room (its own object, beside a floor, coeffs_from_size) and a cube of six equal faces
    (uniform coefficients). The atlas packs the tiles, and the image still holds the splines."""
    grey = scenes.diffuse_material("Grey", GREY)
    add_mesh("Floor", [[(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)]], grey)
    box = add_mesh("Sideboard", box_quads((1.0, 0.5, 0.15), (1.2, 0.6, 0.3)), grey)
    scenes.add_area_light(location=(0, 0, 2.5), size=1.0, energy=300.0)
    job, solution = solve(context, coeffs_from_size=True, preset="PREVIEW")
    sides, size = check_tiles(box, job, solution)
    assert size[0] * size[1] <= 1.3 * sum(t * t for t in sides)
    report("furnished-interior-like box (coeffs_from_size)", sides, size)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    grey = scenes.diffuse_material("Grey", GREY)
    cube = add_mesh("Cube", box_quads((0, 0, 0.5), (1, 1, 1)), grey)
    add_mesh("Floor", [[(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)]], grey)
    scenes.add_area_light(location=(0, 0, 2.5), size=1.0, energy=300.0)
    job, solution = solve(bpy.context, coeffs_from_size=False, preset="PREVIEW")
    sides, size = check_tiles(cube, job, solution)
    t = sides[0]
    assert set(sides) == {t} and sorted(size) == [2 * t, 3 * t]  # 3 x 2 tiles, not a 3 x 3 grid
    report("6-face cube (uniform coefficients)", sides, size)
