"""Blender scene -> bsgi.Scene: the only place that reads the user's scene for a solve.

Nothing of the user's data is changed here: meshes come from the evaluated depsgraph
(`to_mesh()` on evaluated objects, cleared afterwards), NURBS surfaces are read from their
splines, and materials are the user's even where a bake is shown."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import bpy
import numpy as np
from mathutils import Matrix

import bsgi

from . import charts, tangents

# Blender's look for a surface with no material: a light grey diffuse.
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
GEOMETRY_TYPES = {"MESH", "SURFACE", "CURVE", "FONT", "META"}
# Objects solved through their evaluated mesh (to_mesh) but not baked, by the name users know.
EVALUATED_ONLY = {"CURVE": "curve", "FONT": "text", "META": "metaball"}


class ExportError(ValueError):
    """The scene cannot be solved as it is; the message names the object and the problem."""


@dataclass
class ExportedObject:
    """One Blender object's faces (in polygon order) or NURBS splines, as scene surfaces."""

    name: str
    polygon_count: int
    # Per polygon: ("quad" | "triangle" | "ngon", first scene index, number of patches);
    # for a SURFACE object per spline: ("nurbs", scene index, 1).
    patches: list = field(default_factory=list)
    kind: str = "mesh"  # "mesh" | "nurbs" | "chart" (one MeshChart: patches = [("chart", index, 1)])
    chart_uvs: object = None  # a chart's UV coordinates per loop of the user's mesh, (loops, 2), for the bake
    # Why the object is solved (it casts shadows and reflects light) but cannot be baked, or "".
    not_baked: str = ""


@dataclass
class Export:
    scene: bsgi.Scene
    objects: list  # of ExportedObject, the bake targets
    warnings: list


@dataclass
class SurfaceMaterial:
    """What the solver needs of a material: a diffuse albedo, a glossy part, emission."""

    albedo: tuple = (0.0, 0.0, 0.0)  # Lambertian reflectance
    specular: tuple = (0.0, 0.0, 0.0)  # glossy (microfacet) reflectance
    roughness: float = 0.5
    # Anisotropic GGX as Cycles sets it up: alpha_x = roughness^2 * stretch along the tangent,
    # alpha_y = roughness^2 / stretch; the tangent is turned by `rotation` radians about the normal.
    stretch: float = 1.0
    rotation: float = 0.0
    transmission: float = 0.0
    ior: float = 1.5
    emission: tuple = (0.0, 0.0, 0.0)  # radiance

    def scaled(self, k: float) -> "SurfaceMaterial":
        return SurfaceMaterial(_scale(self.albedo, k), _scale(self.specular, k), self.roughness, self.stretch,
                               self.rotation, self.transmission * k, self.ior, _scale(self.emission, k))

    def plus(self, other: "SurfaceMaterial") -> "SurfaceMaterial":
        """Sum of two shaders (Add Shader, the two halves of a Mix Shader)."""
        glossy = sum(self.specular) >= sum(other.specular)
        dominant = self if glossy else other
        return SurfaceMaterial(_add(self.albedo, other.albedo), _add(self.specular, other.specular), dominant.roughness,
                               dominant.stretch, dominant.rotation, self.transmission + other.transmission, dominant.ior,
                               _add(self.emission, other.emission))


def _scale(c, k):
    return tuple(x * k for x in c)


def _add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def _socket_color(node, name, default=(0.0, 0.0, 0.0)):
    sock = node.inputs.get(name)
    if sock is None:
        return default
    value = sock.default_value
    return tuple(value[:3]) if hasattr(value, "__len__") else (float(value),) * 3


def _socket_value(node, name, default=0.0):
    sock = node.inputs.get(name)
    return float(sock.default_value) if sock is not None else default


