"""The solver's per-surface error estimate per object: stored on the object, listed in the solve's
report, and shown as an error-coloured preview the user can switch to (Show Estimated Error).

The preview changes only the bake's own materials: their Material Output is linked to an emission
node of the object's colour (green at 1% estimated error or less, through yellow, to red at 10% or
more), and the link it had is remembered on the material; switching back restores that link and
removes the node, so the materials are exactly as baked."""
from __future__ import annotations

import math

import bpy

PROP_ERROR = "bsgi_estimated_error"  # on an object: relative RMS error of its radiance (a fraction)
PROP_SOURCE = "bsgi_error_view_source"  # on a material while it shows the error: [node, output socket] or []
NODE_NAME = "BSGI Estimated Error"
GOOD, BAD = 0.01, 0.10  # the ramp's ends
UNKNOWN = (0.5, 0.5, 0.5)  # grey: no estimate (an object solved with the estimate switched off)


def object_errors(export, solution) -> dict:
    """Per baked object: the root mean square of its surfaces' estimated errors (surfaces without
    an estimate left out; NaN if none has one)."""
    by_name = {r["name"]: r.get("estimated_error", math.nan) for r in solution.reports}
    out = {}
    for exported in export.objects:
        values = [by_name.get(export.scene.name(first + k), math.nan)
                  for _, first, count in exported.patches for k in range(count)]
        values = [v for v in values if math.isfinite(v)]
        out[exported.name] = math.sqrt(sum(v * v for v in values) / len(values)) if values else math.nan
    return out


def worst_text(errors: dict, count: int = 3) -> str:
    """"highest estimated error: Floor 3.2%, Wall 1.1%" for the objects of largest estimate."""
    known = sorted(((e, name) for name, e in errors.items() if math.isfinite(e)), reverse=True)[:count]
    if not known:
        return ""
    return "highest estimated error: " + ", ".join(f"{name} {100 * e:.1f}%" for e, name in known)


def colour(error: float) -> tuple:
    """Green at GOOD or less, yellow between, red at BAD or more (log scale); grey if unknown."""
    if not math.isfinite(error):
        return UNKNOWN
    t = min(max(math.log(max(error, 1e-12) / GOOD) / math.log(BAD / GOOD), 0.0), 1.0)
    return (min(1.0, 2 * t), min(1.0, 2 * (1 - t)), 0.0)


def baked_materials(obj) -> list:
    """The materials the bake made for obj (its baked material, per-spline and per-slot copies)."""
    from . import bake

    names = [obj.get(bake.PROP_MATERIAL), *obj.get(bake.PROP_SPLINE_MATERIALS, []),
             *obj.get(bake.PROP_SLOT_MATERIALS, [])]
    materials = [bpy.data.materials.get(n) for n in dict.fromkeys(n for n in names if n)]
    return [m for m in materials if m is not None and m.node_tree is not None]


def _output(material):
    outputs = [n for n in material.node_tree.nodes if n.type == "OUTPUT_MATERIAL"]
    active = [n for n in outputs if n.is_active_output]
    return (active or outputs or [None])[0]


def show_error(obj, on: bool) -> None:
    """Switch obj's baked materials between the error colour and their baked look."""
    colour_of = colour(float(obj.get(PROP_ERROR, math.nan)))
    for material in baked_materials(obj):
        output = _output(material)
        if output is None:
            continue
        tree = material.node_tree
        node = tree.nodes.get(NODE_NAME)
        if on:
            if PROP_SOURCE not in material or node is None:  # (a re-bake rebuilt the tree: its link is the baked look)
                links = output.inputs["Surface"].links
                material[PROP_SOURCE] = [links[0].from_node.name, links[0].from_socket.identifier] if links else []
            if node is None:
                node = tree.nodes.new("ShaderNodeEmission")
                node.name = node.label = NODE_NAME
                node.location = (output.location[0], output.location[1] + 200)
            node.inputs["Color"].default_value = (*colour_of, 1.0)
            node.inputs["Strength"].default_value = 1.0
            tree.links.new(node.outputs["Emission"], output.inputs["Surface"])
            continue
        if PROP_SOURCE not in material:
            continue
        source = list(material[PROP_SOURCE])
        if node is not None:
            tree.nodes.remove(node)
        if source and node is not None:
            from_node = tree.nodes.get(source[0])
            socket = next((s for s in from_node.outputs if s.identifier == source[1]), None) if from_node else None
            if socket is not None:
                tree.links.new(socket, output.inputs["Surface"])
        del material[PROP_SOURCE]


def refresh(scene) -> None:
    """Every baked object of the scene as the scene's Show Estimated Error says."""
    from . import bake

    on = bool(scene.bsgi.show_error)
    for obj in scene.objects:
        if bake.is_baked(obj):
            show_error(obj, on)
