#include "bsgi/surface.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bsgi {

namespace {

void check_corners(const std::string& name, std::initializer_list<Vec3> corners) {
    for (const Vec3& c : corners)
        if (!is_finite(c)) throw std::invalid_argument("surface '" + name + "': a vertex is NaN or infinite");
}

void check_area(const std::string& name, double area, double size) {
    // Relative to the squared size, so tiny but valid scenes pass and slivers do not.
    if (!(area > 1e-12 * size * size) || !(size > 0))
        throw std::invalid_argument("surface '" + name + "': zero area (degenerate face)");
}

}  // namespace

Frame Surface::frame_from_derivatives(const Vec3& su, const Vec3& sv, const Vec3& fallback_normal) {
    const Vec3 n = cross(su, sv);
    const double ln = length(n), lu = length(su);
    if (!(ln > 1e-14 * std::max(1e-300, lu * length(sv)))) return Frame::from_normal(fallback_normal);
    Frame f;
    f.z = n / ln;
    f.x = su / lu;
    f.y = cross(f.z, f.x);
    return f;
}

BilinearPatch::BilinearPatch(std::string name, const Vec3& p00, const Vec3& p10, const Vec3& p11, const Vec3& p01)
    : Surface(std::move(name)), p00_(p00), p10_(p10), p11_(p11), p01_(p01) {
    check_corners(this->name(), {p00, p10, p11, p01});
    // Area of a bilinear patch: 2x2 Gauss quadrature of |s_u x s_v| (exact for planar patches).
    const double g = 0.5 / std::sqrt(3.0);
    area_ = 0;
    for (double u : {0.5 - g, 0.5 + g})
        for (double v : {0.5 - g, 0.5 + g}) area_ += 0.25 * evaluate(u, v).jacobian;
    const double size = std::max({length(p10 - p00), length(p11 - p10), length(p01 - p11), length(p00 - p01)});
    check_area(this->name(), area_, size);
    mean_normal_ = normalize(cross(p11 - p00, p01 - p10));
}

SurfacePoint BilinearPatch::evaluate(double u, double v) const {
    SurfacePoint s;
    s.p = p00_ * ((1 - u) * (1 - v)) + p10_ * (u * (1 - v)) + p11_ * (u * v) + p01_ * ((1 - u) * v);
    s.dpdu = (p10_ - p00_) * (1 - v) + (p11_ - p01_) * v;
    s.dpdv = (p01_ - p00_) * (1 - u) + (p11_ - p10_) * u;
    s.jacobian = length(cross(s.dpdu, s.dpdv));
    s.frame = frame_from_derivatives(s.dpdu, s.dpdv, mean_normal_);
    return s;
}

Tessellation BilinearPatch::tessellate() const {
    // Planar patches are exact with two triangles; twisted ones get a grid, refined by Newton.
    const bool planar = std::abs(dot(p11_ - p00_, normalize(cross(p10_ - p00_, p01_ - p00_)))) <
                        1e-9 * std::max(length(p11_ - p00_), 1e-300);
    const int n = planar ? 1 : 8;
    Tessellation t;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const double u = double(i) / n, v = double(j) / n;
            const Vec3 p = evaluate(u, v).p;
            t.positions.insert(t.positions.end(), {float(p.x), float(p.y), float(p.z)});
            t.uvs.insert(t.uvs.end(), {float(u), float(v)});
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
            t.triangles.insert(t.triangles.end(), {a, b, c, a, c, d});
        }
    return t;
}

void BilinearPatch::refine_parameters(const Vec3& p, double& u, double& v) const {
    // Gauss-Newton on |s(u, v) - p|^2: converges in a few steps from the tessellated guess.
    for (int it = 0; it < 6; ++it) {
        const SurfacePoint s = evaluate(u, v);
        const Vec3 r = s.p - p;
        const double a = dot(s.dpdu, s.dpdu), b = dot(s.dpdu, s.dpdv), c = dot(s.dpdv, s.dpdv);
        const double det = a * c - b * b;
        if (!(det > 0)) return;
        const double gu = dot(s.dpdu, r), gv = dot(s.dpdv, r);
        const double du = (c * gu - b * gv) / det, dv = (a * gv - b * gu) / det;
        u = std::clamp(u - du, 0.0, 1.0);
        v = std::clamp(v - dv, 0.0, 1.0);
        if (std::abs(du) + std::abs(dv) < 1e-12) return;
    }
}

TrianglePatch::TrianglePatch(std::string name, const Vec3& p0, const Vec3& p1, const Vec3& p2)
    : Surface(std::move(name)), p0_(p0), p1_(p1), p2_(p2) {
    check_corners(this->name(), {p0, p1, p2});
    const Vec3 n = cross(p1 - p0, p2 - p0);
    area_ = 0.5 * length(n);
    check_area(this->name(), area_, std::max({length(p1 - p0), length(p2 - p1), length(p0 - p2)}));
    normal_ = normalize(n);
}

SurfacePoint TrianglePatch::evaluate(double u, double v) const {
    SurfacePoint s;
    s.p = p0_ + (p1_ - p0_) * u + (p2_ - p1_) * (u * v);
    s.dpdu = (p1_ - p0_) + (p2_ - p1_) * v;
    s.dpdv = (p2_ - p1_) * u;
    s.jacobian = length(cross(s.dpdu, s.dpdv));
    s.frame = frame_from_derivatives(s.dpdu, s.dpdv, normal_);
    return s;
}

Tessellation TrianglePatch::tessellate() const {
    // (u, v) is not affine over the triangle; refine_parameters recovers it from the hit point.
    Tessellation t;
    for (const Vec3& p : {p0_, p1_, p2_}) t.positions.insert(t.positions.end(), {float(p.x), float(p.y), float(p.z)});
    t.uvs = {0.f, 0.5f, 1.f, 0.f, 1.f, 1.f};
    t.triangles = {0, 1, 2};
    return t;
}

void TrianglePatch::refine_parameters(const Vec3& p, double& u, double& v) const {
    // Barycentric coordinates (b1, b2) of p: u = b1 + b2, v = b2 / (b1 + b2).
    const Vec3 e1 = p1_ - p0_, e2 = p2_ - p0_, d = p - p0_;
    const double a = dot(e1, e1), b = dot(e1, e2), c = dot(e2, e2), det = a * c - b * b;
    const double r1 = dot(e1, d), r2 = dot(e2, d);
    const double b1 = (c * r1 - b * r2) / det, b2 = (a * r2 - b * r1) / det;
    u = std::clamp(b1 + b2, 0.0, 1.0);
    v = u > 1e-12 ? std::clamp(b2 / (b1 + b2), 0.0, 1.0) : 0.5;
}

}  // namespace bsgi