def _shader(node, material, warnings, depth=0) -> SurfaceMaterial:
    """The material description of a shader node (recursing through Mix and Add shaders)."""
    if node is None or depth > 16:
        return SurfaceMaterial()
    linked = [s.name for s in node.inputs if s.is_linked and s.type != "SHADER" and s.name not in {"Normal", "Tangent"}]
    if linked:
        warnings.append(f"material '{material.name}': {node.name} inputs {', '.join(linked)} are driven by nodes; "
                        "their own values are used instead")
    kind = node.type
    if kind == "BSDF_DIFFUSE":
        return SurfaceMaterial(albedo=_socket_color(node, "Color"))
    if kind == "EMISSION":
        return SurfaceMaterial(emission=_scale(_socket_color(node, "Color"), _socket_value(node, "Strength", 1.0)))
    if getattr(node, "distribution", "GGX") in {"BECKMANN", "ASHIKHMIN_SHIRLEY"}:
        warnings.append(f"material '{material.name}': {node.name}'s {node.distribution.replace('_', '-').title()} "
                        "microfacet distribution is solved as GGX")
    if kind in {"BSDF_GLOSSY", "BSDF_ANISOTROPIC"}:
        # Cycles' Glossy BSDF: anisotropy a in [-0.99, 0.99] narrows the lobe along the tangent
        # by (1 - a) for a > 0 and widens it by 1 / (1 + a) for a < 0 (the other axis inversely).
        a = min(max(_socket_value(node, "Anisotropy", 0.0), -0.99), 0.99)
        stretch = 1 / (1 + a) if a < 0 else 1 - a
        rotation = _socket_value(node, "Rotation") if a else 0.0
        _warn_tangent(node, material, warnings, a)
        return SurfaceMaterial(specular=_socket_color(node, "Color"), roughness=_socket_value(node, "Roughness", 0.5),
                               stretch=stretch, rotation=2 * math.pi * rotation)
    if kind == "BSDF_GLASS":
        return SurfaceMaterial(transmission=1.0, roughness=_socket_value(node, "Roughness", 0.0),
                               ior=_socket_value(node, "IOR", 1.5))
    if kind == "BSDF_PRINCIPLED":
        base = _socket_color(node, "Base Color")
        metallic = _socket_value(node, "Metallic")
        # Metals do not transmit: Blender's metallic part covers the transmission.
        transmission = _socket_value(node, "Transmission Weight", _socket_value(node, "Transmission")) * (1 - metallic)
        specular_level = _socket_value(node, "Specular IOR Level", 0.5)
        ior = _socket_value(node, "IOR", 1.5)
        # Dielectric specular reflectance at normal incidence, ((ior-1)/(ior+1))^2, scaled by
        # the specular level (0.5 is the physical value); metals reflect their base colour.
        f0 = ((ior - 1) / (ior + 1)) ** 2 * 2 * specular_level
        diffuse_weight = 1 - metallic - transmission
        specular = tuple(metallic * c + (1 - metallic) * f0 for c in base)
        emission = _scale(_socket_color(node, "Emission Color"), _socket_value(node, "Emission Strength"))
        layers = [label for label, name in (("subsurface", "Subsurface Weight"), ("coat", "Coat Weight"),
                                            ("sheen", "Sheen Weight"), ("thin film", "Thin Film Thickness"))
                  if _socket_value(node, name) > 0]
        if _socket_value(node, "Alpha", 1.0) < 1:
            layers.append("alpha (transparency)")
        if layers:
            warnings.append(f"material '{material.name}': {node.name}'s {', '.join(layers)} "
                            f"{'is' if len(layers) == 1 else 'are'} not solved; the base layers are")
        # Cycles' Principled BSDF: anisotropic a in [0, 1] widens the lobe along the tangent by
        # 1 / sqrt(1 - 0.9 a) and narrows it across by the same factor.
        a = min(max(_socket_value(node, "Anisotropic"), 0.0), 1.0)
        rotation = _socket_value(node, "Anisotropic Rotation") if a else 0.0
        _warn_tangent(node, material, warnings, a)
        return SurfaceMaterial(albedo=_scale(base, diffuse_weight), specular=specular,
                               roughness=_socket_value(node, "Roughness", 0.5), stretch=1 / math.sqrt(1 - 0.9 * a),
                               rotation=2 * math.pi * rotation, transmission=transmission, ior=ior, emission=emission)
    if kind == "ADD_SHADER":
        return _shader(_from(node.inputs[0]), material, warnings, depth + 1).plus(
            _shader(_from(node.inputs[1]), material, warnings, depth + 1))
    if kind == "MIX_SHADER":
        fac = min(max(_socket_value(node, "Fac", 0.5), 0.0), 1.0)
        return _shader(_from(node.inputs[1]), material, warnings, depth + 1).scaled(1 - fac).plus(
            _shader(_from(node.inputs[2]), material, warnings, depth + 1).scaled(fac))
    warnings.append(f"material '{material.name}': shader '{node.bl_idname}' is approximated by the material's "
                    "viewport colour")
    return SurfaceMaterial(albedo=tuple(material.diffuse_color[:3]))


