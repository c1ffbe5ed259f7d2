"""Blender lights and the world -> the solver's emitters: area lights as emitting patches, point and
spot lights as emitting spheres, suns as distant lights, the world as world light (a constant, or a rendered map)."""
from __future__ import annotations

import math

import bpy
import numpy as np

import bsgi

from .errors import ExportError
from . import world_map
from .materials import active_output, linked_node, socket_color, socket_value


def add_light(scene, obj, warnings) -> None:
    """A light object as Cycles shines it (unsupported types are skipped with a warning)."""
    kind = obj.data.type
    if kind == "AREA":
        area_light(scene, obj, warnings)
    elif kind == "POINT":
        point_light(scene, obj, warnings)
    elif kind == "SUN":
        sun_light(scene, obj, warnings)
    elif kind == "SPOT":
        spot_light(scene, obj, warnings)
    else:
        warnings.append(f"light '{obj.name}': {kind.lower()} lights are not supported yet; skipped")


def _warn_light_nodes(obj, warnings):
    light = obj.data
    if getattr(light, "use_nodes", False) and light.node_tree is not None:
        warnings.append(f"light '{obj.name}': its shader nodes are ignored; its colour and power are used")


def area_light(scene, obj, warnings):
    light = obj.data
    if getattr(getattr(light, "cycles", None), "is_portal", False):
        warnings.append(f"light '{obj.name}': a portal emits no light of its own; skipped")
        return
    if getattr(light, "spread", math.pi) < math.pi - 1e-6:
        warnings.append(f"light '{obj.name}': its spread of {math.degrees(light.spread):.0f} degrees is solved as "
                        "180 (a Lambertian emitter)")
    _warn_light_nodes(obj, warnings)
    a = light.size / 2
    b = (light.size_y if light.shape in {"RECTANGLE", "ELLIPSE"} else light.size) / 2
    m = obj.matrix_world
    centre = np.array(m @ _v(0, 0), float)
    # Blender area lights emit along their local -Z: axes / corners ordered so the front is there.
    axis_a, axis_b = np.array(m @ _v(a, 0), float) - centre, np.array(m @ _v(0, -b), float) - centre
    area = np.linalg.norm(np.cross(axis_a, axis_b)) * (math.pi if light.shape in {"DISK", "ELLIPSE"} else 4)
    if not area > 0:
        raise ExportError(f"light '{obj.name}': zero size")
    # Cycles: an area light of power P watts emits radiance P / (pi * A) (checked against a render).
    radiance = light.energy / (math.pi * area)
    emission = [c * radiance for c in light.color]
    if light.shape in {"DISK", "ELLIPSE"}:
        scene.add_disk(obj.name, centre, axis_a, axis_b, albedo=[0, 0, 0], emission=emission, receiver=False, occluder=False)
    else:
        corners = np.array([m @ _v(-a, -b), m @ _v(-a, b), m @ _v(a, b), m @ _v(a, -b)], float)
        scene.add_bilinear_patch(obj.name, corners, albedo=[0, 0, 0], emission=emission, receiver=False, occluder=False)


# A point light of radius 0 is a true point in Cycles; the solver needs an area to integrate.
MIN_POINT_LIGHT_RADIUS = 1e-3


def point_light(scene, obj, warnings):
    """A point light as Cycles has it since 4.0: a sphere of the light's radius emitting uniformly,
    radiance P / (4 pi^2 r^2) (power P spread over the sphere's area 4 pi r^2 as a Lambertian
    emitter, pi L per unit area), solved as an exact NURBS sphere that emits but neither receives
    nor casts shadows (as a light). A spot light is the same sphere with its light limited to a
    cone around the object's -Z axis. Returns the sphere's index in the scene."""
    light = obj.data
    _warn_light_nodes(obj, warnings)
    m = np.array(obj.matrix_world, float)
    radius = light.shadow_soft_size  # the object's scale does not size a point light
    if radius < MIN_POINT_LIGHT_RADIUS:
        warnings.append(f"light '{obj.name}': radius {radius:g} m is solved as a sphere of radius "
                        f"{MIN_POINT_LIGHT_RADIUS:g} m (the solver integrates light over an area)")
        radius = MIN_POINT_LIGHT_RADIUS
    radiance = light.energy / (4 * math.pi**2 * radius**2)
    emission = [c * radiance for c in light.color]
    surface = sphere_surface(obj.name, m[:3, 3], radius)
    return scene.add_surface(surface, albedo=[0, 0, 0], emission=emission, receiver=False, occluder=False)


def _light_z_axis(obj, warnings):
    """The light object's +Z axis in world space (it shines along -Z), or None with a warning when
    the object is scaled to nothing along it."""
    z = np.array(obj.matrix_world, float)[:3, 2]
    if not np.linalg.norm(z) > 0:
        warnings.append(f"light '{obj.name}': scaled to zero, it has no direction; skipped")
        return None
    return z


