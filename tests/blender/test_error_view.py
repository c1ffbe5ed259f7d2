"""The solver's per-object error estimate in the add-on (addon/error_view.py): stored on the
object, named in the solve's report, and shown as an error-coloured preview that switches back to
the baked look exactly."""
import math

import bpy
import numpy as np

import scenes
from bsgi_addon import bake, error_view, pipeline


def _tree(material):
    """A material's nodes, links and custom properties, to compare before and after."""
    tree = material.node_tree
    return (sorted((n.name, n.type) for n in tree.nodes),
            sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier) for l in tree.links),
            sorted(material.keys()))


def _shadowed_floor():
    floor = scenes.floor_under_lamp()
    scenes.add_quad("Plate", [(-0.2, -0.2, 0.5), (-0.2, 0.2, 0.5), (0.2, 0.2, 0.5), (0.2, -0.2, 0.5)],
                    scenes.diffuse_material("Plate Grey", (0.5, 0.5, 0.5)))
    return floor


def test_solve_stores_and_reports_each_objects_estimate(context):
    floor = _shadowed_floor()
    context.scene.bsgi.preset = "DRAFT"
    rep = pipeline.solve_and_bake(context)
    for name in ("Floor", "Plate"):
        error = bpy.data.objects[name][error_view.PROP_ERROR]
        assert math.isfinite(error) and 0 < error < 1, (name, error)
        assert rep["estimated_errors"][name] == error
    # The report names the objects, the largest estimate first.
    ordered = sorted(("Floor", "Plate"), key=lambda n: -rep["estimated_errors"][n])
    assert "highest estimated error: " + ", ".join(
        f"{n} {100 * rep['estimated_errors'][n]:.1f}%" for n in ordered) in pipeline.summary_text(rep)
    bpy.ops.bsgi.clear()
    assert error_view.PROP_ERROR not in floor


def test_show_estimated_error_colours_the_bake_and_restores_it(context):
    floor = _shadowed_floor()
    grey = floor.data.materials[0]
    user_before = _tree(grey)
    context.scene.bsgi.preset = "DRAFT"
    pipeline.solve_and_bake(context)
    baked = floor.active_material
    baked_before = _tree(baked)
    context.scene.bsgi.show_error = True
    output = next(n for n in baked.node_tree.nodes if n.type == "OUTPUT_MATERIAL" and n.is_active_output)
    source = output.inputs["Surface"].links[0].from_node
    assert source.name == error_view.NODE_NAME
    expected = error_view.colour(floor[error_view.PROP_ERROR])
    assert np.allclose(tuple(source.inputs["Color"].default_value)[:3], expected, atol=1e-6)  # float32
    assert _tree(baked) != baked_before
    context.scene.bsgi.show_error = False
    assert _tree(baked) == baked_before  # the baked look exactly
    assert _tree(grey) == user_before  # the user's material never touched
    # On again and a clear: the user's material is back, the bake's gone.
    context.scene.bsgi.show_error = True
    bpy.ops.bsgi.clear()
    assert floor.active_material == grey and _tree(grey) == user_before


def test_colour_ramp_ends():
    assert error_view.colour(0.005) == (0.0, 1.0, 0.0)
    assert error_view.colour(0.2) == (1.0, 0.0, 0.0)
    assert np.allclose(error_view.colour(math.sqrt(0.001)), (1.0, 1.0, 0.0))  # the middle of the log ramp
    assert error_view.colour(math.nan) == error_view.UNKNOWN