def _warn_tangent(node, material, warnings, anisotropy):
    """The core's anisotropy follows the surface's own u direction: a Tangent input is not read."""
    tangent = node.inputs.get("Tangent")
    if anisotropy and tangent is not None and tangent.is_linked:
        warnings.append(f"material '{material.name}': {node.name}'s Tangent input is ignored; the anisotropy "
                        "follows each surface's u direction (ds/du), turned by its rotation")


def _active_output(tree, kind):
    """The output node of that type Blender renders with (the active one, else the first)."""
    outputs = [n for n in tree.nodes if n.type == kind]
    return next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)


def _from(socket):
    return socket.links[0].from_node if socket.is_linked else None


def describe_material(material, warnings) -> SurfaceMaterial:
    """A Blender material as the solver sees it."""
    if material is None:
        return SurfaceMaterial(albedo=DEFAULT_ALBEDO)
    tree = material.node_tree
    output = None
    if tree is not None:
        output = _active_output(tree, "OUTPUT_MATERIAL")
    if output is None or not output.inputs["Surface"].is_linked:
        return SurfaceMaterial(albedo=tuple(material.diffuse_color[:3]))
    return _shader(_from(output.inputs["Surface"]), material, warnings)


# The narrowest GGX lobe the angular splines resolve: with the default 24 angular coefficients
# across the disc a lobe needs a width of about 0.1 rad, i.e. alpha = roughness^2 >= 0.04.
# Smoother materials (mirrors, clear glass) are solved at this roughness; the core refuses
# perfectly smooth BSDFs, which have no spline representation.
MIN_ROUGHNESS = 0.2


@dataclass
class SolverMaterial:
    """What the core is given for one material: Lambertian albedo, or a BSDF, and emission.
    kind and the parameters are kept beside the bsgi BSDF, which does not expose them."""

    albedo: tuple
    emission: tuple
    kind: str = "lambert"  # "lambert" | "ggx" | "rough_dielectric"
    alpha: float = 0.0  # roughness^2 (clamped), the isotropic GGX alpha
    alpha_x: float = 0.0  # "ggx": along the tangent ds/du turned by `rotation` radians about the normal
    alpha_y: float = 0.0
    rotation: float = 0.0
    f0: tuple = (0.0, 0.0, 0.0)
    eta: float = 1.0
    bsdf: object = None  # bsgi.Bsdf, None for Lambert (the scene then uses albedo)


def _alpha(name: str, roughness: float, warnings) -> float:
    """Blender's alpha = roughness^2, the roughness clamped to what the splines resolve."""
    if roughness < MIN_ROUGHNESS:
        warnings.append(f"material '{name}': roughness {roughness:.2f} is solved as {MIN_ROUGHNESS} (mirror-like "
                        "reflection and clear glass are not representable by the radiance splines)")
        roughness = MIN_ROUGHNESS
    return roughness**2


def _anisotropic_alphas(name: str, described: SurfaceMaterial, alpha: float, warnings):
    """Blender's (alpha_x, alpha_y) from roughness^2 and the stretch, each clamped to what the
    splines resolve."""
    if described.stretch == 1:
        return alpha, alpha
    r = min(max(described.roughness, 0.0), 1.0)
    alphas = (r * r * described.stretch, r * r / described.stretch)
    lowest = MIN_ROUGHNESS**2
    if min(alphas) < lowest:
        warnings.append(f"material '{name}': its anisotropic lobe's narrow axis (alpha {min(alphas):.3f}) is solved "
                        f"as alpha {lowest:.2f}, the narrowest the radiance splines resolve")
    return tuple(max(a, lowest) for a in alphas)


