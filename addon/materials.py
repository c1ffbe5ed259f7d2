"""Blender materials -> what the solver is given: a node tree's shaders as a described material
(SurfaceMaterial), and the one BSDF the core solves for it (SolverMaterial), per object slot.
Also the node-tree helpers the world's export shares. No solve state here."""
from __future__ import annotations

import math
from contextlib import contextmanager
from functools import lru_cache
from dataclasses import dataclass, field

import bpy
import numpy as np
from mathutils import Matrix

import bsgi

from . import tangents
from .properties import object_setting
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
    # Colour or emission driven by nodes: Blender evaluates them (textures.py bakes them), the
    # values above are the sockets' own.
    albedo_textured: bool = False
    emission_textured: bool = False
    # Cycles' "Light Path" trick for windows (a Mix Shader whose Fac is Is Shadow Ray): what
    # shadow rays get through the material (the Transparent BSDF's colour), or None.
    shadow: tuple | None = None
    # Glossy colour driven by nodes (a Glossy BSDF's Color, a metallic Principled BSDF's Base Color).
    specular_textured: bool = False
    # How the glossy lobe's reflectance rises towards grazing angles in Cycles: Schlick's Fresnel
    # from `specular` (a metallic Principled BSDF), or not at all (a Glossy BSDF: its colour times GGX).
    schlick: bool = True
    # A lone Principled BSDF with neither metal nor transmission: its specular is a dielectric coat
    # over the base, which Cycles layers (a scaled or mixed shader is not: its parts fold).
    coat: bool = False
    # Cycles' Multiscatter GGX (the default distribution): the light scattered between
    # microfacets is put back (bsgi.GgxReflection's multiscatter).
    multiscatter: bool = False
    # Glass's tints, Cycles' reflection and transmission tints: a Glass BSDF's colour on both
    # branches; a Principled BSDF's square root of its base colour on the light it transmits
    # (met on the way in and on the way out of a solid), its reflection white.
    glass_reflection: tuple = (1.0, 1.0, 1.0)
    glass_transmission: tuple = (1.0, 1.0, 1.0)
    # A Diffuse or Principled BSDF whose Normal input is driven (a Normal Map or Bump node):
    # Blender evaluates the bumped normal (textures.py bakes it), the core solves its diffuse part
    # over it (bsgi.Scene.set_normal_texture). What drives it ("normal map", "bump map", a node's
    # name), empty if nothing does.
    bumped: str = ""

    def scaled(self, k: float) -> "SurfaceMaterial":
        return SurfaceMaterial(_scale(self.albedo, k), _scale(self.specular, k), self.roughness, self.stretch,
                               self.rotation, self.transmission * k, self.ior, _scale(self.emission, k),
                               self.albedo_textured, self.emission_textured, self.shadow, self.specular_textured,
                               self.schlick, multiscatter=self.multiscatter, glass_reflection=self.glass_reflection,
                               glass_transmission=self.glass_transmission, bumped=self.bumped)

    def plus(self, other: "SurfaceMaterial") -> "SurfaceMaterial":
        """Sum of two shaders (Add Shader, the two halves of a Mix Shader)."""
        glossy = sum(self.specular) >= sum(other.specular)
        dominant = self if glossy else other
        return SurfaceMaterial(_add(self.albedo, other.albedo), _add(self.specular, other.specular), dominant.roughness,
                               dominant.stretch, dominant.rotation, self.transmission + other.transmission, dominant.ior,
                               _add(self.emission, other.emission), self.albedo_textured or other.albedo_textured,
                               self.emission_textured or other.emission_textured,
                               self.shadow if self.shadow is not None else other.shadow,
                               self.specular_textured or other.specular_textured, dominant.schlick,
                               multiscatter=dominant.multiscatter,
                               glass_reflection=_glass_tint(self, other, "glass_reflection"),
                               glass_transmission=_glass_tint(self, other, "glass_transmission"),
                               bumped=self.bumped or other.bumped)


def _glass_tint(a: SurfaceMaterial, b: SurfaceMaterial, name: str) -> tuple:
    """Two shaders' glass tint as one glass: their tints' mean weighted by what each transmits."""
    total = a.transmission + b.transmission
    if total <= 0:
        return getattr(a, name)
    return tuple((x * a.transmission + y * b.transmission) / total for x, y in zip(getattr(a, name), getattr(b, name)))


def _unit_colour(c) -> tuple:
    """A colour with each channel clamped to [0, 1] (a reflectance or a tint)."""
    return tuple(min(max(x, 0.0), 1.0) for x in c)


def _scale(c, k):
    return tuple(x * k for x in c)


def _add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def dielectric_f0(node) -> float:
    """A Principled BSDF's dielectric specular reflectance at normal incidence, ((ior-1)/(ior+1))^2,
    scaled by the specular level (0.5 is the physical value)."""
    ior = socket_value(node, "IOR", 1.5)
    return ((ior - 1) / (ior + 1)) ** 2 * 2 * socket_value(node, "Specular IOR Level", 0.5)


