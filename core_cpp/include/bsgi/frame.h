// Robust local frames (paper (1)-(3)) at any surface point, degenerate ones included.
//
// Where s_u x s_v is defined the frame is exactly (1)-(3). Where it vanishes (a collapsed row of
// control points at the pole of a NURBS sphere, a zero-area face, s_u parallel to s_v) the
// normal is taken from the caller's limit normal, and x stays as close to s_u as possible.
// The result is always orthonormal and finite: never NaN, whatever the input.
#pragma once
#include <cmath>

#include "bsgi/vec3.h"

namespace bsgi {

// Derivatives shorter than this fraction of the surface's scale count as vanished. Near a pole
// s_v shrinks linearly with the distance to it; below 1e-10 of the scale its direction is
// rounding noise.
constexpr double kVanishingDerivative = 1e-10;

// Unit vector along a, or false when a is zero, tiny against `scale`, or not finite.
inline bool unit_or_fail(const Vec3& a, double scale, Vec3& out) {
    const double l = length(a);
    if (!(l > kVanishingDerivative * scale) || !std::isfinite(l)) return false;
    out = a / l;
    return is_finite(out);
}

// Normal z_S of (2) if s_u x s_v is well defined, relative to `scale` (a length typical of
// |s_u| and |s_v| on this surface, e.g. its size for parameters on [0, 1]).
inline bool normal_from_derivatives(const Vec3& su, const Vec3& sv, double scale, Vec3& n) {
    const Vec3 c = cross(su, sv);
    const double lc = length(c);
    // Both absolutely (a vanishing derivative) and relatively (s_u parallel to s_v).
    if (!(lc > kVanishingDerivative * scale * scale) || !(lc > 1e-12 * length(su) * length(sv))) return false;
    n = c / lc;
    return is_finite(n);
}

// The frame with normal z (unit), x along the first usable tangent candidate: s_u, then
// `limit_su` (the direction s_u takes in the limit where it vanishes), then the direction
// perpendicular to s_v, then any.
inline Frame frame_with_normal(const Vec3& z, const Vec3& su, const Vec3& sv, const Vec3& limit_su = {}) {
    const Vec3 candidates[3] = {su, limit_su, cross(sv, z)};
    for (const Vec3& c : candidates) {
        const double lc = length(c);
        if (!(lc > 0) || !std::isfinite(lc)) continue;
        const Vec3 t = c - z * dot(c, z);
        const double lt = length(t);
        if (!(lt > 1e-6 * lc)) continue;  // c is (nearly) along the normal
        Frame f;
        f.z = z;
        f.x = t / lt;
        f.y = cross(f.z, f.x);
        if (is_finite(f.x) && is_finite(f.y)) return f;
    }
    return Frame::from_normal(z);
}

// Frame (1)-(3) from s_u, s_v; at degenerate points the normal is `limit_normal` (need not be
// unit; if it is unusable too, +z).
inline Frame local_frame(const Vec3& su, const Vec3& sv, double scale, const Vec3& limit_normal,
                         const Vec3& limit_su = {}) {
    Vec3 z;
    if (!normal_from_derivatives(su, sv, scale, z) && !unit_or_fail(limit_normal, 0.0, z)) z = {0, 0, 1};
    return frame_with_normal(z, su, sv, limit_su);
}

}  // namespace bsgi