def solver_material(material, described: SurfaceMaterial, warnings) -> SolverMaterial:
    """The part of the described material that dominates its reflected energy, as the core's
    BSDF: Lambert (diffuse), GGX reflection (metals, glossy coatings) or a rough dielectric
    (transmission). The core has one BSDF per surface, so the other parts are approximated and
    named in a warning."""
    name = material.name if material is not None else "(none)"
    diffuse = sum(described.albedo) / 3
    glossy = sum(described.specular) / 3
    transmission = described.transmission
    if transmission > max(diffuse, glossy):
        if diffuse + glossy > 0.05:
            warnings.append(f"material '{name}': solved as rough glass; its diffuse and metallic parts are dropped")
        eta = max(described.ior, 1.0 + 1e-3)
        alpha = _alpha(name, described.roughness, warnings)
        return SolverMaterial((0, 0, 0), described.emission, "rough_dielectric", alpha=alpha, eta=eta,
                              bsdf=bsgi.RoughDielectric(eta, alpha, alpha))
    if transmission > 0:
        warnings.append(f"material '{name}': its transmission is weaker than its reflection; solved as opaque")
    if glossy > diffuse:
        if diffuse > 0.05:
            warnings.append(f"material '{name}': solved as glossy (GGX); its diffuse part is dropped")
        f0 = tuple(min(1.0, max(0.0, c)) for c in described.specular)
        alpha = _alpha(name, described.roughness, warnings)
        ax, ay = _anisotropic_alphas(name, described, alpha, warnings)
        return SolverMaterial((0, 0, 0), described.emission, "ggx", alpha=alpha, alpha_x=ax, alpha_y=ay,
                              rotation=described.rotation, f0=f0,
                              bsdf=bsgi.GgxReflection(ax, ay, f0, rotation=described.rotation))
    if glossy > 0.05 or (glossy > 0.01 and described.roughness < 0.3):
        warnings.append(f"material '{name}': solved as diffuse; its specular highlights (roughness "
                        f"{described.roughness:.2f}) are not solved, their energy is added to the albedo")
    albedo = tuple(min(1.0, max(0.0, a + s)) for a, s in zip(described.albedo, described.specular))
    return SolverMaterial(albedo, described.emission)


def _warn_light_nodes(obj, warnings):
    light = obj.data
    if getattr(light, "use_nodes", False) and light.node_tree is not None:
        warnings.append(f"light '{obj.name}': its shader nodes are ignored; its colour and power are used")


def _area_light(scene, obj, warnings):
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


def _point_light(scene, obj, warnings):
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


def _spot_light(scene, obj, warnings):
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
    index = _point_light(scene, obj, warnings)
    scene.set_spot_cone(index, -towards, light.spot_size, light.spot_blend)


def _sun_light(scene, obj, warnings):
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


def surface_options(obj) -> dict:
    """The object's per-surface solver options (Object properties), as the core's keywords. Read
    from the original object: the evaluated copy's may predate the user's last change."""
    settings = getattr(obj.original, "bsgi", None)
    if settings is None:
        return {}
    return {"representation": settings.representation.lower(), "spatial_coeffs": settings.spatial_coeffs,
            "angular_coeffs": settings.angular_coeffs}


def _user_slots(obj) -> list:
    """The user's material per slot (at least one slot, None for empty)."""
    from .bake import is_baked, user_materials  # the bake's record of the slots, not the baked materials

    # The evaluated object's slots otherwise: a geometry-nodes instance's materials come with its
    # instanced mesh, its original object is the instancer.
    original = obj.original
    return (user_materials(original) if is_baked(original) else [s.material for s in obj.material_slots]) or [None]


def _slot_materials(obj, warnings) -> list:
    return [solver_material(m, describe_material(m, warnings), warnings) for m in _user_slots(obj)]


def _material_keywords(material: SolverMaterial, options: dict) -> dict:
    return dict(albedo=material.albedo, emission=material.emission, bsdf=material.bsdf, **options)


@dataclass
class _Materials:
    """An object's slot materials as the core takes them, and where Blender's default tangent
    points on it (for anisotropic ones)."""

    solver: list  # of SolverMaterial
    keywords: list  # of dict, for Scene.add_surface
    radial: tangents.RadialTangent
    label: str
    spread: float = 0.0  # the largest turn of Blender's tangent against ds/du on one surface, radians

    def for_surface(self, slot: int, surface) -> dict:
        """The keywords of the slot's material; an anisotropic GGX turned so that its tangent
        follows Blender's on this surface (ds/du turned by the mean angle between them)."""
        slot = min(slot, len(self.solver) - 1)
        material, keywords = self.solver[slot], self.keywords[slot]
        if material.kind != "ggx" or material.alpha_x == material.alpha_y:
            return keywords
        angle, spread = tangents.surface_rotation(self.radial, surface)
        self.spread = max(self.spread, spread)
        bsdf = bsgi.GgxReflection(material.alpha_x, material.alpha_y, material.f0, rotation=material.rotation + angle)
        return {**keywords, "bsdf": bsdf}

    def warn(self, warnings) -> None:
        if math.degrees(self.spread) > tangents.MAX_SPREAD_DEGREES:
            warnings.append(f"object '{self.label}': Blender's tangent for its anisotropic material turns by up to "
                            f"{math.degrees(self.spread):.0f} degrees against the surfaces' own u direction; the "
                            "solver turns the lobe by one mean angle per surface (UV charts and NURBS surfaces "
                            "follow a smooth tangent better than single faces)")