def socket_color(node, name, default=(0.0, 0.0, 0.0)):
    sock = node.inputs.get(name)
    if sock is None:
        return default
    value = sock.default_value
    return tuple(value[:3]) if hasattr(value, "__len__") else (float(value),) * 3


# Node-driven scalar inputs that the solve takes as one value per material: their mean over the
# surfaces using the material, as Blender evaluates them (textures.socket_means), for the export
# under way: (material name, node name, input name) -> mean.
AVERAGED_INPUTS = {
    "BSDF_PRINCIPLED": ("Roughness", "Metallic"),
    "BSDF_GLOSSY": ("Roughness",),
    "BSDF_ANISOTROPIC": ("Roughness",),
    "BSDF_GLASS": ("Roughness",),
}
_averaged: dict = {}


@contextmanager
def averaged_inputs(means: dict):
    """Within the block, socket_value gives these means for their node-driven inputs."""
    _averaged.update(means)
    try:
        yield
    finally:
        _averaged.clear()


def socket_value(node, name, default=0.0):
    sock = node.inputs.get(name)
    return float(sock.default_value) if sock is not None else default


def _scalar(material, node, name, default=0.0):
    """A roughness or metallic input: its mean where nodes drive it (averaged_inputs), else its value."""
    mean = _averaged.get((material.name, node.name, name))
    return mean if mean is not None else socket_value(node, name, default)


def _shader(node, material, warnings, depth=0) -> SurfaceMaterial:
    """The material description of a shader node (recursing through Mix and Add shaders)."""
    if node is None or depth > 16:
        return SurfaceMaterial()
    if _is_shadow_ray_mix(node):
        return _shadow_ray_mix(node, material, warnings, depth)
    colour, glow = TEXTURED_INPUTS.get(node.type, ((), ()))
    tint = SPECULAR_INPUTS.get(node.type, ())
    averaged = [name for name in AVERAGED_INPUTS.get(node.type, ()) if (material.name, node.name, name) in _averaged]
    linked = [s.name for s in node.inputs if s.is_linked and s.type != "SHADER"
              and s.name not in {"Normal", "Tangent", "Alpha", *colour, *glow, *tint, *averaged}]
    _warn_ignored_inputs(node, material, warnings)
    for name in averaged:
        warnings.append(f"material '{material.name}': {node.name}'s {name} is driven by nodes and solved as its mean "
                        f"{_averaged[(material.name, node.name, name)]:.3f} over the surfaces using the material")
    if linked:
        warnings.append(f"material '{material.name}': {node.name} inputs {', '.join(linked)} are driven by nodes; "
                        "their own values are used instead")
    textured = {"albedo_textured": any(_is_linked(node, name) for name in colour),
                "emission_textured": any(_is_linked(node, name) for name in glow)}
    # A Principled BSDF's base colour tints its lobe only where it is metallic.
    specular_textured = any(_is_linked(node, name) for name in tint) and (
        node.type != "BSDF_PRINCIPLED" or _scalar(material, node, "Metallic") > 0)
    kind = node.type
    if kind == "BSDF_DIFFUSE":
        return SurfaceMaterial(albedo=socket_color(node, "Color"), bumped=_bumped(node), **textured)
    if kind == "EMISSION":
        return SurfaceMaterial(emission=_scale(socket_color(node, "Color"), socket_value(node, "Strength", 1.0)),
                               **textured)
    distribution = getattr(node, "distribution", "GGX")
    if distribution in {"BECKMANN", "ASHIKHMIN_SHIRLEY"}:
        warnings.append(f"material '{material.name}': {node.name}'s {distribution.replace('_', '-').title()} "
                        "microfacet distribution is solved as GGX")
    multiscatter = distribution == "MULTI_GGX"
    if kind in {"BSDF_GLOSSY", "BSDF_ANISOTROPIC"}:
        # Cycles' Glossy BSDF: anisotropy a in [-0.99, 0.99] narrows the lobe along the tangent
        # by (1 - a) for a > 0 and widens it by 1 / (1 + a) for a < 0 (the other axis inversely).
        a = min(max(socket_value(node, "Anisotropy", 0.0), -0.99), 0.99)
        stretch = 1 / (1 + a) if a < 0 else 1 - a
        rotation = socket_value(node, "Rotation") if a else 0.0
        _warn_tangent(node, material, warnings, a)
        # Its colour times GGX, without Fresnel (Cycles' node_glossy_bsdf).
        return SurfaceMaterial(specular=socket_color(node, "Color"), roughness=_scalar(material, node, "Roughness", 0.5),
                               stretch=stretch, rotation=2 * math.pi * rotation, specular_textured=specular_textured,
                               schlick=False, multiscatter=multiscatter)
    if kind == "BSDF_GLASS":
        colour = _unit_tint(socket_color(node, "Color", (1.0, 1.0, 1.0)), node, material, warnings)
        return SurfaceMaterial(transmission=1.0, roughness=_scalar(material, node, "Roughness", 0.0),
                               ior=socket_value(node, "IOR", 1.5), multiscatter=multiscatter,
                               glass_reflection=colour, glass_transmission=colour)
    if kind == "BSDF_PRINCIPLED":
        base = socket_color(node, "Base Color")
        metallic = _scalar(material, node, "Metallic")
        # Metals do not transmit: Blender's metallic part covers the transmission.
        transmission = socket_value(node, "Transmission Weight", socket_value(node, "Transmission")) * (1 - metallic)
        ior = socket_value(node, "IOR", 1.5)
        f0 = dielectric_f0(node)  # metals reflect their base colour
        diffuse_weight = 1 - metallic - transmission
        specular = tuple(metallic * c + (1 - metallic) * f0 for c in base)
        emission = _scale(socket_color(node, "Emission Color"), socket_value(node, "Emission Strength"))
        layers = [label for label, name in (("subsurface", "Subsurface Weight"), ("coat", "Coat Weight"),
                                            ("sheen", "Sheen Weight"), ("thin film", "Thin Film Thickness"))
                  if socket_value(node, name) > 0]
        if socket_value(node, "Alpha", 1.0) < 1:
            layers.append("alpha (transparency)")
        if metallic > 0 and min(socket_color(node, "Specular Tint", (1.0, 1.0, 1.0))) < 1:
            # Cycles' metal Fresnel is its F82 tint model: Schlick's curve from the base colour,
            # bent towards the tint near grazing; the solver has Schlick's alone (the white tint).
            layers.append("specular tint (a metal's edge colour)")
        if transmission > 0 and min(socket_color(node, "Specular Tint", (1.0, 1.0, 1.0))) < 1:
            # Cycles tints a glass's f0 (its reflection's generalised Schlick curve), not F.
            layers.append("specular tint (a glass's reflection colour)")
        if layers:
            warnings.append(f"material '{material.name}': {node.name}'s {', '.join(layers)} "
                            f"{'is' if len(layers) == 1 else 'are'} not solved; the base layers are")
        # Cycles' Principled BSDF: anisotropic a in [0, 1] widens the lobe along the tangent by
        # 1 / sqrt(1 - 0.9 a) and narrows it across by the same factor.
        a = min(max(socket_value(node, "Anisotropic"), 0.0), 1.0)
        rotation = socket_value(node, "Anisotropic Rotation") if a else 0.0
        _warn_tangent(node, material, warnings, a)
        return SurfaceMaterial(albedo=_scale(base, diffuse_weight), specular=specular,
                               roughness=_scalar(material, node, "Roughness", 0.5), stretch=1 / math.sqrt(1 - 0.9 * a),
                               rotation=2 * math.pi * rotation, transmission=transmission, ior=ior, emission=emission,
                               specular_textured=specular_textured, coat=metallic == 0 and transmission == 0,
                               multiscatter=multiscatter,
                               glass_transmission=tuple(math.sqrt(c) for c in _unit_colour(base)), bumped=_bumped(node),
                               **textured)
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


