"""Blender data at its worst (issue 17, item 2): each case is solved, or refused with a message
naming the object and the problem; a refused solve leaves the saved .blend as it was.

The scene of each is a grey floor (albedo 0.5) under a square lamp (scenes.floor_under_lamp);
what a case adds must not change the floor's light where Cycles would not, and where a case
changes the floor's own material, the floor's light follows Cycles' reading of it."""
import bpy
import numpy as np
import pytest

import blend_file
import scenes

# The floor's irradiance / pi at its centre times its albedo: read off a solve of the plain scene,
# every case's reference (what a case must or must not change).
FLOOR_CENTRE = np.array([[0.5, 0.5]])


@pytest.fixture
def floor(context):
    floor = scenes.floor_under_lamp()
    # A viewport colour unlike the node tree's, so a fallback to it shows.
    bpy.data.materials["Grey"].diffuse_color = (0.05, 0.05, 0.05, 1)
    context.scene.bsgi.preset = "DRAFT"
    return floor


def saved(tmp_path) -> bytes:
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=False, copy=True)
    return path.read_bytes()


def solve(tmp_path):
    """bpy.ops.bsgi.solve() as a script runs it: None when it solved, else the refusal's message
    (after checking that the refusal left the .blend unchanged)."""
    before = saved(tmp_path)
    try:
        bpy.ops.bsgi.solve()
    except RuntimeError as error:
        assert not blend_file.differences(before, saved(tmp_path)), "a refused solve changed the .blend"
        return str(error)
    return None


def floor_light(name="Floor") -> np.ndarray:
    """The radiance baked on the floor at its centre (RGB); a textured floor's albedo texel times
    its smooth irradiance factor."""
    from bsgi_addon import bake

    radiance = bake.stored_faces(bpy.data.objects[name])[0][1][0]
    light = radiance.upper.evaluate(FLOOR_CENTRE)[0]
    return light if radiance.albedo is None else light * bake.texture_at(radiance.albedo, FLOOR_CENTRE)[0]


def plain_floor_light(tmp_path) -> np.ndarray:
    assert solve(tmp_path) is None
    return floor_light()