def _materials(obj, matrix: Matrix, warnings, label: str, options: dict) -> _Materials:
    solver = _slot_materials(obj, warnings)
    radial = tangents.RadialTangent(np.array(matrix, float), [tuple(c) for c in obj.bound_box])
    return _Materials(solver, [_material_keywords(m, options) for m in solver], radial, label)


def _add_mesh_object(scene, obj, mesh, matrix: Matrix, warnings, label: str | None = None,
                     pending_charts: list | None = None) -> ExportedObject:
    co = np.empty(len(mesh.vertices) * 3, np.float64)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    m = np.array(matrix, float)
    world = co @ m[:3, :3].T + m[:3, 3]
    modified = label is None and obj.type == "MESH" and pending_charts is not None and _modifiers_change_faces(obj, mesh)
    label = label or obj.name
    materials = _materials(obj, matrix, warnings, label, surface_options(obj))
    exported = ExportedObject(obj.name, len(mesh.polygons))
    if modified:
        # The user's mesh shows the evaluated faces only through a UV map the modifiers carry
        # to them: one chart, or no bake.
        problem = _chart_refusal(obj, mesh, _user_slots(obj))
        if not problem:
            pending_charts.append(_chart_job(exported, mesh, world, materials, label, base=obj.original))
            return exported
        exported.not_baked = f"its modifiers ({modifier_names(obj)}) change its faces and {problem}; {APPLY_ADVICE}"
    elif pending_charts is not None and _wants_chart(obj, mesh, _user_slots(obj), label, warnings):
        pending_charts.append(_chart_job(exported, mesh, world, materials, label))
        return exported
    ngon_tris = {}
    if any(p.loop_total > 4 for p in mesh.polygons):
        mesh.calc_loop_triangles()
        for tri in mesh.loop_triangles:
            ngon_tris.setdefault(tri.polygon_index, []).append(tuple(tri.vertices))
    for poly in mesh.polygons:
        name = f"{label}: face {poly.index}"
        verts = list(poly.vertices)
        first = len(scene)
        if len(verts) <= 4:
            pieces, kind = [(name, verts)], "quad" if len(verts) == 4 else "triangle"
        else:
            pieces, kind = [(f"{name} triangle {k}", list(tri)) for k, tri in enumerate(ngon_tris[poly.index])], "ngon"
        try:
            for piece, corners in pieces:
                surface = (bsgi.BilinearPatch if len(corners) == 4 else bsgi.TrianglePatch)(piece, world[corners])
                scene.add_surface(surface, **materials.for_surface(poly.material_index, surface))
        except ValueError as error:
            raise ExportError(str(error)) from None
        exported.patches.append((kind, first, len(pieces)))
    materials.warn(warnings)
    return exported


def chart_min_faces(scene) -> int:
    settings = getattr(scene, "bsgi", None)
    return settings.chart_min_faces if settings is not None else 0


APPLY_ADVICE = "apply the modifiers (Object > Apply) to bake it"


def _modifiers_change_faces(obj, mesh) -> bool:
    """Whether the evaluated mesh has other faces than the user's mesh (Subdivision Surface,
    Mirror, Array, Solidify, Bevel...): then a bake per face of the user's mesh cannot show it."""
    data = obj.original.data
    return len(data.polygons) != len(mesh.polygons) or len(data.loops) != len(mesh.loops)


def modifier_names(obj) -> str:
    return ", ".join(m.name for m in obj.original.modifiers if m.show_viewport) or "none shown"


def _chart_refusal(obj, mesh, slots: list) -> str:
    """Why a mesh whose modifiers change its faces cannot be one chart, or ''."""
    if getattr(getattr(obj.original, "bsgi", None), "mesh_surfaces", "AUTO") == "FACES":
        return "its Mesh Surfaces setting is Per Face"
    indices = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", indices)
    if len({slots[min(int(i), len(slots) - 1)] for i in np.unique(indices)}) > 1:
        return "it has several materials (a UV chart has one)"
    return ""


