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
