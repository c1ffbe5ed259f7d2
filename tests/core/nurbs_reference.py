"""Independent references for NURBS surfaces: scipy's NdBSpline on homogeneous coordinates, and
the control net of Blender's NURBS sphere primitive and of shapes revolved like it, and the light
of a "drop" (a hemisphere under a cone) by quadrature of the analytic surfaces."""
import numpy as np
from scipy.interpolate import NdBSpline


def scipy_nurbs(points, count_u, count_v, knots_u, knots_v, order_u, order_v, cyclic_u, cyclic_v):
    """A function (u, v, du=0, dv=0) -> homogeneous derivative (4,) of the surface, at knot
    parameters. points: (count_u * count_v, 4) = (x, y, z, w), u fastest."""
    pts = np.asarray(points, float).reshape(count_v, count_u, 4)
    hom = np.concatenate([pts[..., :3] * pts[..., 3:], pts[..., 3:]], axis=-1)  # (w x, w y, w z, w)
    if cyclic_u:  # basis functions past the last point reuse the first ones
        hom = np.concatenate([hom, hom[:, : order_u - 1]], axis=1)
    if cyclic_v:
        hom = np.concatenate([hom, hom[: order_v - 1]], axis=0)
    spline = NdBSpline((np.asarray(knots_u), np.asarray(knots_v)), hom.transpose(1, 0, 2), (order_u - 1, order_v - 1))
    return lambda x, y, du=0, dv=0: spline([[x, y]], nu=(du, dv))[0]


def rational_derivatives(f, x, y, wu, wv):
    """Position, s_u, s_v, s_uv from homogeneous derivatives (quotient rule), scaled to
    normalised parameters (wu, wv: widths of the evaluation range)."""
    A, Au, Av, Auv = f(x, y), f(x, y, 1, 0), f(x, y, 0, 1), f(x, y, 1, 1)
    W, Wu, Wv, Wuv = A[3], Au[3], Av[3], Auv[3]
    p = A[:3] / W
    su = (Au[:3] - p * Wu) / W
    sv = (Av[:3] - p * Wv) / W
    suv = (Auv[:3] - p * Wuv - su * Wv - sv * Wu) / W
    return p, su * wu, sv * wv, suv * wu * wv


def blender_sphere_points(radius=1.0):
    """Control net of Blender's `primitive_nurbs_surface_sphere_add`: a semicircle of 5 points
    in u (order 3, endpoint + Bezier) swept by a circle of 8 points in v (order 3, cyclic +
    Bezier + endpoint), as read from Blender 5.0."""
    h = np.sqrt(0.5)
    return revolved_points([(0, -1, 1), (1, -1, h), (1, 0, 1), (1, 1, h), (0, 1, 1)], radius)


def revolved_points(profile, radius=1.0):
    """The control net of a profile of 5 (r, z, weight) points (two quadratic Bezier pieces, as
    the sphere's semicircle) swept by the sphere's circle of 8 points: SPHERE_FLAGS apply."""
    h = np.sqrt(0.5)
    ring = [(-1, 0, 1), (-1, -1, h), (0, -1, 1), (1, -1, h), (1, 0, 1), (1, 1, h), (0, 1, 1), (-1, 1, h)]  # (x, y, w)
    pts = [[radius * r * c, radius * r * s, radius * z, w * wr] for (c, s, wr) in ring for (r, z, w) in profile]
    return np.array(pts, float)


SPHERE_FLAGS = dict(count_u=5, count_v=8, order_u=3, order_v=3, endpoint_u=True, endpoint_v=True,
                    bezier_u=True, bezier_v=True, cyclic_u=False, cyclic_v=True)


def drop_points(radius, apex):
    """The control net of a "drop" centred at the origin: Blender's sphere net with its upper
    arc replaced by a straight cone to an apex `apex` radii up (SPHERE_FLAGS apply)."""
    h = np.sqrt(0.5)
    return revolved_points([(0, -1, 1), (1, -1, h), (1, 0, 1), (0.5, apex / 2, 1), (0, apex, 1)], radius)


def globe_points(radius, apex):
    """A light bulb's globe and neck centred at the origin: a sphere's arc from its lower pole up
    to 30 degrees above its equator (one rational quadratic piece, weight cos 60 degrees), then
    a straight cone to an apex `apex` radii up, a crease between (convex for apex >= 1.2).
    Its first knot span turns by 150 degrees around the axis (SPHERE_FLAGS apply)."""
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    return revolved_points([(0, -1, 1), (np.sqrt(3), -1, 0.5), (c, s, 1), (c / 2, (s + apex) / 2, 1), (0, apex, 1)],
                           radius)


def drop_irradiance(x, radius, apex, centre_height, n=1000):
    """E / L at (x, 0, 0) on a floor facing up, from a convex "drop": a lower hemisphere of the
    radius and a cone from its equator to an apex `apex` radii above the centre (a crease where
    they meet). The midpoint rule over the analytic surfaces; convex, so nothing shadows itself."""
    phi = (np.arange(n) + 0.5) / n * 2 * np.pi
    s = (np.arange(n) + 0.5) / n

    def part(pos, nrm, area):
        d = pos - np.array([x, 0.0, 0.0])
        r2 = (d * d).sum(-1)
        cos_r = np.clip(d[..., 2], 0, None) / np.sqrt(r2)
        cos_e = np.clip(-(d * nrm).sum(-1), 0, None) / np.sqrt(r2)
        return (cos_r * cos_e / r2 * area).sum()

    theta, p = np.meshgrid(s * np.pi / 2, phi, indexing="ij")  # polar angle from the south pole
    nrm = np.stack([np.sin(theta) * np.cos(p), np.sin(theta) * np.sin(p), -np.cos(theta)], -1)
    sphere = part(radius * nrm + [0, 0, centre_height], nrm, radius**2 * np.sin(theta) * (np.pi / 2 / n) * (2 * np.pi / n))
    t, p = np.meshgrid(s, phi, indexing="ij")  # from the rim to the apex
    ring = radius * (1 - t)
    pos = np.stack([ring * np.cos(p), ring * np.sin(p), centre_height + radius * apex * t], -1)
    nrm = np.stack([apex * np.cos(p), apex * np.sin(p), np.ones_like(p)], -1) / np.hypot(1, apex)
    cone = part(pos, nrm, ring * (2 * np.pi / n) * radius * np.hypot(1, apex) / n)
    return sphere + cone
