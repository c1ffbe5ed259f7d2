"""The example scenes in example_blends/: each committed .blend is what its script generates, and
each solves and bakes out of the box with the headless command (addon/cli.py) at the draft
preset into finite, non-black images."""
import pathlib
import runpy

import bpy
import numpy as np
import pytest

import cli
from bsgi_addon import bake

EXAMPLES_DIR = pathlib.Path(__file__).resolve().parents[2] / "example_blends"
SCRIPTS = sorted(EXAMPLES_DIR.glob("make_*.py"))
# .blend file name -> the script that writes it
EXAMPLES = {name: script for script in SCRIPTS for name in runpy.run_path(str(script))["BUILDERS"]}
DIGITS = 5  # floats are compared rounded: Blender stores them in single precision
# Scenes whose draft solve takes several seconds (glossy 4D splines on many surfaces): slow tests.
SLOW_TO_SOLVE = {"cornell_box_glossy.blend", "glossy_spheres.blend", "furnished_interior.blend"}


def test_every_committed_blend_has_its_script():
    assert sorted(p.name for p in EXAMPLES_DIR.glob("*.blend")) == sorted(EXAMPLES)


def _rounded(values):
    return tuple(round(float(v), DIGITS) for v in values)


def _material(m):
    if m is None:
        return None
    nodes = {}
    if m.node_tree is not None:
        for node in m.node_tree.nodes:
            inputs = {s.identifier: (_rounded(s.default_value) if hasattr(s.default_value, "__len__")
                                     else round(float(s.default_value), DIGITS))
                      for s in node.inputs if hasattr(s, "default_value") and not isinstance(s.default_value, str)}
            links = sorted(f"{s.name}<-{s.links[0].from_node.name}" for s in node.inputs if s.is_linked)
            nodes[node.name] = (node.bl_idname, inputs, links)
    return {"name": m.name, "nodes": nodes}


def _geometry(obj):
    data = obj.data
    if obj.type == "MESH":
        co = np.empty(3 * len(data.vertices))
        data.vertices.foreach_get("co", co)
        return {"vertices": _rounded(co), "faces": [tuple(p.vertices) for p in data.polygons],
                "material_indices": [p.material_index for p in data.polygons]}
    if obj.type == "SURFACE":
        return [{"counts": (s.point_count_u, s.point_count_v), "orders": (s.order_u, s.order_v),
                 "flags": (s.use_endpoint_u, s.use_endpoint_v, s.use_bezier_u, s.use_bezier_v, s.use_cyclic_u,
                           s.use_cyclic_v),
                 "points": _rounded(c for p in s.points for c in p.co), "material_index": s.material_index}
                for s in data.splines]
    if obj.type == "LIGHT":
        size = (data.size, data.size_y) if data.type == "AREA" else (getattr(data, "angle", 0.0),)
        return {"type": data.type, "shape": getattr(data, "shape", None), "size": _rounded(size),
                "energy": round(data.energy, DIGITS), "color": _rounded(data.color)}
    if obj.type == "CAMERA":
        return {"lens": round(data.lens, DIGITS)}
    return None


def scene_description(path) -> dict:
    """What the scene in path is made of: objects (names, types, transforms, geometry, the
    add-on's per-object options), the materials in their slots (nodes and input values), the
    camera and render settings."""
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    objects = {
        obj.name: {"type": obj.type, "parent": obj.parent.name if obj.parent else None,
                   "transform": _rounded(c for row in obj.matrix_world for c in row),
                   "materials": [(slot.link, _material(slot.material)) for slot in obj.material_slots],
                   "geometry": _geometry(obj),
                   "solver_options": {p.identifier: getattr(obj.bsgi, p.identifier)
                                      for p in obj.bsgi.bl_rna.properties if p.identifier != "rna_type"}}
        for obj in scene.objects
    }
    world = scene.world
    return {"objects": objects, "camera": scene.camera.name if scene.camera else None,
            "engine": scene.render.engine, "resolution": (scene.render.resolution_x, scene.render.resolution_y),
            "view_transform": scene.view_settings.view_transform,
            "world": _material(world) if world is not None else None}


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_committed_blend_is_what_its_script_generates(name, tmp_path):
    builders = runpy.run_path(str(EXAMPLES[name]))["BUILDERS"]
    builders[name]()
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / name), compress=True)
    committed = EXAMPLES_DIR / name
    assert scene_description(committed) == scene_description(tmp_path / name), (
        f"{name} differs from what {EXAMPLES[name].name} generates: rerun the script")
    assert not any(image.packed_file for image in bpy.data.images), f"{name} packs images"
    assert committed.read_bytes()[:7] != b"BLENDER", f"{name} is saved without compression"


def _images(node_tree, seen=None):
    """Images reachable from a node tree, through node groups."""
    seen = set() if seen is None else seen
    for node in node_tree.nodes:
        if getattr(node, "image", None) is not None:
            seen.add(node.image.name)
        if getattr(node, "node_tree", None) is not None:
            _images(node.node_tree, seen)
    return seen


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_TO_SOLVE else n
                                  for n in sorted(EXAMPLES)])
def test_example_solves_and_bakes_at_draft(name, tmp_path, capsys):
    out = tmp_path / name
    status = cli.main([str(EXAMPLES_DIR / name), "--out", str(out), "--render", str(tmp_path / "view.png"),
                       "--resolution", "64", "48", "--preset", "draft"])
    printed = capsys.readouterr()
    assert status == 0, printed.err
    assert "bsgi: error" not in printed.err
    assert (tmp_path / "view.png").stat().st_size > 0

    bpy.ops.wm.open_mainfile(filepath=str(out))  # the saved, solved scene
    geometry = [o for o in bpy.context.scene.objects if o.type in {"MESH", "SURFACE"}]
    assert geometry
    for obj in geometry:
        assert bake.is_baked(obj), f"{name}: '{obj.name}' is not baked"
        for _, radiances in bake.stored_faces(obj):
            for radiance in filter(None, radiances):  # None: an emitter's face
                for spline in filter(None, (radiance.upper, radiance.lower, radiance.diffuse)):
                    assert np.isfinite(spline.coefficients).all(), f"{name}: '{obj.name}' has non-finite radiance"
        # The bake is shown: the slots hold the baked materials (one per spline for several splines).
        images = set()
        for slot in obj.material_slots:
            images |= _images(slot.material.node_tree)
        assert images, f"{name}: '{obj.name}' shows no baked image"
        for image_name in images:
            image = bpy.data.images[image_name]
            pixels = np.empty(len(image.pixels), np.float32)
            image.pixels.foreach_get(pixels)
            rgb = pixels.reshape(-1, image.channels)[:, :3]
            assert np.isfinite(rgb).all(), f"{name}: image '{image_name}' has non-finite texels"
            if not image_name.endswith((" tangent", " normal")):  # the frame images of view-dependent bakes
                assert rgb.max() > 1e-3, f"{name}: image '{image_name}' is black"
