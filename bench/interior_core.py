"""The furnished interior (example_blends/interior_layout.py) straight into a bsgi.Scene, without
Blender: for object counts Blender is slow to build, and for the solver's own benchmarks. Every
box face is a quad (6 per box, as a modelled book has them); a metal ball is a box of GGX metal
here (the core has no mesh sphere without Blender); the room's quads face into it. The sun is a
distant light, the sky a constant world.

    python bench/interior_core.py 1000        # prints the scene's counts
"""
from __future__ import annotations

import math
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "example_blends"))
import interior_layout  # noqa: E402

import bsgi  # noqa: E402

SUN_IRRADIANCE = 3.0  # W/m^2 facing the sun, as the .blend's sun of strength 3
SKY_RADIANCE = (0.06, 0.08, 0.12)  # a blue sky of about the .blend's Sky Texture at strength 0.3


def _material(name):
    rgb, metallic, roughness = interior_layout.MATERIALS[name]
    if metallic:
        alpha = roughness * roughness
        return dict(albedo=(0, 0, 0), bsdf=bsgi.GgxReflection(alpha, alpha, list(rgb)))
    return dict(albedo=rgb)


def add_box_per_face(scene: bsgi.Scene, name: str, quads: list, material: dict) -> None:
    """A box's six quads as six bilinear patches, '<name>.<face>'."""
    for f, quad in enumerate(quads):
        scene.add_bilinear_patch(f"{name}.{f}", _patch(quad), emission=(0, 0, 0), **material)


def build_scene(objects: int, add_box=add_box_per_face) -> tuple:
    """(scene, interior): the interior of `objects` objects as a core scene; each box (and ball)
    added by add_box(scene, name, its six quads, its material's keywords)."""
    interior = interior_layout.furnished_interior(objects)
    scene = bsgi.Scene()
    materials = {name: _material(name) for name in interior_layout.MATERIALS}
    for k, (material, quad) in enumerate(interior_layout.room_quads(interior)):
        scene.add_bilinear_patch(f"Room {k}", _patch(quad), emission=(0, 0, 0), **materials[material])
    for thing in interior.things:
        for p, piece in enumerate(thing.pieces):
            if isinstance(piece, interior_layout.Ball):
                piece = interior_layout.Box(piece.centre, (2 * piece.radius,) * 3, piece.material)
            add_box(scene, f"{thing.name} {p}", interior_layout.box_quads(piece), materials[piece.material])
    scene.add_distant_light("Sun", np.array(interior.sun_direction), np.full(3, SUN_IRRADIANCE), math.radians(0.53))
    scene.world_radiance = np.array(SKY_RADIANCE)
    return scene, interior


def _patch(quad):
    """A quad's corners (counter-clockwise) as a bilinear patch's (p00, p10, p11, p01)."""
    return np.array(quad, dtype=float)


if __name__ == "__main__":
    scene, interior = build_scene(int(sys.argv[1]) if len(sys.argv) > 1 else 100)
    print(f"{len(interior.things)} objects, {len(scene)} surfaces, {interior.counts}, "
          f"{interior.length:.1f} x {interior.width:.1f} m")
