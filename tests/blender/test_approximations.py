"""The report of what a solve approximates (addon/export.py Approximation, pipeline.report_lines):
per material (with the objects it is on), light, object and world, each approximated input once,
and the status line's count of them."""
import bpy

import scenes
from bsgi_addon import pipeline


def _patterned_material():
    """A Principled BSDF with a normal map and an alpha mask: its coat is folded under the bump, the
    mask is not modelled."""
    m = bpy.data.materials.new("Tiles")
    if m.node_tree is None:
        m.use_nodes = True
    nodes, links = m.node_tree.nodes, m.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    normal_map = nodes.new("ShaderNodeNormalMap")
    links.new(normal_map.outputs["Normal"], bsdf.inputs["Normal"])
    noise = nodes.new("ShaderNodeTexNoise")
    links.new(noise.outputs["Fac"], bsdf.inputs["Alpha"])
    return m


def test_report_names_each_approximation_once_per_material_with_its_objects(context):
    tiles = _patterned_material()
    scenes.add_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], tiles)
    scenes.add_quad("Step", [(-1, -1, 0.2), (-0.5, -1, 0.2), (-0.5, -0.5, 0.2), (-1, -0.5, 0.2)], tiles)
    lamp = scenes.add_area_light()
    lamp.data.spread = 1.0  # solved as 180 degrees, with a warning naming the light
    bpy.context.view_layer.update()
    settings = context.scene.bsgi
    settings.preset = "DRAFT"
    rep = pipeline.solve_and_bake(context)

    by_owner = {a["owner"]: a for a in rep["approximations"]}
    assert set(by_owner) == {"material 'Tiles'", "light 'Lamp'"}
    tiles_entry = by_owner["material 'Tiles'"]
    assert tiles_entry["objects"] == ["Floor", "Step"]
    assert len(tiles_entry["notes"]) == 2  # once each, although two objects use it
    assert any("Normal input (normal map) is solved on its diffuse base" in n and "coat" in n for n in tiles_entry["notes"])
    assert any("Alpha input" in n and "opaque" in n for n in tiles_entry["notes"])
    assert by_owner["light 'Lamp'"]["objects"] == []

    lines = pipeline.report_lines(rep)
    assert lines[0].startswith("material 'Tiles' (on 'Floor', 'Step'): ") and "normal map" in lines[0]
    assert sum("'Tiles'" in line for line in lines) == 1  # grouped: one line for the material
    assert "3 approximations in 2 items" in pipeline.summary_text(rep)


def test_a_scene_solved_exactly_reports_no_approximation(context):
    scenes.floor_under_lamp()
    bpy.context.view_layer.update()
    context.scene.bsgi.preset = "DRAFT"
    rep = pipeline.solve_and_bake(context)
    assert rep["approximations"] == [] and pipeline.report_lines(rep) == []
    assert "approximation" not in pipeline.summary_text(rep)
