"""Blender scene -> bsgi.Scene: the only place that reads the user's scene for a solve, by what it
reads: geometry.py (meshes, charts, NURBS, instances), materials.py (node trees), lights.py (lights
and the world).

Nothing of the user's data is changed here: meshes come from the evaluated depsgraph
(`to_mesh()` on evaluated objects, cleared afterwards), NURBS surfaces are read from their
splines, and materials are the user's even where a bake is shown."""
from __future__ import annotations

from dataclasses import dataclass

import bsgi

from . import geometry, lights


@dataclass
class Export:
    scene: bsgi.Scene
    objects: list  # of ExportedObject, the bake targets
    warnings: list


def export_scene(depsgraph) -> Export:
    """Every visible geometry object's faces as patches (a NURBS surface object's splines as exact
    surfaces), every area and point light as an emitter, suns as distant lights, a one-colour world
    as world light."""
    scene = bsgi.Scene()
    objects, warnings = [], []
    instances: dict = {}  # (object, instancer) -> count, for one warning per pair
    pending_charts: list = []
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type == "LIGHT":
            lights.add_light(scene, obj, warnings)
            continue
        if obj.type not in geometry.GEOMETRY_TYPES:
            continue
        if geometry.own_geometry(inst) or not inst.show_self:  # show_self: e.g. a particle emitter set not to show
            continue
        label = None
        if inst.is_instance:
            key = (obj.name, inst.parent.name if inst.parent is not None else "")
            label = f"{obj.name} (instance {instances.get(key, 0)} of '{key[1]}')"
        exported = geometry.add_object(scene, obj, inst.matrix_world, warnings, label, pending_charts)
        if exported is None:
            continue
        if inst.is_instance:
            instances[key] = instances.get(key, 0) + 1
        else:
            if obj.type in geometry.EVALUATED_ONLY:
                exported.not_baked = (f"{geometry.EVALUATED_ONLY[obj.type]} objects are meshes only as Blender evaluates "
                                      "them, and a bake needs a mesh of its own to hold its UV map; convert it to a "
                                      "mesh (Object > Convert > Mesh) to bake it")
            objects.append(exported)
    for job in pending_charts:
        geometry.build_chart(scene, job, warnings)
    for exported in objects:
        if exported.not_baked:
            warnings.append(f"object '{exported.name}': solved (it casts shadows and reflects light) but not baked: "
                            f"{exported.not_baked}")
    objects = [exported for exported in objects if not exported.not_baked]
    for (name, parent), count in instances.items():
        warnings.append(f"object '{name}': {count} instance{'s' if count > 1 else ''} from '{parent}' "
                        f"{'are' if count > 1 else 'is'} solved (casting shadows and reflecting light) but not "
                        "baked: instances share one mesh, which cannot show each instance's own light; make them "
                        "real (Object > Apply > Make Instances Real) to bake them")
    lights.world_light(depsgraph.scene, scene, warnings)
    return Export(scene, objects, list(dict.fromkeys(warnings)))