# Per shader node: the inputs colouring its diffuse reflection and its emission that Blender
# evaluates for the solve when nodes drive them (a Cycles bake of the diffuse-colour and
# emission passes, textures.py).
TEXTURED_INPUTS = {
    "BSDF_DIFFUSE": (("Color",), ()),
    "BSDF_PRINCIPLED": (("Base Color",), ("Emission Color", "Emission Strength")),
    "EMISSION": ((), ("Color", "Strength")),
}


# Per shader node: the inputs colouring its glossy lobe that Blender evaluates for the solve when
# nodes drive them (a Cycles bake of the glossy-colour pass, textures.py).
SPECULAR_INPUTS = {
    "BSDF_GLOSSY": ("Color",),
    "BSDF_ANISOTROPIC": ("Color",),
    "BSDF_PRINCIPLED": ("Base Color",),
}


def _is_linked(node, name) -> bool:
    socket = node.inputs.get(name)
    return socket is not None and socket.is_linked


def _is_shadow_ray_mix(node) -> bool:
    """A Mix Shader whose Fac comes from Light Path's Is Shadow Ray: the window trick."""
    if node.type != "MIX_SHADER" or not node.inputs["Fac"].is_linked:
        return False
    link = node.inputs["Fac"].links[0]
    return link.from_node.type == "LIGHT_PATH" and link.from_socket.name == "Is Shadow Ray"