def _wants_chart(obj, mesh, slots: list, label: str, warnings) -> bool:
    """From the scene's face count (0: never) a mesh of one material becomes a UV chart, unless
    the object says otherwise; a chart is one surface with one BSDF, so a mesh of several
    materials stays per face."""
    choice = getattr(getattr(obj.original, "bsgi", None), "mesh_surfaces", "AUTO")
    threshold = chart_min_faces(bpy.context.scene)
    if choice == "FACES" or (choice == "AUTO" and (not threshold or len(mesh.polygons) < threshold)):
        return False
    indices = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", indices)
    if len({slots[min(int(i), len(slots) - 1)] for i in np.unique(indices)}) > 1:
        warnings.append(f"object '{label}': {len(mesh.polygons)} faces of several materials are solved per face, "
                        "not as one UV chart (a chart has one material)")
        return False
    return True


@dataclass
class _ChartJob:
    """What a chart needs, read while the depsgraph is iterated; built after (a generated UV map
    needs a temporary object in the scene, which would disturb the iteration)."""

    exported: ExportedObject
    label: str
    world: np.ndarray  # (V, 3) world positions
    triangles: np.ndarray  # (T, 3) vertex indices
    triangle_loops: np.ndarray  # (T, 3) loop indices
    polygons: list  # vertex index tuples, for a generated UV map
    uvs: np.ndarray | None  # per loop, from a suitable UV map of the user's, or None
    materials: _Materials
    slot: int  # the chart's material (of its first face)
    uv_reasons: list
    # A mesh whose modifiers change its faces: the user's object, whose own mesh's loops get the
    # bake's UVs (the modifiers carry them to the evaluated faces).
    base: object = None
    base_uvs: np.ndarray | None = None  # per loop of the user's mesh, for the bake
    loop_count: int = 0  # of the evaluated mesh


def _chart_job(exported, mesh, world, materials, label, base=None) -> _ChartJob:
    triangles, loops = charts.loop_triangles(mesh)
    name, found = charts.suitable_uv_map(mesh, loops)
    if base is not None and name is not None and base.data.uv_layers.get(name) is None:
        # Made by the modifiers (geometry nodes): the bake cannot give it to the user's mesh.
        name, found = None, [f"UV map '{name}' is made by its modifiers"]
    indices = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", indices)
    polygons = [tuple(p.vertices) for p in mesh.polygons] if name is None else []
    # The user's UV map as their own mesh holds it: the modifiers carry it to the faces solved.
    base_uvs = charts.layer_uvs(base.data, name) if base is not None and name is not None else None
    return _ChartJob(exported, label, world, triangles, loops, polygons, found if name is not None else None,
                     materials, int(indices[0]), [] if name is not None else found, base, base_uvs, len(mesh.loops))


def _build_chart(scene, job: _ChartJob, warnings) -> None:
    uvs = job.uvs
    if uvs is None and job.base is not None:
        uvs = _carried_generated_uvs(job, warnings)
        if uvs is None:  # not baked: any chart of the evaluated faces will do for the solve
            uvs = charts.generated_uvs(job.world, job.polygons, job.label)
    if uvs is None:
        uvs = charts.generated_uvs(job.world, job.polygons, job.label)
        why = "; ".join(job.uv_reasons) or "it has no UV map"
        if not job.exported.not_baked:  # a UV map only the solve sees needs no word
            warnings.append(f"object '{job.label}': solved as one UV chart over a UV map generated by Smart UV "
                            f"Project (no UV map of its own is a chart: {why}); the object's own UV maps are unchanged")
        problem = charts.chart_problem(uvs[job.triangle_loops])
        if problem:
            raise ExportError(f"object '{job.label}': the generated UV map is not a chart ({problem}); set its "
                              "Mesh Surfaces (Object Properties > B-spline GI) to Per Face")
    first = len(scene)
    try:
        chart = bsgi.MeshChart(f"{job.label}: chart 0", job.world, job.triangles, uvs[job.triangle_loops])
        scene.add_surface(chart, **job.materials.for_surface(job.slot, chart))
    except ValueError as error:
        raise ExportError(str(error)) from None
    job.materials.warn(warnings)
    job.exported.kind = "chart"
    bake_uvs = uvs if job.base is None else job.base_uvs
    job.exported.chart_uvs = None if job.exported.not_baked else bake_uvs.astype(np.float32)
    job.exported.patches = [("chart", first, 1)]


