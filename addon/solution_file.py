"""The baked objects' splines to and from the core's solution file (bsgi.save_solution)."""
from __future__ import annotations

import re

import bpy

import bsgi

from . import bake

# Surface names as the exporter gives them: "<object>: face <i>[ triangle <k>]", "<object>: spline <i>",
# "<object>: chart 0".
_FACE = re.compile(r"^(?P<object>.*): (?P<part>face|spline|chart) (?P<face>\d+)(?: triangle (?P<k>\d+))?$")


def export_solution(scene, path) -> int:
    """Write every baked object's radiance (all its splines: upper, lower, diffuse part);
    returns the number of surfaces written."""
    radiance, names = [], []
    for obj in scene.objects:
        if bake.PROP_RADIANCE not in obj:
            continue
        for i, (kind, surfaces) in enumerate(bake.stored_faces(obj)):
            for k, surface in enumerate(surfaces):
                part = {"nurbs": "spline", "chart": "chart"}.get(kind, "face")
                names.append(f"{obj.name}: {part} {i}" + (f" triangle {k}" if kind == "ngon" else ""))
                radiance.append(surface)
    if not radiance:
        raise ValueError("no baked objects: solve first")
    bsgi.save_solution(path, radiance, names, scene.bsgi.solver_settings())
    return len(radiance)


def import_solution(scene, path) -> list:
    """Bake the splines of a solution file onto the objects they name; returns the objects."""
    stored = bsgi.load_solution(path)
    per_object: dict = {}
    charts = set()  # objects solved as one UV chart: baked through the UV map of their solve
    for name, surface in zip(stored.names, stored.surfaces):
        match = _FACE.match(name)
        if surface is None or match is None:
            continue  # lights and surfaces that are not object faces
        per_object.setdefault(match["object"], {}).setdefault(int(match["face"]), []).append(surface)
        if match["part"] == "chart":
            charts.add(match["object"])
    baked = []
    for obj_name, faces in per_object.items():
        obj = bpy.data.objects.get(obj_name)
        if obj is not None and obj.type == "SURFACE":
            bake.bake_object(obj, [("nurbs", faces[i]) for i in sorted(faces)])
            baked.append(obj)
            continue
        if obj is not None and obj.type == "MESH" and obj_name in charts:
            bake.bake_object(obj, [("chart", faces[0])])
            baked.append(obj)
            continue
        if obj is None or obj.type != "MESH":
            raise ValueError(f"solution file names object '{obj_name}', which is not a mesh in this scene")
        mesh = obj.data
        if sorted(faces) != list(range(len(mesh.polygons))):
            raise ValueError(f"object '{obj_name}': the solution has {len(faces)} faces, the mesh {len(mesh.polygons)}")
        kinds = {3: "triangle", 4: "quad"}
        bake.bake_object(obj, [(kinds.get(p.loop_total, "ngon"), faces[p.index]) for p in mesh.polygons])
        baked.append(obj)
    return baked