def _shadow_ray_mix(node, material, warnings, depth) -> SurfaceMaterial:
    """Cycles' Light Path trick: camera and bounce rays see the first shader, shadow rays the
    second; a Transparent BSDF there lets shadow rays through with its colour (Cycles defines what
    the scene means, so the solve does the same for the visibility of lights)."""
    seen = _shader(linked_node(node.inputs[1]), material, warnings, depth + 1)
    shadow_node = linked_node(node.inputs[2])
    if shadow_node is not None and shadow_node.type == "BSDF_TRANSPARENT":
        seen.shadow = _unit_tint(socket_color(shadow_node, "Color", (1.0, 1.0, 1.0)), shadow_node, material, warnings)
    else:
        warnings.append(f"material '{material.name}': {node.name} shows shadow rays another shader than a "
                        "Transparent BSDF; lights are seen through it as through the first shader")
    return seen


def _unit_tint(colour, node, material, warnings) -> tuple:
    """A Glass BSDF's colour as a tint the solve takes: each channel in [0, 1] (Cycles takes a
    brighter one as glass that makes light)."""
    clamped = _unit_colour(colour)
    if max(colour) > 1 + 1e-6:
        warnings.append(f"material '{material.name}': {node.name}'s colour "
                        f"({', '.join(f'{c:.2f}' for c in colour)}) passes more light than it receives; solved "
                        f"as ({', '.join(f'{c:.2f}' for c in clamped)})")
    return clamped


# Shaders whose Normal input the solve models (on their diffuse reflection).
BUMPED_SHADERS = {"BSDF_DIFFUSE", "BSDF_PRINCIPLED"}


def _bumped(node) -> str:
    """What drives a shader's Normal input where the solve models it, else ""."""
    return _normal_input_name(node) if node.type in BUMPED_SHADERS else ""


def _normal_input_name(node) -> str:
    """What drives a shader's Normal input, as the user made it: "normal map", "bump map" or the
    node's name; "" if nothing does."""
    normal = node.inputs.get("Normal")
    source = linked_node(normal) if normal is not None else None
    return "" if source is None else {"NORMAL_MAP": "normal map", "BUMP": "bump map"}.get(source.type, f"'{source.name}'")


def _warn_ignored_inputs(node, material, warnings):
    """Inputs that change how a surface looks but that the solve does not model, named as what
    the user made them (a normal map or a bump on a glossy or glass shader, a transparency mask)."""
    what = _normal_input_name(node) if node.type not in BUMPED_SHADERS else ""
    if what:
        warnings.append(f"material '{material.name}': {node.name}'s Normal input ({what}) is "
                        "ignored; the surface's own normals are used (bumps are solved on diffuse reflection)")
    alpha = node.inputs.get("Alpha")
    if alpha is not None and alpha.is_linked:
        warnings.append(f"material '{material.name}': {node.name}'s Alpha input (transparency driven by nodes) is "
                        "ignored; the surface is solved opaque")


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