def _carried_generated_uvs(job: _ChartJob, warnings):
    """For a mesh whose modifiers change its faces and carry none of its UV maps as a chart: a
    UV map generated on a copy of the user's mesh, carried by the user's modifier stack (on a
    temporary object) to the evaluated faces. Returns the evaluated faces' UVs (the user's mesh
    gets the generated ones only at the bake), or None, and then the object is not baked."""
    from .bake import UV_NAME

    data = job.base.data
    co = np.empty(len(data.vertices) * 3, np.float64)
    data.vertices.foreach_get("co", co)
    generated = charts.generated_uvs(co.reshape(-1, 3), [tuple(p.vertices) for p in data.polygons], job.label)
    # The map as generated, then squeezed into the left or the lower half of the UV square: a
    # modifier that mirrors or offsets its copies' UVs (Mirror's Mirror U / V, Array's UV offsets)
    # then lays the copies in the other half.
    problem = ""
    for scale in ((1.0, 1.0), (0.5, 1.0), (1.0, 0.5)):
        base_uvs = generated * scale
        carried = charts.carried_uvs(job.base, UV_NAME, base_uvs)
        if carried is None or len(carried) != job.loop_count:
            problem = "they do not carry UV maps"
            break
        problem = charts.chart_problem(carried[job.triangle_loops])
        if not problem:
            break
    why = "; ".join(job.uv_reasons) or "it has no UV map"
    if problem:
        job.exported.not_baked = (f"its modifiers ({modifier_names(job.base)}) change its faces, and neither its own "
                                  f"UV maps ({why}) nor one generated by Smart UV Project before them are a chart "
                                  f"after them ({problem}), even in half the UV square; {APPLY_ADVICE}, or let "
                                  "their copies' UVs move (Mirror U / V, Array's UV offsets)")
        return None
    warnings.append(f"object '{job.label}': solved as one UV chart over a UV map generated by Smart UV Project and "
                    f"carried by its modifiers (no UV map of its own is a chart after them: {why}); the bake adds it "
                    f"as the UV map '{UV_NAME}', the object's own UV maps are unchanged")
    job.base_uvs = base_uvs
    return carried


def nurbs_surface(name: str, spline, matrix: Matrix) -> "bsgi.NurbsSurface":
    """A Blender SURFACE spline as the exact rational surface, control points in world space.
    Points are Cartesian with the weight beside them, so the affine transform commutes with the
    rational combination: transforming the points transforms the surface."""
    co = np.empty(len(spline.points) * 4, np.float64)
    spline.points.foreach_get("co", co)
    co = co.reshape(-1, 4)
    m = np.array(matrix, float)
    co[:, :3] = co[:, :3] @ m[:3, :3].T + m[:3, 3]
    return bsgi.NurbsSurface(name, co, spline.point_count_u, spline.point_count_v, spline.order_u, spline.order_v,
                             spline.use_endpoint_u, spline.use_endpoint_v, spline.use_bezier_u, spline.use_bezier_v,
                             spline.use_cyclic_u, spline.use_cyclic_v)


def _nurbs_problem(spline) -> str:
    """Why Blender draws nothing for a spline (its knot rule cannot use the point counts), or ''."""
    return (bsgi.blender_nurbs_problem(spline.point_count_u, spline.order_u, spline.use_endpoint_u, spline.use_bezier_u,
                                       spline.use_cyclic_u)
            or bsgi.blender_nurbs_problem(spline.point_count_v, spline.order_v, spline.use_endpoint_v,
                                          spline.use_bezier_v, spline.use_cyclic_v))


def baked_splines(obj) -> list:
    """The splines of a SURFACE object that are solved and baked: NURBS ones Blender draws."""
    return [s for s in obj.data.splines if s.type == "NURBS" and not _nurbs_problem(s)]


