"""A neutral scene description the tests build both a bsgi.Scene and a Mitsuba 3 scene from, so
the reference path tracer sees exactly the geometry and materials the solver sees."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Patch:
    name: str
    corners: np.ndarray  # 4 (planar quad, counter-clockwise seen from its front) or 3 (triangle)
    albedo: tuple = (0.0, 0.0, 0.0)
    emission: tuple = (0.0, 0.0, 0.0)  # radiance leaving the front side
    receiver: bool = True
    ggx_alpha: float = 0.0  # > 0: GGX reflection with Fresnel 1 (Mitsuba's roughconductor, material 'none')
    dielectric: tuple = ()  # (eta, alpha): rough dielectric boundary, index eta below the front
    # (alpha_x, alpha_y, rotation): anisotropic GGX (Fresnel 1), alpha_x along the first edge
    # (corner 0 -> 1, the solver's ds/du) turned by `rotation` radians about the front normal.
    ggx_anisotropic: tuple = ()
    thin_glass: float = 0.0  # > 0: a window pane of smooth glass of this index (Mitsuba's thindielectric)


@dataclass
class SceneSpec:
    patches: list = field(default_factory=list)

    def add(self, name, corners, albedo=(0, 0, 0), emission=(0, 0, 0), receiver=True, ggx_alpha=0.0, dielectric=(),
            ggx_anisotropic=(), thin_glass=0.0):
        self.patches.append(Patch(name, np.asarray(corners, float), tuple(albedo), tuple(emission), receiver, ggx_alpha,
                                  tuple(dielectric), tuple(ggx_anisotropic), thin_glass))
        return self


def quad(center, half_u, half_v):
    """Corners of a rectangle whose front (normal u x v) faces where u x v points."""
    c, a, b = (np.asarray(x, float) for x in (center, half_u, half_v))
    return np.array([c - a - b, c + a - b, c + a + b, c - a + b])


def box(center, size, angle=0.0):
    """The six outward-facing quads of a box standing on z = center[2] - size[2] / 2, turned about z."""
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    h = np.asarray(size, float) / 2
    faces = []
    for axis in range(3):
        for sign in (-1, 1):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = h[(axis + 1) % 3]
            v = np.zeros(3)
            v[(axis + 2) % 3] = h[(axis + 2) % 3]
            if sign < 0:
                u, v = v, u
            faces.append(quad(np.asarray(center) + rot @ (n * h), rot @ u, rot @ v))
    return faces


def glass_over_floor(eta=1.5, alpha=0.3) -> SceneSpec:
    """A rough glass sheet between a lamp and a floor (paper figure 9's transmitting rectangle)."""
    spec = SceneSpec()
    spec.add("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), (0.8, 0.8, 0.8))
    spec.add("glass", quad([0, 0, 0.5], [0.4, 0, 0], [0, 0.4, 0]), dielectric=(eta, alpha))
    spec.add("lamp", quad([0.1, 0, 1.5], [0, 0.3, 0], [0.3, 0, 0]), emission=(5.0, 5.0, 5.0), receiver=False)
    return spec


def brushed_floor(alpha_x, alpha_y, rotation) -> SceneSpec:
    """An anisotropic metal floor (paper figure 11's brushed metal) under a small square lamp
    straight above its centre, beside a white wall that lights it indirectly."""
    spec = SceneSpec()
    spec.add("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), ggx_anisotropic=(alpha_x, alpha_y, rotation))
    spec.add("wall", quad([1, 0, 0.75], [0, 0, 0.75], [0, 1, 0]), (0.7, 0.7, 0.7))
    spec.add("lamp", quad([0, 0, 1.2], [0, 0.2, 0], [0.2, 0, 0]), emission=(10.0, 10.0, 10.0), receiver=False)
    return spec


def glossy_cornell_box(alpha=0.3) -> SceneSpec:
    """The Cornell box with a rough metal (GGX, Fresnel 1) back wall."""
    spec = cornell_box()
    back = next(p for p in spec.patches if p.name == "back")
    back.ggx_alpha = alpha
    back.albedo = (0.0, 0.0, 0.0)
    return spec


def cornell_box() -> SceneSpec:
    """The Cornell box of example_blends/make_cornell_box.py as patches (its lamp as an
    emitting, occluding patch: the path tracer has no light that does not occlude)."""
    white, red, green = (0.73, 0.73, 0.73), (0.63, 0.065, 0.05), (0.14, 0.45, 0.091)
    spec = SceneSpec()
    spec.add("floor", quad([0, 0, 0], [1, 0, 0], [0, 1, 0]), white)
    spec.add("ceiling", quad([0, 0, 2], [0, 1, 0], [1, 0, 0]), white)
    spec.add("back", quad([0, 1, 1], [1, 0, 0], [0, 0, 1]), white)
    spec.add("left", quad([-1, 0, 1], [0, 1, 0], [0, 0, 1]), red)
    spec.add("right", quad([1, 0, 1], [0, 0, 1], [0, 1, 0]), green)
    for i, face in enumerate(box([-0.35, 0.35, 0.6], [0.6, 0.6, 1.2], np.radians(-17))):
        spec.add(f"tall box {i}", face, white)
    for i, face in enumerate(box([0.35, -0.35, 0.3], [0.6, 0.6, 0.6], np.radians(17))):
        spec.add(f"short box {i}", face, white)
    radiance = 30.0 / (np.pi * 0.5 * 0.4)
    spec.add("lamp", quad([0, 0, 1.98], [0, 0.2, 0], [0.25, 0, 0]), emission=(radiance,) * 3, receiver=False)
    return spec


def to_bsgi(spec: SceneSpec, options=None):
    """The solver's scene; options: per patch name, keyword options of Scene.add_* (e.g. spatial_coeffs)."""
    options = options or {}
    import bsgi

    scene = bsgi.Scene()
    for p in spec.patches:
        if p.thin_glass:
            surface = (bsgi.BilinearPatch if len(p.corners) == 4 else bsgi.TrianglePatch)(p.name, p.corners)
            scene.add_surface(surface, albedo=(0, 0, 0), emission=(0, 0, 0), thin_glass=p.thin_glass)
            continue
        add = scene.add_bilinear_patch if len(p.corners) == 4 else scene.add_triangle
        bsdf = bsgi.GgxReflection(p.ggx_alpha, p.ggx_alpha, [1.0, 1.0, 1.0]) if p.ggx_alpha > 0 else None
        if p.dielectric:
            bsdf = bsgi.RoughDielectric(p.dielectric[0], p.dielectric[1], p.dielectric[1])
        if p.ggx_anisotropic:
            ax, ay, rotation = p.ggx_anisotropic
            bsdf = bsgi.GgxReflection(ax, ay, [1.0, 1.0, 1.0], rotation=rotation)
        add(p.name, p.corners, albedo=p.albedo, emission=p.emission, receiver=p.receiver, occluder=True, bsdf=bsdf,
            **options.get(p.name, {}))
    return scene


def solved_radiance(scene, solution, pairs):
    """The solution's radiance at each pair's (patch, u, v) towards its direction."""
    out = np.zeros((len(pairs["patch"]), 3))
    for k, (i, uv, d) in enumerate(zip(pairs["patch"], pairs["uv"], pairs["direction"])):
        f = scene.evaluate_surface(int(i), *uv)
        local = np.array([[np.dot(d, f["x"]), np.dot(d, f["y"]), np.dot(d, f["normal"])]])
        out[k] = solution.surfaces[int(i)].evaluate(uv[None], local)[0]
    return out