def linked_node(socket, groups=(), depth=0):
    """The node feeding a socket as Cycles sees it: through reroutes, muted nodes (their internal
    links) and node groups (into the group to what feeds its output, and out again at its Group
    Input; groups is the stack of group nodes entered). None for an unlinked socket, a muted or
    invalid link (Blender marks the links of a cycle invalid), or a chain deeper than 64."""
    links = [link for link in socket.links if link.is_valid and not link.is_muted] if socket.is_linked else []
    if not links or depth > 64:
        return None
    link = links[0]
    node, out = link.from_node, link.from_socket
    if node.type == "REROUTE":
        return linked_node(node.inputs[0], groups, depth + 1)
    if node.mute:
        through = next((i.from_socket for i in node.internal_links if i.to_socket == out), None)
        return None if through is None else linked_node(through, groups, depth + 1)
    if node.type == "GROUP":
        output = None if node.node_tree is None else active_output(node.node_tree, "GROUP_OUTPUT")
        inner = None if output is None else next((s for s in output.inputs if s.identifier == out.identifier), None)
        return None if inner is None else linked_node(inner, (*groups, node), depth + 1)
    if node.type == "GROUP_INPUT" and groups:
        outer = next((s for s in groups[-1].inputs if s.identifier == out.identifier), None)
        return None if outer is None else linked_node(outer, groups[:-1], depth + 1)
    return node


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
    kind: str = "lambert"  # "lambert" | "ggx" | "diffuse_ggx" | "rough_dielectric"
    alpha: float = 0.0  # roughness^2 (clamped), the isotropic GGX alpha
    alpha_x: float = 0.0  # "ggx": along the tangent ds/du turned by `rotation` radians about the normal
    alpha_y: float = 0.0
    rotation: float = 0.0
    f0: tuple = (0.0, 0.0, 0.0)
    schlick: bool = True  # "ggx": Schlick's Fresnel from f0, or f0 at every angle (SurfaceMaterial.schlick)
    multiscatter: bool = False  # the lobe's multiple scattering (SurfaceMaterial.multiscatter)
    eta: float = 1.0
    bsdf: object = None  # bsgi.Bsdf, None for Lambert (the scene then uses albedo)
    # Node-driven colour of a Lambertian material and node-driven emission: baked by textures.py
    # into the surfaces' albedo and emission textures. `specular` is the glossy reflectance the
    # albedo absorbs (the baked diffuse colour plus it is the albedo, as for constants).
    albedo_textured: bool = False
    emission_textured: bool = False
    # Node-driven glossy colour of a GGX material: baked by textures.py into the surfaces'
    # specular textures (the core's BSDF then takes each texture's mean as its f0).
    specular_textured: bool = False
    specular: tuple = (0.0, 0.0, 0.0)
    pass_weight: tuple = (1.0, 1.0, 1.0)  # Cycles' diffuse-colour pass over the base colour
    # "diffuse_ggx" (a Principled BSDF's base under its coat): the coat folded into one Lambertian
    # albedo, for an object whose representation is set to diffuse.
    folded_albedo: tuple | None = None
    # Glass ("rough_dielectric"): the user's roughness, what shadow rays get (the Light Path
    # trick, or None), and the warnings that hold only if it is solved as a rough dielectric.
    roughness: float = 0.0
    shadow: tuple | None = None
    solid_notes: list = field(default_factory=list)
    # "lambert" under a normal map or bump (SurfaceMaterial.bumped), with the material's Bump Map
    # Correction (Cycles' bump shadowing term).
    bumped: bool = False
    bump_correction: bool = True


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
    chosen = _solver_material(name, described, warnings)
    if described.bumped and not bumps_solved():
        warnings.append(f"material '{name}': its Normal input ({described.bumped}) is solved flat, with the surface's own "
                        "normals (the scene's Bumps)")
    elif described.bumped:
        chosen = _bumped_material(name, chosen, described.bumped, warnings)
        cycles = getattr(material, "cycles", None)
        chosen.bump_correction = bool(getattr(cycles, "use_bump_map_correction", True))
    chosen.emission_textured = described.emission_textured
    if chosen.kind == "ggx" and described.specular_textured:
        # Its f0 over each surface (Cycles' glossy-colour pass), which the core blends exactly:
        # Schlick's Fresnel is affine in f0.
        chosen.specular_textured = True
    elif described.albedo_textured or described.specular_textured:
        if chosen.kind in {"lambert", "diffuse_ggx"} and described.albedo_textured:
            # Its albedo is the baked diffuse colour plus the lobe's, or under a layered coat the
            # base colour itself (the core layers each texel, bsgi.SurfaceRadiance.coat_share).
            chosen.albedo_textured = True
        else:
            warnings.append(f"material '{name}': its colour is driven by nodes on a {chosen.kind.replace('_', ' ')} "
                            "surface, which is solved with the socket's own value (textures colour diffuse surfaces "
                            "and the lobe of glossy ones)")
    return chosen


def _bumped_material(name: str, chosen: SolverMaterial, what: str, warnings) -> SolverMaterial:
    """A material whose normal is bumped: its diffuse reflection is solved over the bumped normal
    (Lambertian only: a layered coat is folded into its base, named); a glossy or glass one keeps
    its own normals, named."""
    if chosen.kind == "diffuse_ggx":
        warnings.append(f"material '{name}': its Normal input ({what}) is solved on its diffuse base, with its coat (the "
                        "specular layer) folded into the base's albedo: the coat's highlights are not solved")
        chosen = SolverMaterial(chosen.folded_albedo, chosen.emission, specular=chosen.specular,
                                pass_weight=chosen.pass_weight)
    if chosen.kind != "lambert":
        warnings.append(f"material '{name}': its Normal input ({what}) is ignored on a {chosen.kind.replace('_', ' ')} surface; "
                        "the surface's own normals are used (bumps are solved on diffuse reflection)")
        return chosen
    chosen.bumped = True
    return chosen


