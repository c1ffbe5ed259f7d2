"""Normal maps and bumps (addon/textures.py's normal pass, bsgi.Scene.set_normal_texture): a Diffuse or
Principled BSDF whose Normal input a Normal Map node drives is solved over its bumped normal, as
Cycles shades it (its bump shadowing term included), and its bake looks the radiance up along the
user's own normal nodes. Checked against the closed form of a tilted plane and Cycles' render."""
import math
import pathlib
import sys

import bpy
import numpy as np
import pytest

from bsgi_addon import pipeline
from test_pipeline import render_exr, render_floor_from_above
from test_textures import add_uv_quad, exported_object

# The example scenes' builders (scene_parts.wave_bump: the textured interior's bumped floor's nodes).
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "example_blends"))

ALBEDO, STRENGTH, COLOR, TILT = 0.6, 3.0, (1.0, 0.8, 0.6), 40.0


def cycles_shadowing(cos_n, cos_i):
    """Cycles' bump shadowing term (closure/bsdf.h) for a diffuse closure with Bump Map Correction."""
    alpha2 = min(max(0.125 * (1 / cos_n**2 - 1), 0.0), 1.0)
    lam = 0.5 * (math.sqrt(1 + alpha2 * (1 / cos_i**2 - 1)) - 1)
    return 1.0 if cos_n >= 1 or cos_i >= 1 else 1 / (1 + lam)


def bumped_material(name, colour_node, principled=False):
    """A diffuse material (a Diffuse BSDF, or a Principled BSDF without specular) whose Normal
    input a tangent-space Normal Map node drives from `colour_node(tree)`'s colour."""
    m = bpy.data.materials.new(name)
    tree = m.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    if principled:
        shader = tree.nodes.new("ShaderNodeBsdfPrincipled")
        shader.inputs["Base Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1)
        shader.inputs["Specular IOR Level"].default_value = 0.0
    else:
        shader = tree.nodes.new("ShaderNodeBsdfDiffuse")
        shader.inputs["Color"].default_value = (ALBEDO, ALBEDO, ALBEDO, 1)
    normal_map = tree.nodes.new("ShaderNodeNormalMap")
    normal_map.space, normal_map.uv_map = "TANGENT", "UVMap"
    tree.links.new(colour_node(tree).outputs["Color"], normal_map.inputs["Color"])
    tree.links.new(normal_map.outputs["Normal"], shader.inputs["Normal"])
    tree.links.new(shader.outputs[0], out.inputs["Surface"])
    return m


def constant(normal):
    def build(tree):
        node = tree.nodes.new("ShaderNodeRGB")
        node.outputs["Color"].default_value = (*((np.asarray(normal) + 1) / 2), 1)
        return node
    return build


def washboard_image(ridges=4, width=128, degrees=35.0):
    """A tangent-space normal map whose normals turn about the v axis, +-degrees, `ridges` times
    across u: (sin a(u), 0, cos a(u)) as (n + 1) / 2, a Non-Color float image."""
    image = bpy.data.images.new("Washboard", width, 4, alpha=False, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    a = np.radians(degrees) * np.sin(2 * np.pi * ridges * (np.arange(width) + 0.5) / width)
    row = np.stack([np.sin(a), np.zeros_like(a), np.cos(a)], -1)
    pixels = np.ones((4, width, 4), np.float32)
    pixels[..., :3] = (row[None] + 1) / 2
    image.pixels.foreach_set(pixels.ravel())
    image.pack()
    return image


def washboard(tree):
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = bpy.data.images.get("Washboard") or washboard_image()
    return node


def floor_under_sun(context, material):
    add_uv_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], material)
    light = bpy.data.lights.new("Sun", "SUN")
    light.energy, light.color, light.angle = STRENGTH, COLOR, 0.0
    sun = bpy.data.objects.new("Sun", light)
    sun.rotation_euler = (0, math.radians(TILT), 0)  # towards the light: (sin TILT, 0, cos TILT)
    context.scene.collection.objects.link(sun)


