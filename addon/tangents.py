"""The direction of an anisotropic lobe as Blender renders it, for the solver's GGX.

Cycles gives an anisotropic BSDF whose Tangent input is not connected the Tangent node's radial
tangent about the object's local Z axis: the generated texture coordinates' (-y, x, 0) about the
centre of the object's bounding box (the automatic texture space), carried to world space as a
normal, projected onto the surface. The core turns each surface's own tangent ds/du by a rotation instead; this module
finds the rotation that turns ds/du onto Blender's tangent. No bpy: the caller passes the
object's matrix and bounding box."""
from __future__ import annotations

import numpy as np

# Across one surface the solver's lobe keeps one direction relative to ds/du; Blender's tangent
# may turn relative to it (a sphere's parallels against a mesh face's edge). Beyond this spread
# the solved lobe is said to differ from Blender's.
MAX_SPREAD_DEGREES = 15.0


class RadialTangent:
    """Blender's default tangent of one object: radial about its local Z axis."""

    def __init__(self, matrix, bound_box):
        m = np.asarray(matrix, float)
        box = np.asarray(bound_box, float)
        self.linear, self.offset = m[:3, :3], m[:3, 3]
        # pinv: an object scaled flat has no inverse; the export refuses it by name afterwards.
        self.inverse = np.linalg.pinv(self.linear)
        lo, hi = box.min(0), box.max(0)
        self.centre, self.half = (lo + hi) / 2, np.maximum((hi - lo) / 2, 1e-30)

    def at(self, points) -> np.ndarray:
        """World-space tangent directions (not yet projected onto a surface) at world points."""
        local = (np.asarray(points, float) - self.offset) @ self.inverse.T
        g = (local - self.centre) / self.half
        # Cycles carries the direction to world space as it does normals (by the inverse transpose
        # of the object's matrix), which matters under uneven scale: measured, see test_tangents.
        return np.stack([-g[:, 1], g[:, 0], np.zeros(len(g))], axis=1) @ self.inverse


def rotation_onto(tangents, x, y):
    """The rotation about the normal that turns the frame's x onto the tangents (the lobe is
    symmetric under t -> -t, so angles are averaged doubled), and the largest deviation from
    it, both in radians. Samples where the tangent has no component in the plane (on the axis)
    are left out; (0, 0) if none is left."""
    tx, ty = np.einsum("ij,ij->i", tangents, x), np.einsum("ij,ij->i", tangents, y)
    keep = np.hypot(tx, ty) > 1e-9 * max(float(np.abs(tangents).max(initial=0.0)), 1e-300)
    if not keep.any():
        return 0.0, 0.0
    doubled = 2 * np.arctan2(ty[keep], tx[keep])
    mean = np.arctan2(np.sin(doubled).sum(), np.cos(doubled).sum())
    deviation = np.abs(np.angle(np.exp(1j * (doubled - mean)))) / 2
    return float(mean / 2), float(deviation.max())


def surface_rotation(radial: RadialTangent, surface, samples: int = 5):
    """rotation_onto over a samples x samples grid of a bsgi surface's parameters."""
    g = (np.arange(samples) + 0.5) / samples
    uv = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    frames = surface.evaluate(uv)
    return rotation_onto(radial.at(frames["position"]), frames["x"], frames["y"])