def _solver_material(name: str, described: SurfaceMaterial, warnings) -> SolverMaterial:
    diffuse = sum(described.albedo) / 3
    glossy = sum(described.specular) / 3
    transmission = described.transmission
    if transmission > max(diffuse, glossy):
        if diffuse + glossy > 0.05:
            warnings.append(f"material '{name}': solved as rough glass; its diffuse and metallic parts are dropped")
        eta = max(described.ior, 1.0 + 1e-3)
        notes: list = []  # given once the object's shape says it is solid glass (geometry.py)
        alpha = _alpha(name, described.roughness, notes)
        # Cycles' glass: its shadowing, the light carried across without the radiance's (n_o / n_i)^2
        # (as Cycles shows an open sheet; a closed solid's factors cancel), and with Multiscatter
        # GGX the light between microfacets put back (single scattering lost up to 60% at roughness 1).
        glass = bsgi.RoughDielectric(eta, alpha, alpha, multiscatter=described.multiscatter, height_correlated=True,
                                     scale_radiance=False, reflection_tint=described.glass_reflection,
                                     transmission_tint=described.glass_transmission)
        return SolverMaterial((0, 0, 0), described.emission, "rough_dielectric", alpha=alpha, eta=eta, bsdf=glass,
                              roughness=described.roughness, multiscatter=described.multiscatter,
                              shadow=described.shadow, solid_notes=notes)
    if transmission > 0:
        warnings.append(f"material '{name}': its transmission is weaker than its reflection; solved as opaque")
    if glossy > diffuse:
        if diffuse > 0.05:
            warnings.append(f"material '{name}': solved as glossy (GGX); its diffuse part is dropped")
        f0 = _unit_colour(described.specular)
        alpha = _alpha(name, described.roughness, warnings)
        ax, ay = _anisotropic_alphas(name, described, alpha, warnings)
        return SolverMaterial((0, 0, 0), described.emission, "ggx", alpha=alpha, alpha_x=ax, alpha_y=ay,
                              rotation=described.rotation, f0=f0, schlick=described.schlick,
                              multiscatter=described.multiscatter,
                              bsdf=bsgi.GgxReflection(ax, ay, f0, rotation=described.rotation, schlick=described.schlick,
                                                      multiscatter=described.multiscatter, height_correlated=True))
    # Cycles layers the specular lobe over the diffuse base, which gets the energy the lobe leaves:
    # folded into one Lambertian albedo, base (1 - E) + E, E the lobe's hemispherical albedo (a
    # rough lobe reflects far less than its f0: roughness 1 leaves 0.016 of f0 0.04).
    lobe = layer_albedo(tuple(described.specular), described.roughness, multiscatter=described.multiscatter)
    albedo = _unit_colour(a * (1 - e) + e for a, e in zip(described.albedo, lobe))
    visible = glossy > 0 and coat_peak_ratio(described.specular, described.roughness, described.albedo) >= coat_threshold()
    # Cycles' diffuse-colour pass (textures.py bakes it) is the base seen along the normal, under
    # the lobe's albedo in that direction.
    seen = layer_albedo(tuple(described.specular), described.roughness, normal_only=True,
                        multiscatter=described.multiscatter)
    pass_weight = tuple(1 - e for e in seen)
    if visible and described.coat and not (described.specular_textured or max(described.emission) > 0
                                           or described.stretch != 1):
        # Its highlight shows: the layered coat itself (2D base + 4D coat, (38)); `albedo` is the
        # folded Lambertian, for an object set to a diffuse representation.
        alpha = _alpha(name, described.roughness, warnings)
        f0 = _unit_colour(described.specular)
        base = _unit_colour(described.albedo)
        # Cycles' coat reflects with a dielectric's Fresnel curve (the IOR of its f0), not Schlick's.
        root = math.sqrt(min(max(sum(f0) / 3, 1e-6), 0.99))
        eta = (1 + root) / (1 - root)
        return SolverMaterial(base, described.emission, "diffuse_ggx", alpha=alpha, alpha_x=alpha, alpha_y=alpha, f0=f0,
                              eta=eta, bsdf=layered_coat(base, alpha, f0, eta, described.multiscatter), specular=lobe,
                              folded_albedo=albedo, multiscatter=described.multiscatter,
                              pass_weight=pass_weight)
    if visible or glossy > 0.05 or (glossy > 0.01 and described.roughness < 0.3):
        warnings.append(f"material '{name}': solved as diffuse; its specular highlights (roughness "
                        f"{described.roughness:.2f}) are not solved, their energy is added to the albedo")
    return SolverMaterial(albedo, described.emission, specular=lobe, pass_weight=pass_weight)


# A Principled BSDF's dielectric coat is solved (bsgi.DiffuseGgx, layered as Cycles layers it: a 2D
# base and a 4D coat) where its highlight reaches a fraction of the base's radiance (its peak at
# normal incidence against base / pi), per the scene's Glossy Coats; elsewhere it is folded into a
# Lambertian albedo. Folded, a floor and wall under an area light (tests/blender/test_principled_materials.py,
# preview, mean per-pixel difference from Cycles) were off by about 0.4-0.7 times that fraction:
# 0.83% at 0.012 (roughness 1 over base 0.8), 1.55% at 0.024 (0.85 over 0.8), 1.59% at 0.040 (1.0
# over 0.25), 3.2% at 0.052 (0.7 over 0.8), 3.85% at 0.077 (0.85 over 0.25), 8.0% at 0.20 (the
# default material, 0.5 over 0.8); layered 0.55-0.87% on each. Layered costs 2-6 times the solve of
# the folded (the furnished interior at preview with its roughness-1 dark woods and books layered:
# 162 s against 31 s). Draft and Preview fold up to 5% (about 3% off), Final and Reference up to
# 1.5% (about 1%).
COAT_THRESHOLDS = {"fast": 0.05, "accurate": 0.015}


def bumps_solved() -> bool:
    """Whether the current scene solves normal maps and bumps (its Bumps setting)."""
    settings = getattr(bpy.context.scene, "bsgi", None) if bpy.context.scene is not None else None
    return settings is None or settings.bumps == "SOLVED"


