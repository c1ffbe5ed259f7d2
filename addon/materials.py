"""Blender materials -> what the solver is given: a node tree's shaders as a described material
(SurfaceMaterial), and the one BSDF the core solves for it (SolverMaterial), per object slot.
Also the node-tree helpers the world's export shares. No solve state here."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mathutils import Matrix

import bsgi

from . import tangents
from .user_materials import is_baked, user_materials

# Blender's look for a surface with no material: a light grey diffuse.
DEFAULT_ALBEDO = (0.8, 0.8, 0.8)


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


def socket_color(node, name, default=(0.0, 0.0, 0.0)):
    sock = node.inputs.get(name)
    if sock is None:
        return default
    value = sock.default_value
    return tuple(value[:3]) if hasattr(value, "__len__") else (float(value),) * 3


def socket_value(node, name, default=0.0):
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
        return SurfaceMaterial(albedo=socket_color(node, "Color"))
    if kind == "EMISSION":
        return SurfaceMaterial(emission=_scale(socket_color(node, "Color"), socket_value(node, "Strength", 1.0)))
    if getattr(node, "distribution", "GGX") in {"BECKMANN", "ASHIKHMIN_SHIRLEY"}:
        warnings.append(f"material '{material.name}': {node.name}'s {node.distribution.replace('_', '-').title()} "
                        "microfacet distribution is solved as GGX")
    if kind in {"BSDF_GLOSSY", "BSDF_ANISOTROPIC"}:
        # Cycles' Glossy BSDF: anisotropy a in [-0.99, 0.99] narrows the lobe along the tangent
        # by (1 - a) for a > 0 and widens it by 1 / (1 + a) for a < 0 (the other axis inversely).
        a = min(max(socket_value(node, "Anisotropy", 0.0), -0.99), 0.99)
        stretch = 1 / (1 + a) if a < 0 else 1 - a
        rotation = socket_value(node, "Rotation") if a else 0.0
        _warn_tangent(node, material, warnings, a)
        return SurfaceMaterial(specular=socket_color(node, "Color"), roughness=socket_value(node, "Roughness", 0.5),
                               stretch=stretch, rotation=2 * math.pi * rotation)
    if kind == "BSDF_GLASS":
        return SurfaceMaterial(transmission=1.0, roughness=socket_value(node, "Roughness", 0.0),
                               ior=socket_value(node, "IOR", 1.5))
    if kind == "BSDF_PRINCIPLED":
        base = socket_color(node, "Base Color")
        metallic = socket_value(node, "Metallic")
        # Metals do not transmit: Blender's metallic part covers the transmission.
        transmission = socket_value(node, "Transmission Weight", socket_value(node, "Transmission")) * (1 - metallic)
        specular_level = socket_value(node, "Specular IOR Level", 0.5)
        ior = socket_value(node, "IOR", 1.5)
        # Dielectric specular reflectance at normal incidence, ((ior-1)/(ior+1))^2, scaled by
        # the specular level (0.5 is the physical value); metals reflect their base colour.
        f0 = ((ior - 1) / (ior + 1)) ** 2 * 2 * specular_level
        diffuse_weight = 1 - metallic - transmission
        specular = tuple(metallic * c + (1 - metallic) * f0 for c in base)
        emission = _scale(socket_color(node, "Emission Color"), socket_value(node, "Emission Strength"))
        layers = [label for label, name in (("subsurface", "Subsurface Weight"), ("coat", "Coat Weight"),
                                            ("sheen", "Sheen Weight"), ("thin film", "Thin Film Thickness"))
                  if socket_value(node, name) > 0]
        if socket_value(node, "Alpha", 1.0) < 1:
            layers.append("alpha (transparency)")
        if layers:
            warnings.append(f"material '{material.name}': {node.name}'s {', '.join(layers)} "
                            f"{'is' if len(layers) == 1 else 'are'} not solved; the base layers are")
        # Cycles' Principled BSDF: anisotropic a in [0, 1] widens the lobe along the tangent by
        # 1 / sqrt(1 - 0.9 a) and narrows it across by the same factor.
        a = min(max(socket_value(node, "Anisotropic"), 0.0), 1.0)
        rotation = socket_value(node, "Anisotropic Rotation") if a else 0.0
        _warn_tangent(node, material, warnings, a)
        return SurfaceMaterial(albedo=_scale(base, diffuse_weight), specular=specular,
                               roughness=socket_value(node, "Roughness", 0.5), stretch=1 / math.sqrt(1 - 0.9 * a),
                               rotation=2 * math.pi * rotation, transmission=transmission, ior=ior, emission=emission)
    if kind == "ADD_SHADER":
        return _shader(linked_node(node.inputs[0]), material, warnings, depth + 1).plus(
            _shader(linked_node(node.inputs[1]), material, warnings, depth + 1))
    if kind == "MIX_SHADER":
        fac = min(max(socket_value(node, "Fac", 0.5), 0.0), 1.0)
        return _shader(linked_node(node.inputs[1]), material, warnings, depth + 1).scaled(1 - fac).plus(
            _shader(linked_node(node.inputs[2]), material, warnings, depth + 1).scaled(fac))
    warnings.append(f"material '{material.name}': shader '{node.bl_idname}' is approximated by the material's "
                    "viewport colour")
    return SurfaceMaterial(albedo=tuple(material.diffuse_color[:3]))


def _warn_tangent(node, material, warnings, anisotropy):
    """The core's anisotropy follows the surface's own u direction: a Tangent input is not read."""
    tangent = node.inputs.get("Tangent")
    if anisotropy and tangent is not None and tangent.is_linked:
        warnings.append(f"material '{material.name}': {node.name}'s Tangent input is ignored; the anisotropy "
                        "follows each surface's u direction (ds/du), turned by its rotation")


def active_output(tree, kind):
    """The output node of that type Blender renders with (the active one, else the first)."""
    outputs = [n for n in tree.nodes if n.type == kind]
    return next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)


def linked_node(socket):
    return socket.links[0].from_node if socket.is_linked else None


def describe_material(material, warnings) -> SurfaceMaterial:
    """A Blender material as the solver sees it."""
    if material is None:
        return SurfaceMaterial(albedo=DEFAULT_ALBEDO)
    tree = material.node_tree
    output = None
    if tree is not None:
        output = active_output(tree, "OUTPUT_MATERIAL")
    if output is None or not output.inputs["Surface"].is_linked:
        return SurfaceMaterial(albedo=tuple(material.diffuse_color[:3]))
    return _shader(linked_node(output.inputs["Surface"]), material, warnings)


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


def surface_options(obj) -> dict:
    """The object's per-surface solver options (Object properties), as the core's keywords. Read
    from the original object: the evaluated copy's may predate the user's last change."""
    settings = getattr(obj.original, "bsgi", None)
    if settings is None:
        return {}
    return {"representation": settings.representation.lower(), "spatial_coeffs": settings.spatial_coeffs,
            "angular_coeffs": settings.angular_coeffs}


def user_slots(obj) -> list:
    """The user's material per slot (at least one slot, None for empty)."""
    # The evaluated object's slots otherwise: a geometry-nodes instance's materials come with its
    # instanced mesh, its original object is the instancer.
    original = obj.original
    return (user_materials(original) if is_baked(original) else [s.material for s in obj.material_slots]) or [None]