def add_mesh(name, vertices, edges=(), faces=(), material=None):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in vertices], list(edges), list(faces))
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def small_box(name="Box", scale=(1, 1, 1)):
    cube = [(0.1 * x + 0.6, 0.1 * y + 0.6, 0.1 * z + 0.1) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    obj = add_mesh(name, cube, faces=faces, material=bpy.data.materials["Grey"])
    obj.scale = scale
    return obj


@pytest.fixture
def reference(floor, tmp_path):
    """The plain scene's floor light, then a fresh copy of the plain scene for the case."""
    light = plain_floor_light(tmp_path)
    bpy.ops.bsgi.clear()
    return light


def test_empty_mesh_loose_edges_and_vertices_are_solved_around(floor, reference, tmp_path):
    add_mesh("Nothing", [])
    add_mesh("Wire", [(0, 0, 0.5), (0.3, 0, 0.5), (0.3, 0.3, 0.5)], edges=[(0, 1), (1, 2)])
    add_mesh("Points", [(0.1, 0.1, 0.2), (0.2, 0.1, 0.2)])
    assert solve(tmp_path) is None
    np.testing.assert_allclose(floor_light(), reference, rtol=1e-9)  # no faces, nothing cast or reflected


@pytest.mark.parametrize("scale", [(0, 0, 0), (1, 1, 0)])
def test_zero_scale_is_refused_by_name(floor, tmp_path, scale):
    small_box(scale=scale)
    message = solve(tmp_path)
    assert message is not None and "'Box: face" in message and "zero area" in message


@pytest.mark.parametrize("scale", [(-1, 1, 1), (1, 1, -1), (-1, -1, -1)])
def test_negative_scale_floor_is_lit_as_the_unmirrored_one(floor, reference, tmp_path, scale):
    """Cycles shades both sides of a diffuse surface; a mirrored floor (its faces turned over)
    gets the same light on one side or the other."""
    floor.scale = scale
    assert solve(tmp_path) is None
    from bsgi_addon import bake

    radiance = bake.stored_faces(floor)[0][1][0]
    sides = [s.evaluate(FLOOR_CENTRE)[0] for s in (radiance.upper, radiance.lower) if s is not None]
    assert any(np.allclose(side, reference, rtol=1e-6) for side in sides), (sides, reference)


def test_non_manifold_and_self_intersecting_meshes_are_solved(floor, reference, tmp_path):
    # Four triangles on one edge (non-manifold), a bow-tie quad, a quad with two equal corners.
    grey = bpy.data.materials["Grey"]
    add_mesh("Fan", [(0.6, 0.6, 0.3), (0.8, 0.6, 0.3), (0.6, 0.8, 0.3), (0.4, 0.6, 0.3), (0.6, 0.6, 0.5)],
             faces=[(0, 1, 2), (0, 2, 3), (0, 1, 4), (0, 2, 4)], material=grey)
    add_mesh("Bowtie", [(-0.8, -0.8, 0.3), (-0.6, -0.6, 0.3), (-0.6, -0.8, 0.3), (-0.8, -0.6, 0.3)],
             faces=[(0, 1, 2, 3)], material=grey)
    add_mesh("Pinched", [(-0.8, 0.6, 0.3), (-0.8, 0.6, 0.3), (-0.6, 0.6, 0.3), (-0.6, 0.8, 0.3)],
             faces=[(0, 1, 2, 3)], material=grey)
    assert solve(tmp_path) is None
    light = floor_light()
    # Small occluders away from the centre: the centre's light changes by their shadow and
    # reflection, a few per cent at most.
    assert np.all(np.isfinite(light)) and np.all(np.abs(light / reference - 1) < 0.05)


def nurbs_patch(flags: dict, order=(3, 3)):
    bpy.ops.surface.primitive_nurbs_surface_surface_add(radius=0.2, location=(0.6, 0.6, 0.4))
    obj = bpy.context.object
    obj.name = "Patch"
    spline = obj.data.splines[0]
    for key, value in flags.items():
        setattr(spline, key, value)
    spline.order_u, spline.order_v = order
    return obj


FLAG_SETS = [dict(use_endpoint_u=e, use_endpoint_v=e, use_bezier_u=b, use_bezier_v=b, use_cyclic_u=c, use_cyclic_v=cv)
             for e in (False, True) for b in (False, True) for c in (False, True) for cv in (False, True)]


@pytest.mark.parametrize("flags", FLAG_SETS, ids=lambda f: "".join(k[4] + k[-1] + str(int(v)) for k, v in f.items()))
def test_nurbs_every_flag_combination_is_solved(floor, tmp_path, flags):
    nurbs_patch(flags)
    message = solve(tmp_path)
    assert message is None, message
    assert np.all(np.isfinite(floor_light()))


@pytest.mark.parametrize("order", [(6, 6), (2, 6), (1, 1)])
def test_nurbs_order_above_its_points_is_solved(floor, tmp_path, order):
    nurbs_patch({}, order)  # Blender clamps the order to the points
    assert solve(tmp_path) is None


@pytest.mark.parametrize("points", [(1, 1), (2, 1), (4, 1)])
def test_nurbs_with_too_few_points_is_skipped_by_name(floor, reference, tmp_path, capfd, points):
    nu, nv = points
    curve = bpy.data.curves.new("Few", "SURFACE")
    spline = curve.splines.new("NURBS")
    spline.points.add(nu * nv - 1)
    for k, point in enumerate(spline.points):
        point.co = ((k % nu) * 0.2, (k // nu) * 0.2, 0.3, 1)
    obj = bpy.data.objects.new("Few", curve)
    bpy.context.scene.collection.objects.link(obj)
    assert solve(tmp_path) is None
    assert "object 'Few': spline 0 is skipped, Blender draws nothing for it" in "".join(capfd.readouterr())
    np.testing.assert_allclose(floor_light(), reference, rtol=1e-9)


def grey_output():
    tree = bpy.data.materials["Grey"].node_tree
    output = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    return tree, output, output.inputs["Surface"].links[0].from_node


def test_reroutes_are_followed(floor, reference, tmp_path):
    tree, output, bsdf = grey_output()
    socket = bsdf.outputs[0]
    for _ in range(30):
        reroute = tree.nodes.new("NodeReroute")
        tree.links.new(socket, reroute.inputs[0])
        socket = reroute.outputs[0]
    tree.links.new(socket, output.inputs["Surface"])
    assert solve(tmp_path) is None
    np.testing.assert_allclose(floor_light(), reference, rtol=1e-9)


def test_muted_mix_shader_passes_its_first_shader(floor, reference, tmp_path):
    """Cycles: a muted node passes its first matching input through (its internal links)."""
    tree, output, bsdf = grey_output()
    mix, glow = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeEmission")
    glow.inputs["Strength"].default_value = 50
    mix.inputs["Fac"].default_value = 1.0
    tree.links.new(bsdf.outputs[0], mix.inputs[1])
    tree.links.new(glow.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], output.inputs["Surface"])
    mix.mute = True
    assert solve(tmp_path) is None
    np.testing.assert_allclose(floor_light(), reference, rtol=1e-9)


@pytest.mark.parametrize("what", ["node", "link"])
def test_muted_bsdf_or_link_leaves_the_surface_black(floor, tmp_path, what):
    """A muted BSDF has no shader input to pass, a muted link carries nothing: Cycles renders
    no closure there, black."""
    tree, output, bsdf = grey_output()
    if what == "node":
        bsdf.mute = True
    else:
        output.inputs["Surface"].links[0].is_muted = True
    assert solve(tmp_path) is None
    np.testing.assert_array_equal(floor_light(), 0)


@pytest.mark.parametrize("depth", [1, 24])
def test_nested_node_groups_are_entered(floor, reference, tmp_path, depth):
    """The floor's Diffuse BSDF inside `depth` nested groups: the same floor."""
    tree, output, _ = grey_output()
    group = bpy.data.node_groups.new("Level 0", "ShaderNodeTree")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    diffuse = group.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1)
    group.links.new(diffuse.outputs[0], group.nodes.new("NodeGroupOutput").inputs[0])
    for level in range(1, depth):
        outer = bpy.data.node_groups.new(f"Level {level}", "ShaderNodeTree")
        outer.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
        node = outer.nodes.new("ShaderNodeGroup")
        node.node_tree = group
        outer.links.new(node.outputs[0], outer.nodes.new("NodeGroupOutput").inputs[0])
        group = outer
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    tree.links.new(node.outputs[0], output.inputs["Surface"])
    assert solve(tmp_path) is None
    np.testing.assert_allclose(floor_light(), reference, rtol=1e-9)


def test_a_cycle_of_shader_nodes_is_solved_without_it(floor, reference, tmp_path):
    """Two Add Shaders feeding each other: Blender marks the closing link invalid and Cycles
    drops it, leaving the floor's BSDF."""
    tree, output, bsdf = grey_output()
    first, second = tree.nodes.new("ShaderNodeAddShader"), tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(bsdf.outputs[0], first.inputs[0])
    tree.links.new(second.outputs[0], first.inputs[1])
    tree.links.new(first.outputs[0], second.inputs[0])
    tree.links.new(first.outputs[0], output.inputs["Surface"])
    assert not all(link.is_valid for link in tree.links)
    assert solve(tmp_path) is None
    np.testing.assert_allclose(floor_light(), reference, rtol=1e-9)


def test_missing_image_is_solved_magenta_and_named(floor, tmp_path, capfd):
    """Cycles renders an image it cannot read magenta (1, 0, 1); so does the texture bake."""
    tree, _, bsdf = grey_output()
    image = bpy.data.images.new("Missing", 4, 4)
    image.source = "FILE"
    image.filepath = str(tmp_path / "no such texture.png")
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    tree.links.new(texture.outputs["Color"], bsdf.inputs["Color"])
    assert solve(tmp_path) is None
    from bsgi_addon import bake

    radiance = bake.stored_faces(floor)[0][1][0]
    np.testing.assert_allclose(radiance.albedo.reshape(-1, 3).mean(axis=0), [1, 0, 1], atol=1e-6)
    assert "material 'Grey' (on 'Floor'): image 'Missing' cannot be read" in "".join(capfd.readouterr())


def test_ten_thousand_material_slots(floor, reference, tmp_path):
    """10,000 slots, the floor's face on the last-but-one: an empty slot (Blender's default
    material, albedo 0.8 in the solve)."""
    grey = bpy.data.materials["Grey"]
    for k in range(9999):
        floor.data.materials.append(None if k % 2 else grey)
    floor.data.polygons[0].material_index = 9998
    assert len(floor.material_slots) == 10000
    assert solve(tmp_path) is None
    np.testing.assert_allclose(floor_light(), reference * 0.8 / 0.5, rtol=1e-9)


def test_linked_library_object_is_solved_not_baked(floor, tmp_path, capfd):
    library = tmp_path / "library.blend"
    mesh = bpy.data.meshes.new("Shelf")
    mesh.from_pydata([(0.5, 0.5, 0.2), (0.8, 0.5, 0.2), (0.8, 0.8, 0.2), (0.5, 0.8, 0.2)], [], [(0, 1, 2, 3)])
    shelf = bpy.data.objects.new("Shelf", mesh)
    bpy.data.libraries.write(str(library), {shelf}, fake_user=True)
    bpy.data.objects.remove(shelf)
    bpy.data.meshes.remove(mesh)
    with bpy.data.libraries.load(str(library), link=True) as (source, target):
        target.objects = ["Shelf"]
    bpy.context.scene.collection.objects.link(target.objects[0])
    assert solve(tmp_path) is None
    out = "".join(capfd.readouterr())
    assert "object 'Shelf': solved (it casts shadows and reflects light) but not baked: it is linked from the " \
           "library" in out
    assert "bsgi_radiance" in bpy.data.objects["Floor"] and "bsgi_radiance" not in bpy.data.objects["Shelf"]
