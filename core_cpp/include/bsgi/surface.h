// Parametric surfaces s(u, v) on [0, 1]^2 with derivatives and the local frame (1)-(3).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bsgi/vec3.h"

namespace bsgi {

struct SurfacePoint {
    Vec3 p;           // position s(u, v)
    Vec3 dpdu, dpdv;  // s_u, s_v
    Frame frame;      // x along s_u, z along s_u x s_v (paper (1)-(3)); orthonormal even where degenerate
    double jacobian;  // |s_u x s_v|: area element of (8)
};

// Triangles with the surface parameters at their corners, for the ray caster.
struct Tessellation {
    std::vector<float> positions;  // 3 per vertex
    std::vector<float> uvs;        // 2 per vertex
    std::vector<uint32_t> triangles;
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
    // Exact parameters of a point on the surface, from the tessellation's interpolated guess.
    virtual void refine_parameters(const Vec3& /*p*/, double& /*u*/, double& /*v*/) const {}
    virtual double area() const = 0;

protected:
    // The frame of (1)-(3) where it is defined; where s_u or s_u x s_v vanishes (a collapsed edge,
    // a pole) the frame is built around `fallback_normal` instead.
    static Frame frame_from_derivatives(const Vec3& su, const Vec3& sv, const Vec3& fallback_normal);

private:
    std::string name_;
};

// s(u, v) = (1-u)(1-v) p00 + u(1-v) p10 + u v p11 + (1-u) v p01: quads and parallelograms.
class BilinearPatch final : public Surface {
public:
    BilinearPatch(std::string name, const Vec3& p00, const Vec3& p10, const Vec3& p11, const Vec3& p01);
    SurfacePoint evaluate(double u, double v) const override;
    Tessellation tessellate() const override;
    void refine_parameters(const Vec3& p, double& u, double& v) const override;
    double area() const override { return area_; }

private:
    Vec3 p00_, p10_, p11_, p01_;
    Vec3 mean_normal_;
    double area_;
};

// s(u, v) = p0 + u (p1 - p0) + u v (p2 - p1): the unit square onto a triangle, the edge u = 0
// collapsed into p0. Keeps the whole square as spline domain (no mask needed).
class TrianglePatch final : public Surface {
public:
    TrianglePatch(std::string name, const Vec3& p0, const Vec3& p1, const Vec3& p2);
    SurfacePoint evaluate(double u, double v) const override;
    Tessellation tessellate() const override;
    void refine_parameters(const Vec3& p, double& u, double& v) const override;
    double area() const override { return area_; }

private:
    Vec3 p0_, p1_, p2_;
    Vec3 normal_;
    double area_;
};

}  // namespace bsgi
