"""Quads of simple shapes, with no Blender in them (the example generators and the core-only
benchmark scenes share them)."""
from __future__ import annotations

import math


def rectangle(cx, cy, z, sx, sy):
    """Corners of an axis-aligned rectangle at height z, facing +z."""
    a, b = sx / 2, sy / 2
    return [(cx - a, cy - b, z), (cx + a, cy - b, z), (cx + a, cy + b, z), (cx - a, cy + b, z)]


def box_quads(cx, cy, sx, sy, h, angle, z0=0.0):
    """A closed box standing at height z0, rotated by angle about z, outward normals."""
    c, s = math.cos(angle), math.sin(angle)

    def p(x, y, z):
        return (cx + c * x - s * y, cy + s * x + c * y, z0 + z)

    a, b = sx / 2, sy / 2
    bottom = [p(-a, -b, 0), p(-a, b, 0), p(a, b, 0), p(a, -b, 0)]
    top = [p(-a, -b, h), p(a, -b, h), p(a, b, h), p(-a, b, h)]
    sides = [
        [p(-a, -b, 0), p(a, -b, 0), p(a, -b, h), p(-a, -b, h)],
        [p(a, -b, 0), p(a, b, 0), p(a, b, h), p(a, -b, h)],
        [p(a, b, 0), p(-a, b, 0), p(-a, b, h), p(a, b, h)],
        [p(-a, b, 0), p(-a, -b, 0), p(-a, -b, h), p(-a, b, h)],
    ]
    return [bottom, top] + sides