def coat_threshold() -> float:
    """The highlight fraction from which the current scene's coats are solved (materials are
    described per export: the scene's Glossy Coats and quality)."""
    settings = getattr(bpy.context.scene, "bsgi", None) if bpy.context.scene is not None else None
    if settings is None:
        return COAT_THRESHOLDS["fast"]
    if settings.coats == "FOLDED":
        return math.inf
    if settings.coats == "ALL":
        return 0.0
    return COAT_THRESHOLDS["accurate" if settings.preset in ("FINAL", "REFERENCE") else "fast"]


# Every object's slots are described anew: a layered coat tabulates its directional albedo when
# made (5 ms), so the same few materials' coats are made once and shared.
@lru_cache(maxsize=1024)
def layered_coat(base: tuple, alpha: float, f0: tuple, eta: float, multiscatter: bool = False):
    return bsgi.DiffuseGgx(base, alpha, alpha, f0, layered=True, eta=eta, multiscatter=multiscatter, height_correlated=True)


def coat_peak_ratio(f0, roughness: float, base) -> float:
    """The coat's BSDF along the normal, lit along the normal, against the base's albedo / pi."""
    r = min(max(roughness, MIN_ROUGHNESS), 1.0)
    coat = bsgi.GgxReflection(r * r, r * r, [min(max(c, 0.0), 1.0) for c in f0], height_correlated=True)
    normal = np.array([[0.0, 0.0, 1.0]])
    peak = float(coat.eval(normal, normal).max())
    return peak / (max(sum(base) / 3, 1e-3) / math.pi)


# Every object's slots are described anew (solver_material per object): the same few materials
# would integrate their lobe once per object, a few milliseconds each, without the cache.
@lru_cache(maxsize=1024)
def layer_albedo(f0: tuple, roughness: float, normal_only: bool = False, nodes: int = 24,
                 multiscatter: bool = False) -> tuple:
    """The albedo, per channel, of a GGX reflection lobe of reflectance f0 at normal incidence and
    Blender's roughness (alpha = roughness^2), with its multiple scattering or not, as the core's
    GgxReflection gives it: hemispherical,
    2 * integral of E(mu) mu dmu with E(mu) its directional albedo (or E(1) with normal_only), by a
    midpoint rule in mu^2 and cosine-weighted directions (the lobes solved as diffuse are wide: a
    coarse rule is exact to about 1e-4)."""
    if max(f0) <= 0:
        return (0.0, 0.0, 0.0)
    r = min(max(roughness, 0.05), 1.0)
    lobe = bsgi.GgxReflection(r * r, r * r, [min(max(c, 0.0), 1.0) for c in f0], multiscatter=multiscatter,
                              height_correlated=True)
    g = (np.arange(nodes) + 0.5) / nodes
    cos2, phi = np.meshgrid(g, 2 * np.pi * (np.arange(2 * nodes) + 0.5) / (2 * nodes), indexing="ij")
    cos_i, sin_i = np.sqrt(cos2).ravel(), np.sqrt(1 - cos2).ravel()
    wi = np.stack([sin_i * np.cos(phi.ravel()), sin_i * np.sin(phi.ravel()), cos_i], 1)
    views = [1.0] if normal_only else np.sqrt(g)  # outgoing directions, cosine-weighted too
    total = np.zeros(3)
    for mu in views:
        wo = np.broadcast_to([np.sqrt(1 - mu * mu), 0.0, mu], wi.shape)
        total += np.pi * lobe.eval(np.ascontiguousarray(wo), wi).mean(axis=0)
    return tuple(float(x) for x in total / len(views))


def surface_options(obj) -> dict:
    """The object's per-surface solver options (Object properties), as the core's keywords. Read
    from the original object: the evaluated copy's may predate the user's last change."""
    return {"representation": object_setting(obj, "representation").lower(),
            "spatial_coeffs": object_setting(obj, "spatial_coeffs"),
            "angular_coeffs": object_setting(obj, "angular_coeffs")}


def solved_diffuse(obj) -> bool:
    """Whether the object is set to a diffuse representation: its layered coats are then folded
    (SolverMaterial.folded_albedo), and so is the albedo texture of a textured one."""
    return surface_options(obj)["representation"] == "diffuse"


def user_slots(obj) -> list:
    """The user's material per slot (at least one slot, None for empty)."""
    # The evaluated object's slots otherwise: a geometry-nodes instance's materials come with its
    # instanced mesh, its original object is the instancer.
    original = obj.original
    return (user_materials(original) if is_baked(original) else [s.material for s in obj.material_slots]) or [None]


def _slot_materials(obj, warnings) -> list:
    return [solver_material(m, describe_material(m, warnings), warnings) for m in user_slots(obj)]


