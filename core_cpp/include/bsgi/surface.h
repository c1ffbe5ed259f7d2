// Parametric surfaces s(u, v) on [0, 1]^2 with derivatives and the local frame (1)-(3).
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bsgi/frame.h"
#include "bsgi/vec3.h"

namespace bsgi {

struct SurfacePoint {
    Vec3 p;           // position s(u, v)
    Vec3 dpdu, dpdv;  // s_u, s_v
    Frame frame;      // x along s_u, z along s_u x s_v (paper (1)-(3)); orthonormal even where degenerate
    double jacobian;  // |s_u x s_v|: area element of (8)
    // Smooth shading (Cycles' interpolated corner normals of a mesh face): the unit normal on the
    // front side that the light's cosine and a glossy lobe's frame read (radiance_frame); zero
    // where the surface has none (the frame's normal). Rays still leave the geometric surface.
    Vec3 shading{0, 0, 0};
};

inline bool smooth_shaded(const SurfacePoint& s) { return !is_zero(s.shading); }

// The frame a surface's radiance splines are in at s (its glossy ones' angular coordinates): the
// shading frame on a smooth-shaded face (its normal the shading normal, x the frame's x turned
// into its plane), else the frame (1)-(3). The side a direction leaves from stays the geometric
// one (which side of the surface it is on).
inline Frame radiance_frame(const Frame& frame, const Vec3& shading) {
    if (is_zero(shading)) return frame;
    return frame_with_normal(shading, frame.x, frame.y);
}
inline Frame radiance_frame(const SurfacePoint& s) { return radiance_frame(s.frame, s.shading); }

// |cos| between direction d (any length: the cosine is scaled by |d|) and the receiver's normal
// on the side d points into: the geometric side (the sign of d . frame.z) with the shading
// normal's cosine, 0 where the shading normal turns away from d (as Cycles' max(N . L, 0)).
inline double receiver_cosine(const SurfacePoint& s, const Vec3& d) {
    const double geometric = dot(d, s.frame.z);
    if (!smooth_shaded(s)) return std::abs(geometric);
    const double c = dot(d, s.shading);
    return std::max(geometric < 0 ? -c : c, 0.0);
}

// Triangles with the surface parameters at their corners, for the ray caster.
struct Tessellation {
    std::vector<double> positions;  // 3 per vertex (double: the ray scene centres them before going to float)
    std::vector<float> uvs;        // 2 per vertex
    std::vector<uint32_t> triangles;
    // Optional, 3 per triangle: the surface's unit normal on each triangle, used instead of the
    // winding normal (e.g. where a triangle has no area). Empty: the winding normal.
    std::vector<float> normals;
};

class Surface {
public:
    explicit Surface(std::string name) : name_(std::move(name)) {}
    virtual ~Surface() = default;

    const std::string& name() const { return name_; }
    virtual SurfacePoint evaluate(double u, double v) const = 0;
    // Parameter-domain mask chi of (8): false where (u, v) is not part of the surface.
    virtual bool in_domain(double /*u*/, double /*v*/) const { return true; }
    virtual Tessellation tessellate() const = 0;
    // Triangles for ray casting. Curved surfaces may stand them off the surface, on its convex
    // side, so that a ray reaching the surface meets a triangle first and Newton's method
    // (intersect()) finds the exact hit; by default the tessellation itself.
    virtual Tessellation tessellate_for_rays() const { return tessellate(); }
    // Exact parameters of a point on the surface, from the tessellation's interpolated guess.
    virtual void refine_parameters(const Vec3& /*p*/, double& /*u*/, double& /*v*/) const {}
    virtual double area() const = 0;

    // A length typical of the surface (its bounding-box diagonal): the scale of its derivatives
    // on [0, 1]^2, against which "vanishing" is judged.
    double size() const { return size_; }
    // True when the tessellation is the surface itself and its (u, v) are linear on each
    // triangle (meshes, parallelograms): ray hits need no refinement.
    virtual bool tessellation_is_exact() const { return false; }
    // Cyclic directions: parameters wrap around instead of stopping at 0 and 1.
    virtual bool periodic_u() const { return false; }
    virtual bool periodic_v() const { return false; }
    // Parameter values (normalised, inside (0, 1)) of the lines u = c (first) and v = c (second)
    // across which the normal jumps, a crease of the surface: integrals over it split there.
    virtual std::array<std::vector<double>, 2> creases() const { return {}; }
    // True where evaluate() gives shading normals (smooth-shaded faces): ray hits then look them up.
    virtual bool has_shading_normals() const { return false; }