def _add_nurbs_object(scene, obj, matrix: Matrix, warnings, label: str | None = None) -> ExportedObject | None:
    """One exact NURBS surface per spline of a SURFACE object (not its tessellation)."""
    original = obj.original
    label = label or obj.name
    if original.modifiers:
        warnings.append(f"object '{obj.name}': modifiers of NURBS surfaces are ignored (the splines are solved exactly)")
    materials = _materials(original, matrix, warnings, label, surface_options(obj))
    exported = ExportedObject(obj.name, 0, kind="nurbs")
    from .bake import user_spline_material_index

    drawn = baked_splines(original)
    for k, spline in enumerate(original.data.splines):
        if spline.type != "NURBS":
            continue
        if spline not in drawn:
            warnings.append(f"object '{obj.name}': spline {k} is skipped, Blender draws nothing for it "
                            f"({_nurbs_problem(spline)})")
            continue
        first = len(scene)
        index = user_spline_material_index(original, k)
        try:
            surface = nurbs_surface(f"{label}: spline {k}", spline, matrix)
            scene.add_surface(surface, **materials.for_surface(index, surface))
        except ValueError as error:
            raise ExportError(str(error)) from None
        exported.patches.append(("nurbs", first, 1))
    materials.warn(warnings)
    return exported if exported.patches else None


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
            if obj.data.type == "AREA":
                _area_light(scene, obj, warnings)
            elif obj.data.type == "POINT":
                _point_light(scene, obj, warnings)
            elif obj.data.type == "SUN":
                _sun_light(scene, obj, warnings)
            elif obj.data.type == "SPOT":
                _spot_light(scene, obj, warnings)
            else:
                warnings.append(f"light '{obj.name}': {obj.data.type.lower()} lights are not supported yet; skipped")
            continue
        if obj.type not in GEOMETRY_TYPES:
            continue
        if _own_geometry(inst) or not inst.show_self:  # show_self: e.g. a particle emitter set not to show
            continue
        label = None
        if inst.is_instance:
            key = (obj.name, inst.parent.name if inst.parent is not None else "")
            label = f"{obj.name} (instance {instances.get(key, 0)} of '{key[1]}')"
        exported = _add_object(scene, obj, inst.matrix_world, warnings, label, pending_charts)
        if exported is None:
            continue
        if inst.is_instance:
            instances[key] = instances.get(key, 0) + 1
        else:
            if obj.type in EVALUATED_ONLY:
                exported.not_baked = (f"{EVALUATED_ONLY[obj.type]} objects are meshes only as Blender evaluates "
                                      "them, and a bake needs a mesh of its own to hold its UV map; convert it to a "
                                      "mesh (Object > Convert > Mesh) to bake it")
            objects.append(exported)
    for job in pending_charts:
        _build_chart(scene, job, warnings)
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
    _world_light(depsgraph.scene, scene, warnings)
    return Export(scene, objects, list(dict.fromkeys(warnings)))


def _own_geometry(inst) -> bool:
    """Whether an instance is the evaluated mesh of a curve, surface, text or metaball object,
    which Blender lists beside the object itself (also inside collection instances): the object
    is exported already. (Geometry-nodes instances made by such an object look the same and are
    skipped too.)"""
    obj = inst.object
    return inst.is_instance and obj.type == "MESH" and obj.original.type in {"SURFACE", "CURVE", "FONT", "META"}


def _add_object(scene, obj, matrix: Matrix, warnings, label: str | None, pending_charts: list) -> ExportedObject | None:
    """One evaluated geometry object (a real object or an instance) at its world matrix."""
    if obj.type == "SURFACE":
        return _add_nurbs_object(scene, obj, matrix, warnings, label)
    mesh = obj.to_mesh()
    try:
        if mesh is None or len(mesh.polygons) == 0:
            return None
        return _add_mesh_object(scene, obj, mesh, matrix, warnings, label, pending_charts)
    finally:
        obj.to_mesh_clear()


def _world_light(blender_scene, scene, warnings):
    """The world's background, when it is one colour, as the solver's world light: radiance
    colour x strength from every direction no surface blocks (as Cycles shines it)."""
    world = blender_scene.world
    if world is None:
        return
    color, strength = tuple(world.color), 1.0  # without nodes Cycles shines the world colour
    if world.node_tree is not None and (bpy.app.version >= (5, 0, 0) or world.use_nodes):  # 5.x: always nodes
        output = _active_output(world.node_tree, "OUTPUT_WORLD")
        background = _from(output.inputs["Surface"]) if output is not None else None
        if background is None:
            return
        if background.type != "BACKGROUND" or any(s.is_linked for s in background.inputs):
            warnings.append(f"world '{world.name}': only a constant background (one colour, no texture or sky) "
                            "can be solved; its light is ignored")
            return
        color, strength = _socket_color(background, "Color"), _socket_value(background, "Strength", 1.0)
    scene.world_radiance = _scale(color, max(strength, 0.0))