def _material_keywords(material: SolverMaterial, options: dict) -> dict:
    if material.kind == "diffuse_ggx" and options.get("representation") == "diffuse":
        return dict(albedo=material.folded_albedo, emission=material.emission, bsdf=None, **options)
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
    material_names: list = field(default_factory=list)  # per slot, for the report

    def for_surface(self, slot: int, surface) -> dict:
        """The keywords of the slot's material; an anisotropic GGX turned so that its tangent
        follows Blender's on this surface (ds/du turned by the mean angle between them)."""
        slot = min(slot, len(self.solver) - 1)
        material, keywords = self.solver[slot], self.keywords[slot]
        if material.kind != "ggx" or material.alpha_x == material.alpha_y:
            return keywords
        angle, spread = tangents.surface_rotation(self.radial, surface)
        self.spread = max(self.spread, spread)
        bsdf = bsgi.GgxReflection(material.alpha_x, material.alpha_y, material.f0, rotation=material.rotation + angle,
                                  schlick=material.schlick, multiscatter=material.multiscatter, height_correlated=True)
        return {**keywords, "bsdf": bsdf}

    def use_glass(self, shape: GlassShape, choice: str, warnings) -> set:
        """Decides, per glass slot, thin pane or solid glass (glass_model), says which and why,
        and makes the panes' keywords thin glass; returns the thin slots."""
        thin = set()
        for slot, material in enumerate(self.solver):
            if material.kind != "rough_dielectric":
                continue
            model, why = glass_model(material, shape, choice)
            name = self.material_names[slot]
            if model == "solid":
                warnings.append(f"object '{self.label}': its glass (material '{name}') is solved as a rough "
                                f"dielectric, with radiance splines for both hemispheres ({why})")
                warnings.extend(material.solid_notes)
                if material.shadow is not None:
                    warnings.append(f"material '{name}': the Light Path trick (shadow rays through a Transparent "
                                    "BSDF) is not solved on solid glass")
                continue
            thin.add(slot)
            slab = shape.kind == "slab"
            light = ("shadow rays (direct light) pass with the Transparent BSDF's colour as Cycles' Light Path "
                     "trick sets it, other rays" if material.shadow is not None else "light")
            warnings.append(
                f"object '{self.label}': its glass (material '{name}') is solved as a thin pane ({why}): {light} "
                f"{'crosses each face' if slab else 'passes straight through it'} with the Fresnel factor of "
                f"{'one face' if slab else 'a thin sheet'} of index {material.eta:.2f}, and it reflects specularly "
                "(Cycles bends the rays at each face; a pane offsets them by about its thickness)")
            if max(material.emission) > 0:
                warnings.append(f"object '{self.label}': a thin pane does not emit; its glass's emission is dropped")
            # Its glass's tints per crossing, as Cycles tints each glass event (a Principled glass
            # the square root of its base colour on the light through it).
            self.keywords[slot] = {**self.keywords[slot], "albedo": (0, 0, 0), "emission": (0, 0, 0), "bsdf": None,
                                   "thin_glass": material.eta, "one_interface": slab,
                                   "shadow_transmittance": material.shadow,
                                   "transmission_tint": material.bsdf.transmission_tint,
                                   "reflection_tint": material.bsdf.reflection_tint}
        return thin

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


# Glass smoother than this on a single plane or a thin closed slab is a window pane (thin glass):
# its transmitted lobe is too narrow for the angular splines, and light crosses it nearly unbent.
THIN_GLASS_MAX_ROUGHNESS = 0.1
# A closed glass solid thinner than this fraction of its width is a slab (a solidified pane).
THIN_SLAB_MAX_RATIO = 0.1


@dataclass
class GlassShape:
    """What an object's shape says about its glass: "plane" (all faces in one plane), "slab" (a
    closed solid, thin against its width), "thick" (a thicker closed solid) or "open" (an open
    surface not in one plane); `why` in words."""

    kind: str
    why: str


def glass_model(material: SolverMaterial, shape: GlassShape, choice: str) -> tuple:
    """("thin" | "solid", why) for glass on an object of that shape; choice is the object's Glass
    setting (AUTO, THIN, SOLID)."""
    if choice == "THIN":
        return "thin", "set to Thin Pane in its object properties"
    if choice == "SOLID":
        return "solid", "set to Solid in its object properties"
    if material.roughness >= THIN_GLASS_MAX_ROUGHNESS:
        return "solid", f"roughness {material.roughness:.2f}, not below {THIN_GLASS_MAX_ROUGHNESS}"
    if shape.kind in {"plane", "slab"}:
        return "thin", f"smooth (roughness {material.roughness:.2f}) on {shape.why}"
    return "solid", f"smooth, but on {shape.why}"


def object_materials(obj, matrix: Matrix, warnings, label: str, options: dict) -> ObjectMaterials:
    solver = _slot_materials(obj, warnings)
    radial = tangents.RadialTangent(np.array(matrix, float), [tuple(c) for c in obj.bound_box])
    names = [m.name if m is not None else "(none)" for m in user_slots(obj)]
    return ObjectMaterials(solver, [_material_keywords(m, options) for m in solver], radial, label,
                           material_names=names)