def solve(context, preset="PREVIEW"):
    context.scene.bsgi.preset = preset
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    return job, solution.surfaces[exported_object(job.export, "Floor").patches[0][1]]


@pytest.mark.parametrize("principled", [False, True])
@pytest.mark.parametrize("correction", [True, False])
def test_a_tilted_normal_map_is_a_tilted_plane_under_the_sun(context, principled, correction):
    # The map's tangent-space normal (sin 25, 0, cos 25) is the floor's (its u along +x) turned
    # 25 degrees towards the sun at 40: rho / pi E cos(15) (times G1 at the sun's 40 degrees to the
    # floor with Bump Map Correction).
    theta = math.radians(25)
    material = bumped_material("Bumped", constant([math.sin(theta), 0, math.cos(theta)]), principled)
    material.cycles.use_bump_map_correction = correction
    floor_under_sun(context, material)
    job, floor = solve(context)
    assert not any("Normal input" in w or "normal" in w.lower() for w in job.export.warnings), job.export.warnings
    uv = np.random.default_rng(3).uniform(0.05, 0.95, (40, 2))
    got = floor.evaluate(uv, np.tile([0.3, -0.2, 0.9], (len(uv), 1)))
    t = math.radians(TILT)
    g = cycles_shadowing(math.cos(theta), math.cos(t)) if correction else 1.0
    want = ALBEDO / math.pi * STRENGTH * np.array(COLOR) * math.cos(t - theta) * g
    err = np.abs(got / want - 1).max()
    print(f"\nbumped floor ({'principled' if principled else 'diffuse'}, correction {correction}): worst {err:.2e} "
          f"of the tilted plane's {want[0]:.4f}")
    assert err < 6e-4  # measured 2.9e-4 with the correction (G1 over the spline's cap), 1.4e-5 without
    # The normals the solve took: the map's, in the floor's frame, everywhere.
    normals = 2 * floor.normals.reshape(-1, 3).astype(float) - 1
    off = np.abs(normals - [math.sin(theta), 0, math.cos(theta)]).max()
    print(f"baked normals off by {off:.1e}")
    assert off < 1e-4


def test_the_scenes_bumps_setting_solves_them_flat(context):
    # Bumps Flat: the surface with its own normals (2D), the choice named.
    floor_under_sun(context, bumped_material("Washboard", washboard))
    context.scene.bsgi.bumps = "FLAT"
    job, floor = solve(context, "DRAFT")
    assert floor.normals is None and floor.kind == "diffuse"
    assert any("Normal input (normal map) is solved flat" in w for w in job.export.warnings), job.export.warnings