def spot_light(scene, obj, warnings):
    """A spot light as Cycles has it: the point light's sphere, its emission scaled by
    smoothstep((cos angle - cos(size / 2)) / ((1 - cos(size / 2)) blend)) of the angle between the
    light's -Z axis and the direction it leaves in."""
    light = obj.data
    towards = _light_z_axis(obj, warnings)
    if towards is None:
        return
    m = np.array(obj.matrix_world, float)[:3, :3]
    sx, sy = np.linalg.norm(m[:, 0]), np.linalg.norm(m[:, 1])
    if abs(sx - sy) > 1e-6 * max(sx, sy):
        warnings.append(f"light '{obj.name}': its cone, elliptical from the object's unequal X and Y scale, is "
                        "solved as a circular cone")
    index = point_light(scene, obj, warnings)
    scene.set_spot_cone(index, -towards, light.spot_size, light.spot_blend)


def sun_light(scene, obj, warnings):
    """A sun as Cycles has it: irradiance strength x colour (W/m^2) on a surface facing it, from a
    disc of the light's angular diameter around the object's +Z axis (the light shines along -Z)."""
    light = obj.data
    _warn_light_nodes(obj, warnings)
    towards = _light_z_axis(obj, warnings)
    if towards is None:
        return
    scene.add_distant_light(obj.name, towards, [c * light.energy for c in light.color], light.angle)


def sphere_surface(name: str, centre, radius: float) -> "bsgi.NurbsSurface":
    """An exact sphere as the rational quadratic NURBS surface Blender's NURBS Sphere primitive
    makes: u along a half circle from the lower pole to the upper one, v around the axis (closed),
    front outwards."""
    h = math.sqrt(0.5)
    around = [(-1, 0, 1), (-1, -1, h), (0, -1, 1), (1, -1, h), (1, 0, 1), (1, 1, h), (0, 1, 1), (-1, 1, h)]
    profile = [(0, -1, 1), (1, -1, h), (1, 0, 1), (1, 1, h), (0, 1, 1)]  # (distance from the axis, height, weight)
    points = np.array([(cx * r, cy * r, z, wc * wp) for cx, cy, wc in around for r, z, wp in profile], float)
    points[:, :3] = points[:, :3] * radius + np.asarray(centre, float)
    return bsgi.NurbsSurface(name, points, 5, 8, 3, 3, True, True, True, True, False, True)


def _v(x, y):
    from mathutils import Vector

    return Vector((x, y, 0.0))


def world_light(blender_scene, scene, warnings):
    """The world as the solver's world light, as Cycles shines it on diffuse and glossy surfaces:
    a one-colour background as a constant radiance (colour x strength), any other node tree
    (Environment or Sky Texture, strength, a Mapping node's rotation...) as the equirectangular
    image Cycles renders of it (world_map.render_world)."""
    world = blender_scene.world
    if world is None:
        return
    visibility = world.cycles_visibility
    if not visibility.diffuse and not visibility.glossy:
        return  # Cycles' diffuse and glossy rays do not see it: no light on the surfaces
    if visibility.diffuse != visibility.glossy:
        warnings.append(f"world '{world.name}': visible to {'diffuse' if visibility.diffuse else 'glossy'} rays only; "
                        "solved as lighting every surface")
    color, strength = tuple(world.color), 1.0  # without nodes Cycles shines the world colour
    if world.node_tree is not None and (bpy.app.version >= (5, 0, 0) or world.use_nodes):  # 5.x: always nodes
        output = active_output(world.node_tree, "OUTPUT_WORLD")
        surface = linked_node(output.inputs["Surface"]) if output is not None else None
        if surface is None:
            return
        if surface.type != "BACKGROUND" or any(s.is_linked for s in surface.inputs):
            _world_map(blender_scene, world, scene, warnings)
            return
        color, strength = socket_color(surface, "Color"), socket_value(surface, "Strength", 1.0)
    scene.world_radiance = tuple(c * max(strength, 0.0) for c in color)


def _world_map(blender_scene, world, scene, warnings):
    """A world node tree, rendered by Cycles, as the solver's world map."""
    light_paths = world_map.light_path_nodes(world.node_tree)
    if light_paths:
        names = ", ".join(f"'{n}'" for n in light_paths)
        warnings.append(f"world '{world.name}': Light Path node{'s' if len(light_paths) > 1 else ''} {names} "
                        "cannot be told apart by ray type here: the world's light is taken as camera rays see it")
    settings = getattr(blender_scene, "bsgi", None)
    width = settings.world_map_width if settings is not None else 512
    image = world_map.render_world(world, width)
    if not np.all(np.isfinite(image)):
        raise ExportError(f"world '{world.name}': its node tree gives non-finite radiance (NaN or infinity)")
    scene.world_map = np.maximum(image, 0.0)
