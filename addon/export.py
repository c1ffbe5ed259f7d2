"""Blender scene -> bsgi.Scene: the only place that reads the user's scene for a solve, by what it
reads: geometry.py (meshes, charts, NURBS, instances), materials.py (node trees), lights.py (lights
and the world).

Nothing of the user's data is changed here: meshes come from the evaluated depsgraph
(`to_mesh()` on evaluated objects, cleared afterwards), NURBS surfaces are read from their
splines, and materials are the user's even where a bake is shown."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import bpy

import bsgi

from . import geometry, lights, textures
from .materials import averaged_inputs, user_slots


@dataclass
class Approximation:
    """What the solve approximates of one material, light, object or world: each input and how
    (from the export's warnings, which name their owner first), and the objects a material is on."""

    owner: str  # "material 'Checker'", "light 'Lamp'", "object 'Ball'", "world 'World'"
    notes: list  # what is approximated and how, one sentence each
    objects: list = field(default_factory=list)  # for a material: the objects using it

    def text(self) -> str:
        on = f" (on {', '.join(repr(o) for o in self.objects)})" if self.objects else ""
        return f"{self.owner}{on}: " + "; ".join(self.notes)


@dataclass
class Export:
    scene: bsgi.Scene
    objects: list  # of ExportedObject, the bake targets
    warnings: list
    users: dict = field(default_factory=dict)  # material name -> the objects it is on
    textures: dict = field(default_factory=dict)  # the texture bake's {"seconds", "texels"}

    def approximations(self) -> list:
        """The warnings so far as Approximations, one per material, light, object or world."""
        return approximations(self.warnings, self.users)


_OWNER = re.compile(r"^((?:material|light|object|world) '.*?'): (.*)$", re.S)


def approximations(warnings: list, users: dict) -> list:
    """The warnings grouped by what they approximate, once per owner; a material's entry lists
    the objects using it (users: material name -> object names)."""
    grouped: dict = {}
    for warning in warnings:
        match = _OWNER.match(warning)
        if match:
            grouped.setdefault(match.group(1), []).append(match.group(2))
    result = []
    for owner, notes in grouped.items():
        name = owner.split("'", 1)[1][:-1]
        objects = sorted(users.get(name, ())) if owner.startswith("material") else []
        result.append(Approximation(owner, list(dict.fromkeys(notes)), objects))
    return result


def linked_from(obj) -> str:
    """The library file an object or its data is linked from, or ''."""
    for block in (obj, obj.data):
        library = getattr(block, "library", None)
        if library is not None:
            return library.filepath
    return ""


def export_scene(depsgraph) -> Export:
    """Every visible geometry object's faces as patches (a NURBS surface object's splines as exact
    surfaces), every area and point light as an emitter, suns as distant lights, a one-colour world
    as world light."""
    # Node-driven roughness and metallic, one mean per material, as Blender evaluates them.
    with averaged_inputs(textures.socket_means(depsgraph)):
        return _export_scene(depsgraph)


def _export_scene(depsgraph) -> Export:
    scene = bsgi.Scene()
    objects, warnings = [], []
    instances: dict = {}  # (object, instancer) -> count, for one warning per pair
    pending_charts: list = []
    users: dict = {}  # material name -> the objects it is on, for the report
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
        for material in user_slots(obj):
            if material is not None:
                users.setdefault(material.name, set()).add(obj.original.name)
        if inst.is_instance:
            instances[key] = instances.get(key, 0) + 1
            if textures.has_textures(obj):
                warnings.append(f"object '{obj.name}': its instances' node-driven colour and emission use the "
                                "sockets' own values (textures are baked on real objects; make the instances real)")
        else:
            if obj.type in geometry.EVALUATED_ONLY:
                exported.not_baked = (f"{geometry.EVALUATED_ONLY[obj.type]} objects are meshes only as Blender evaluates "
                                      "them, and a bake needs a mesh of its own to hold its UV map; convert it to a "
                                      "mesh (Object > Convert > Mesh) to bake it")
            elif linked_from(obj.original):
                exported.not_baked = (f"it is linked from the library '{linked_from(obj.original)}', whose data a "
                                      "bake cannot change; make it local (Object > Relations > Make Local) to bake it")
            objects.append(exported)
    for job in pending_charts:
        geometry.build_chart(scene, job, warnings)
    for exported in objects:
        if exported.not_baked:
            warnings.append(f"object '{exported.name}': solved (it casts shadows and reflects light) but not baked: "
                            f"{exported.not_baked}")
    # Node-driven colour and emission, as Blender evaluates them (instances share their mesh and
    # keep the sockets' own values).
    textured = textures.apply_textures(depsgraph, scene, objects, warnings)
    objects = [exported for exported in objects if not exported.not_baked]
    for (name, parent), count in instances.items():
        warnings.append(f"object '{name}': {count} instance{'s' if count > 1 else ''} from '{parent}' "
                        f"{'are' if count > 1 else 'is'} solved (casting shadows and reflecting light) but not "
                        "baked: instances share one mesh, which cannot show each instance's own light; make them "
                        "real (Object > Apply > Make Instances Real) to bake them")
    for name in users:
        for image, path in textures.missing_images(bpy.data.materials.get(name)):
            warnings.append(f"material '{name}': image '{image}' cannot be read ('{path}' is missing); it is solved "
                            "magenta, as Cycles renders it")
    lights.world_light(depsgraph.scene, scene, warnings)
    return Export(scene, objects, list(dict.fromkeys(warnings)), users, textured)