def test_a_bump_on_a_glossy_shader_is_named(context):
    m = bumped_material("Shiny", constant([0.3, 0, 0.95]))
    tree = m.node_tree
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    tree.links.new(tree.nodes["Normal Map"].outputs["Normal"], glossy.inputs["Normal"])
    tree.links.new(glossy.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    floor_under_sun(context, m)
    job, floor = solve(context, "DRAFT")
    assert any("Normal input (normal map) is ignored" in w for w in job.export.warnings), job.export.warnings
    assert floor.normals is None


def test_a_coated_principled_folds_its_coat_under_a_bump(context):
    m = bumped_material("Default", constant([0.3, 0, 0.95]), principled=True)
    shader = next(n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    shader.inputs["Specular IOR Level"].default_value = 0.5
    floor_under_sun(context, m)
    job, floor = solve(context, "DRAFT")
    assert any("coat (the specular layer) folded" in w for w in job.export.warnings), job.export.warnings
    assert floor.normals is not None


def cycles_and_bake(context, tmp_path):
    """Cycles' render of the floor from above (direct light only, 256 samples), then the add-on's
    solve at preview (direct light) and bake, and Cycles' render of the bake: (reference, baked,
    the solve's report)."""
    reference, _ = render_floor_from_above(context, tmp_path / "cycles.exr", samples=256)
    context.scene.bsgi.preset = "PREVIEW"
    context.scene.bsgi.max_bounces = 0
    report = pipeline.solve_and_bake(context)
    return reference, render_exr(context.scene, tmp_path / "baked.exr", samples=16, bounces=0), report


@pytest.mark.slow
def test_a_washboard_normal_map_baked_is_what_cycles_renders(context, tmp_path):
    # Ridges of +-35 degrees across the floor under a sun at 40 degrees and a grey world, seen from
    # straight above: Cycles' path-traced render (direct light only) against its render of the bake
    # (the atlas over the bumped normal looked up along the user's own Normal Map node).
    floor_under_sun(context, bumped_material("Washboard", washboard))
    world = bpy.data.worlds.new("Grey")
    if world.node_tree is None:
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.3, 0.3, 1)
    context.scene.world = world
    reference, baked, report = cycles_and_bake(context, tmp_path)
    assert not any("ignored" in w for w in report.get("warnings", [])), report.get("warnings")
    columns_ref, columns_baked = reference.mean(axis=(0, 2)), baked.mean(axis=(0, 2))  # ridges run along v
    rel = np.abs(baked - reference).sum(axis=2) / reference.sum(axis=2)
    flat = ALBEDO / math.pi * (STRENGTH * np.mean(COLOR) * math.cos(math.radians(TILT)) + 0.3 * math.pi)
    print(f"\nwashboard: baked / Cycles mean {baked.mean() / reference.mean():.4f}, per pixel {rel.mean():.4f}; "
          f"columns from {columns_ref.min():.4f} to {columns_ref.max():.4f} (Cycles), {columns_baked.min():.4f} to "
          f"{columns_baked.max():.4f} (baked), the flat floor {flat:.4f}")
    assert columns_ref.max() - columns_ref.min() > 0.3 * flat  # the ridges show
    # Measured: mean 0.9989, per pixel 0.32% (Cycles' own noise at 256 samples about 0.2% of it;
    # 11 x 11 angular over the 57.5-degree cap; 1.3% and 0.9901 at the lobe's 7 x 7).
    assert abs(baked.mean() / reference.mean() - 1) < 2e-3
    assert rel.mean() < 0.005
    # Material Preview's engine shows the same bake: EEVEE's render of it (the Normal Map node
    # evaluated by EEVEE) against Cycles', column by column across the ridges.
    from subprocess_render import run_bpy
    from test_bake_view import read_exr
    from test_textures import EEVEE_RENDER

    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    run = run_bpy(EEVEE_RENDER, args=[str(blend), str(tmp_path / "eevee.exr")])
    assert run.ok, run.log
    columns_eevee = read_exr(tmp_path / "eevee.exr").mean(axis=(0, 2))
    eevee_rel = np.abs(columns_eevee / columns_baked - 1)
    print(f"EEVEE's render of the bake against Cycles': columns {eevee_rel.mean():.4f} on average, at most "
          f"{eevee_rel.max():.4f}")
    assert eevee_rel.mean() < 0.007  # measured 0.0033 (at most 0.060, in one column)


def test_an_object_of_a_bumped_and_a_glossy_material_bakes_each_on_its_disc(context):
    # One mesh, a bumped diffuse face and a metal face: the bumped slot's material looks its atlas
    # up along the user's Normal Map on the bumped cap's disc, the metal's along the view on the
    # glossy disc (they differ: the cap spans the map's normals only).
    bumped = bumped_material("Washboard", washboard)
    metal = bpy.data.materials.new("Metal")
    shader = metal.node_tree.nodes["Principled BSDF"]
    shader.inputs["Metallic"].default_value, shader.inputs["Roughness"].default_value = 1.0, 0.4
    mesh = bpy.data.meshes.new("Two")
    mesh.from_pydata([(-1, -1, 0), (0, -1, 0), (0, 1, 0), (-1, 1, 0), (1, -1, 0), (1, 1, 0)], [],
                     [(0, 1, 2, 3), (1, 4, 5, 2)])
    uv = mesh.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", np.array([0, 0, 1, 0, 1, 1, 0, 1] * 2, np.float32))
    mesh.materials.append(bumped)
    mesh.materials.append(metal)
    mesh.polygons[1].material_index = 1
    obj = bpy.data.objects.new("Floor", mesh)
    context.scene.collection.objects.link(obj)
    light = bpy.data.lights.new("Sun", "SUN")
    light.energy = STRENGTH
    sun = bpy.data.objects.new("Sun", light)
    sun.rotation_euler = (0, math.radians(TILT), 0)
    context.scene.collection.objects.link(sun)
    context.scene.bsgi.preset = "DRAFT"
    report = pipeline.solve_and_bake(context)
    slot_materials = [bpy.data.materials[name] for name in obj["bsgi_slot_materials"] if name]
    assert len(slot_materials) == 1
    groups = {n.node_tree.name: n.inputs["Disc Radius"].default_value
              for m in (slot_materials[0], obj.material_slots[1].material) for n in m.node_tree.nodes
              if n.type == "GROUP" and "Disc Radius" in n.inputs}
    print(f"\ndiscs: {groups}")
    assert set(groups) == {"BSGI Normal Radiance", "BSGI View Radiance"}
    assert groups["BSGI Normal Radiance"] < 0.8 < groups["BSGI View Radiance"]
    direction = next(n for n in slot_materials[0].node_tree.nodes if n.type == "GROUP" and "Direction" in n.inputs)
    assert direction.inputs["Direction"].links[0].from_node.type == "NORMAL_MAP"
    assert not any("along the view" in w for w in report.get("warnings", []))
    # The radiance stored on the object keeps the bumped normals: a bake redone without a solve.
    from bsgi_addon import bake

    stored = bake.stored_faces(obj)
    assert stored[0][1][0].normals is not None and stored[1][1][0].normals is None
    bake.rebake(obj)


@pytest.mark.slow
def test_a_bump_node_under_a_textured_colour_baked_is_what_cycles_renders(context, tmp_path):
    # A Principled BSDF (no specular) whose Base Color is a Checker and whose Normal is a Bump
    # node over a Wave texture's bands: Cycles' normal pass evaluates the bump for the solve, the
    # bake multiplies its atlas by the Checker and looks it up along the Bump node.
    from scene_parts import wave_bump
    from test_textures import checker

    m = bpy.data.materials.new("Bumpy checker")
    tree = m.node_tree
    shader = tree.nodes["Principled BSDF"]
    shader.inputs["Specular IOR Level"].default_value = 0.0
    tree.links.new(checker(tree).outputs["Color"], shader.inputs["Base Color"])
    wave_bump(tree, shader, scale=3.0, strength=1.0, distance=0.02)
    floor_under_sun(context, m)
    context.scene.bsgi.texture_texels = 64
    reference, baked, report = cycles_and_bake(context, tmp_path)
    assert not any("Normal input" in w for w in report.get("warnings", [])), report.get("warnings")
    rel = np.abs(baked - reference).sum(axis=2) / reference.sum(axis=2)
    spread = reference.mean(axis=2).std() / reference.mean()
    print(f"\nbumped checker: baked / Cycles mean {baked.mean() / reference.mean():.4f}, per pixel {rel.mean():.4f} "
          f"(median {np.median(rel):.4f}); the render's spread {spread:.3f}")
    # Without the bump (the Normal input unlinked: the flat floor) the bake is what Cycles renders
    # of a flat floor, not of this one.
    tree.links.remove(shader.inputs["Normal"].links[0])
    pipeline.solve_and_bake(context)
    flat = render_exr(context.scene, tmp_path / "flat.exr", samples=16, bounces=0)
    flat_rel = (np.abs(flat - reference).sum(axis=2) / reference.sum(axis=2)).mean()
    print(f"the flat floor's bake: per pixel {flat_rel:.4f} from Cycles' render of the bumped one")
    assert flat_rel > 3 * rel.mean()
    assert abs(baked.mean() / reference.mean() - 1) < 3e-3  # measured 0.9990
    assert rel.mean() < 0.01  # measured 0.0052