    // Intersection of the ray o + t d with the exact surface near the guess (u, v, t), by
    // Newton's method on s(u, v) = o + t d. Returns false (leaving the guess) when it does not
    // converge inside the parameter domain, e.g. where the tessellation overhangs the surface.
    virtual bool intersect(const Vec3& o, const Vec3& d, double& u, double& v, double& t) const;

protected:
    // The frame of (1)-(3) where it is defined; where s_u or s_u x s_v vanishes (a collapsed edge,
    // a pole) the frame is built around `fallback_normal` instead.
    Frame frame_from_derivatives(const Vec3& su, const Vec3& sv, const Vec3& fallback_normal) const;
    // Normal near (u, v), nudged towards the middle of the domain: the limit normal at points
    // where s_u x s_v vanishes. Zero if there is none nearby either.
    Vec3 nudged_normal(double u, double v) const;
    // s_u and s_v alone (no frame): what nudged_normal() looks at. By default from evaluate();
    // surfaces whose evaluate() relies on nudged_normal() must override it.
    virtual void first_derivatives(double u, double v, Vec3& su, Vec3& sv) const;
    // Closest point on the surface to p from the guess (u, v): Gauss-Newton on |s(u, v) - p|^2.
    void project(const Vec3& p, double& u, double& v) const;
    // Wraps periodic parameters into [0, 1), clamps the others to [0, 1].
    void into_domain(double& u, double& v) const;
    // Triangles over the grid of parameters pu x pv (each increasing from 0 to 1), their vertices
    // on the surface; lifted: raised to the convex side by twice the largest chord deviation of
    // their cells, so that the triangles enclose the surface where it is convex (spheres,
    // cylinders) and rays cannot slip between them and the surface at silhouettes.
    Tessellation grid_tessellation(const std::vector<double>& pu, const std::vector<double>& pv, bool lifted) const;

    double size_ = 1;

private:
    std::string name_;
};

// s(u, v) = (1-u)(1-v) p00 + u(1-v) p10 + u v p11 + (1-u) v p01: quads and parallelograms.
class BilinearPatch final : public Surface {
public:
    BilinearPatch(std::string name, const Vec3& p00, const Vec3& p10, const Vec3& p11, const Vec3& p01);
    // With smooth shading: the corners' normals (as the corners), interpolated bilinearly.
    BilinearPatch(std::string name, const Vec3& p00, const Vec3& p10, const Vec3& p11, const Vec3& p01,
                  const std::array<Vec3, 4>& corner_normals);
    SurfacePoint evaluate(double u, double v) const override;
    Tessellation tessellate() const override;
    void refine_parameters(const Vec3& p, double& u, double& v) const override;
    double area() const override { return area_; }
    bool tessellation_is_exact() const override { return parallelogram_; }
    bool has_shading_normals() const override { return !corner_normals_.empty(); }

private:
    Vec3 p00_, p10_, p11_, p01_;
    bool parallelogram_;
    Vec3 mean_normal_;
    double area_;
    std::vector<Vec3> corner_normals_;  // p00's, p10's, p11's, p01's; empty: flat
};

// s(u, v) = p0 + u (p1 - p0) + u v (p2 - p1): the unit square onto a triangle, the edge u = 0
// collapsed into p0. Keeps the whole square as spline domain (no mask needed).
class TrianglePatch final : public Surface {
public:
    TrianglePatch(std::string name, const Vec3& p0, const Vec3& p1, const Vec3& p2);
    // With smooth shading: the corners' normals, interpolated barycentrically (as Cycles does).
    TrianglePatch(std::string name, const Vec3& p0, const Vec3& p1, const Vec3& p2, const std::array<Vec3, 3>& corner_normals);
    SurfacePoint evaluate(double u, double v) const override;
    Tessellation tessellate() const override;
    void refine_parameters(const Vec3& p, double& u, double& v) const override;
    double area() const override { return area_; }
    bool has_shading_normals() const override { return !corner_normals_.empty(); }

private:
    Vec3 p0_, p1_, p2_;
    Vec3 normal_;
    double area_;
    std::vector<Vec3> corner_normals_;  // p0's, p1's, p2's; empty: flat
};

// The unit shading normal from corner normals weighted by w (the point's interpolation weights),
// or zero (flat) where the interpolation vanishes or turns to the back of the geometric normal.
Vec3 interpolated_shading(const Vec3* corner_normals, const double* w, int corners, const Vec3& geometric);
// The corner normals given to a surface, checked (finite, non-zero) and made unit; names the
// surface in the error.
std::vector<Vec3> checked_corner_normals(const std::string& name, const Vec3* normals, int corners);

}  // namespace bsgi
