"""Closed-form radiometry used as independent references by the tests."""
import numpy as np


def polygon_irradiance(point, normal, polygon, radiance=1.0):
    """Irradiance at `point` (surface normal `normal`) from a Lambertian polygon of uniform
    `radiance`, unoccluded, all of it above the point's tangent plane: Lambert's contour formula
    E = L/2 * sum_i Theta_i (g_i . n), Theta_i the angle edge i subtends, g_i the unit normal of
    the plane through the point and the edge."""
    x = np.asarray(point, float)
    n = np.asarray(normal, float)
    vs = [np.asarray(v, float) - x for v in polygon]
    total = 0.0
    for a, b in zip(vs, vs[1:] + vs[:1]):
        cross = np.cross(a, b)
        angle = np.arccos(np.clip(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)), -1, 1))
        total += angle * np.dot(cross / np.linalg.norm(cross), n)
    return radiance * abs(total) / 2.0


def rectangle_minus_rectangle(rect, hole):
    """The axis-aligned rectangle `rect` = (x0, x1, y0, y1) minus `hole` (same form): at most four
    disjoint rectangles (full-height slabs left and right of the hole, then the parts below and
    above it between them)."""
    x0, x1, y0, y1 = rect
    hx0, hx1 = max(hole[0], x0), min(hole[1], x1)
    hy0, hy1 = max(hole[2], y0), min(hole[3], y1)
    if hx0 >= hx1 or hy0 >= hy1:
        return [rect]
    pieces = [(x0, hx0, y0, y1), (hx1, x1, y0, y1), (hx0, hx1, y0, hy0), (hx0, hx1, hy1, y1)]
    return [p for p in pieces if p[1] > p[0] and p[3] > p[2]]


def shadowed_square_irradiance(x, y, light, light_height, occluder, occluder_height, radiance=1.0):
    """Irradiance at (x, y, 0) on an upward-facing floor from a Lambertian axis-aligned rectangle
    `light` = (x0, x1, y0, y1) at light_height facing down, partly hidden by an opaque axis-aligned
    rectangle `occluder` parallel to it at occluder_height (0 < occluder_height < light_height).
    Seen from the point, the occluder covers its central projection onto the light's plane (a
    rectangle scaled by light_height / occluder_height about the point); Lambert's formula summed
    over the visible rest, which is a union of rectangles."""
    s = light_height / occluder_height
    hole = (x + s * (occluder[0] - x), x + s * (occluder[1] - x), y + s * (occluder[2] - y), y + s * (occluder[3] - y))
    point, normal = np.array([x, y, 0.0]), np.array([0.0, 0.0, 1.0])
    total = 0.0
    for x0, x1, y0, y1 in rectangle_minus_rectangle(light, hole):
        corners = [np.array(c + (light_height,)) for c in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))]
        total += polygon_irradiance(point, normal, corners, radiance)
    return total


def directional_albedo(bsdf, mu, n=400):
    """Integral of rho cos over the incoming hemisphere, light leaving at cos theta = mu, per
    channel: a midpoint rule in cos^2 theta and phi (cosine-weighted), independent of the core's
    tables (a narrow lobe needs n of 1,000 near the normal)."""
    g = (np.arange(n) + 0.5) / n
    c2, phi = np.meshgrid(g, 2 * np.pi * (np.arange(2 * n) + 0.5) / (2 * n), indexing="ij")
    cos_i, sin_i = np.sqrt(c2).ravel(), np.sqrt(1 - c2).ravel()
    wi = np.stack([sin_i * np.cos(phi.ravel()), sin_i * np.sin(phi.ravel()), cos_i], 1)
    wo = np.ascontiguousarray(np.broadcast_to([np.sqrt(1 - mu * mu), 0.0, mu], wi.shape))
    return np.pi * bsdf.eval(wo, wi).mean(axis=0)