def _slot_materials(obj, warnings) -> list:
    return [solver_material(m, describe_material(m, warnings), warnings) for m in user_slots(obj)]


def _material_keywords(material: SolverMaterial, options: dict) -> dict:
    return dict(albedo=material.albedo, emission=material.emission, bsdf=material.bsdf, **options)


@dataclass
class ObjectMaterials:
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

    def add(self, scene, slot: int, surface) -> int:
        """Adds the surface with the slot's material to the scene. Cycles' Emission shader emits
        from both sides of a mesh (area lights from their front only): so do emissive surfaces."""
        keywords = self.for_surface(slot, surface)
        index = scene.add_surface(surface, **keywords)
        if max(keywords["emission"]) > 0:
            scene.set_two_sided_emission(index)
        return index

    def warn(self, warnings) -> None:
        if math.degrees(self.spread) > tangents.MAX_SPREAD_DEGREES:
            warnings.append(f"object '{self.label}': Blender's tangent for its anisotropic material turns by up to "
                            f"{math.degrees(self.spread):.0f} degrees against the surfaces' own u direction; the "
                            "solver turns the lobe by one mean angle per surface (UV charts and NURBS surfaces "
                            "follow a smooth tangent better than single faces)")


def object_materials(obj, matrix: Matrix, warnings, label: str, options: dict) -> ObjectMaterials:
    solver = _slot_materials(obj, warnings)
    radial = tangents.RadialTangent(np.array(matrix, float), [tuple(c) for c in obj.bound_box])
    return ObjectMaterials(solver, [_material_keywords(m, options) for m in solver], radial, label)
