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
    if (std::isinf(area) || std::isinf(size))
        throw std::invalid_argument("surface '" + name + "': coordinates too large (its area overflows a double)");
    // Relative to the squared size, so tiny but valid scenes pass and slivers do not.
    if (!(area > 1e-12 * size * size) || !(size > 0))
        throw std::invalid_argument("surface '" + name + "': zero area (degenerate face)");
}

}  // namespace

Vec3 interpolated_shading(const Vec3* corner_normals, const double* w, int corners, const Vec3& geometric) {
    Vec3 n{0, 0, 0};
    for (int c = 0; c < corners; ++c) n += corner_normals[c] * w[c];
    const double l = length(n);
    // (Opposite corner normals cancel; custom normals may point behind the face: flat there.)
    if (!(l > 1e-6) || !(dot(n, geometric) > 1e-6 * l)) return {0, 0, 0};
    return n / l;
}

std::vector<Vec3> checked_corner_normals(const std::string& name, const Vec3* normals, int corners) {
    std::vector<Vec3> out(normals, normals + corners);
    for (Vec3& n : out) {
        const double l = length(n);
        if (!is_finite(n) || !(l > 0))
            throw std::invalid_argument("surface '" + name + "': a corner normal is zero, NaN or infinite");
        n = n / l;
    }
    return out;
}

Frame Surface::frame_from_derivatives(const Vec3& su, const Vec3& sv, const Vec3& fallback_normal) const {
    return local_frame(su, sv, size_, fallback_normal);
}

Vec3 Surface::nudged_normal(double u, double v) const {
    // Step towards the middle of the domain, farther and farther, until s_u x s_v is defined.
    for (double h : {1e-7, 1e-5, 1e-3, 1e-2, 1e-1}) {
        const double un = u + h * (u < 0.5 ? 1 : -1), vn = v + h * (v < 0.5 ? 1 : -1);
        Vec3 su, sv, n;
        first_derivatives(un, vn, su, sv);
        if (normal_from_derivatives(su, sv, size_, n)) return n;
    }
    return {0, 0, 0};
}

void Surface::first_derivatives(double u, double v, Vec3& su, Vec3& sv) const {
    const SurfacePoint s = evaluate(u, v);
    su = s.dpdu;
    sv = s.dpdv;
}

void Surface::into_domain(double& u, double& v) const {
    if (periodic_u()) u -= std::floor(u);
    else u = std::clamp(u, 0.0, 1.0);
    if (periodic_v()) v -= std::floor(v);
    else v = std::clamp(v, 0.0, 1.0);
}

void Surface::project(const Vec3& p, double& u, double& v) const {
    for (int it = 0; it < 12; ++it) {
        const SurfacePoint s = evaluate(u, v);
        const Vec3 r = s.p - p;
        const double a = dot(s.dpdu, s.dpdu), b = dot(s.dpdu, s.dpdv), c = dot(s.dpdv, s.dpdv);
        // A little damping keeps the step finite where s_u or s_v vanishes (poles).
        const double mu = 1e-12 * (a + c) + 1e-300;
        const double det = (a + mu) * (c + mu) - b * b;
        if (!(det > 0)) return;
        const double gu = dot(s.dpdu, r), gv = dot(s.dpdv, r);
        const double du = ((c + mu) * gu - b * gv) / det, dv = ((a + mu) * gv - b * gu) / det;
        u -= du;
        v -= dv;
        into_domain(u, v);
        if (std::abs(du) + std::abs(dv) < 1e-13) return;
    }
}

bool Surface::intersect(const Vec3& o, const Vec3& d, double& u, double& v, double& t) const {
    double uu = u, vv = v, tt = t;
    const double magnitude = size_ + length(o) + length(d) * std::abs(t);
    int stuck = 0;
    double last_residual = 1e300;
    for (int it = 0; it < 24; ++it) {
        const SurfacePoint s = evaluate(uu, vv);
        const Vec3 F = s.p - (o + d * tt);
        const double residual = length(F);
        // Solve [s_u s_v -d] (du, dv, dt) = F.
        const Vec3 c1 = s.dpdu, c2 = s.dpdv, c3 = -d;
        const double det = dot(c1, cross(c2, c3));
        double du, dv, dt;
        if (std::abs(det) > 1e-9 * length(c1) * length(c2) * length(c3)) {
            du = dot(F, cross(c2, c3)) / det;
            dv = dot(c1, cross(F, c3)) / det;
            dt = dot(c1, cross(c2, F)) / det;
        } else {
            // Near a pole or a grazing hit: damped normal equations (J^T J + mu I) x = J^T F.
            const double a11 = dot(c1, c1), a12 = dot(c1, c2), a13 = dot(c1, c3), a22 = dot(c2, c2), a23 = dot(c2, c3),
                         a33 = dot(c3, c3);
            const double mu = 1e-9 * (a11 + a22 + a33) + 1e-300;
            const Vec3 r0{a11 + mu, a12, a13}, r1{a12, a22 + mu, a23}, r2{a13, a23, a33 + mu};
            const Vec3 b{dot(c1, F), dot(c2, F), dot(c3, F)};
            const double dd = dot(r0, cross(r1, r2));
            if (!(std::abs(dd) > 0)) return false;
            // Cramer's rule on the symmetric system (columns equal rows).
            du = dot(b, cross(r1, r2)) / dd;
            dv = dot(r0, cross(b, r2)) / dd;
            dt = dot(r0, cross(r1, b)) / dd;
        }
        if (!std::isfinite(du) || !std::isfinite(dv) || !std::isfinite(dt)) return false;
        const double un = uu - du, vn = vv - dv;
        uu = un, vv = vn, tt -= dt;
        into_domain(uu, vv);
        const bool clamped = (uu != un && !periodic_u()) || (vv != vn && !periodic_v());
        if (residual <= 1e-11 * magnitude && std::abs(du) + std::abs(dv) < 1e-9) {
            u = uu, v = vv, t = tt;
            return in_domain(u, v);
        }
        // Pushed against the edge of the domain without getting closer: the ray misses there.
        stuck = (clamped && residual >= 0.5 * last_residual) ? stuck + 1 : 0;
        if (stuck >= 3) return false;
        last_residual = residual;
    }
    return false;
}

Tessellation Surface::grid_tessellation(const std::vector<double>& pu, const std::vector<double>& pv, bool lifted) const {
    const size_t nu = pu.size(), nv = pv.size();
    std::vector<Vec3> P(nu * nv), N(nu * nv);
    for (size_t j = 0; j < nv; ++j)
        for (size_t i = 0; i < nu; ++i) {
            const SurfacePoint s = evaluate(pu[i], pv[j]);
            P[j * nu + i] = s.p;
            N[j * nu + i] = s.frame.z;
        }
    if (lifted) {
        // Each cell's chord deviation along the normal at its middle, against the diagonal the
        // cell is split along; every vertex rises by twice the largest of its cells'.
        std::vector<double> rise(nu * nv, 0.0);
        for (size_t j = 0; j + 1 < nv; ++j)
            for (size_t i = 0; i + 1 < nu; ++i) {
                const SurfacePoint mid = evaluate(0.5 * (pu[i] + pu[i + 1]), 0.5 * (pv[j] + pv[j + 1]));
                const Vec3 chord = (P[j * nu + i] + P[(j + 1) * nu + i + 1]) * 0.5;
                const double dev = 2 * dot(mid.p - chord, mid.frame.z);
                for (size_t c : {j * nu + i, j * nu + i + 1, (j + 1) * nu + i, (j + 1) * nu + i + 1})
                    if (std::abs(dev) > std::abs(rise[c])) rise[c] = dev;
            }
        for (size_t k = 0; k < P.size(); ++k) P[k] += N[k] * rise[k];
    }
    Tessellation t;
    t.positions.reserve(3 * nu * nv);
    t.uvs.reserve(2 * nu * nv);
    for (size_t j = 0; j < nv; ++j)
        for (size_t i = 0; i < nu; ++i) {
            const Vec3& p = P[j * nu + i];
            t.positions.insert(t.positions.end(), {p.x, p.y, p.z});
            t.uvs.insert(t.uvs.end(), {float(pu[i]), float(pv[j])});
        }
    for (uint32_t j = 0; j + 1 < nv; ++j)
        for (uint32_t i = 0; i + 1 < nu; ++i) {
            const uint32_t a = j * uint32_t(nu) + i, b = a + 1, c = a + uint32_t(nu) + 1, d = a + uint32_t(nu);
            t.triangles.insert(t.triangles.end(), {a, b, c, a, c, d});
        }
    return t;
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
    size_ = std::max(length(p11 - p00), length(p10 - p01));
    // A parallelogram's bilinear map is affine: its two triangles carry exact (u, v).
    parallelogram_ = length((p11 - p10) - (p01 - p00)) <= 1e-12 * size_;
}

BilinearPatch::BilinearPatch(std::string name, const Vec3& p00, const Vec3& p10, const Vec3& p11, const Vec3& p01,
                             const std::array<Vec3, 4>& corner_normals)
    : BilinearPatch(std::move(name), p00, p10, p11, p01) {
    corner_normals_ = checked_corner_normals(this->name(), corner_normals.data(), 4);
}

SurfacePoint BilinearPatch::evaluate(double u, double v) const {
    SurfacePoint s;
    s.p = p00_ * ((1 - u) * (1 - v)) + p10_ * (u * (1 - v)) + p11_ * (u * v) + p01_ * ((1 - u) * v);
    s.dpdu = (p10_ - p00_) * (1 - v) + (p11_ - p01_) * v;
    s.dpdv = (p01_ - p00_) * (1 - u) + (p11_ - p10_) * u;
    s.jacobian = length(cross(s.dpdu, s.dpdv));
    s.frame = frame_from_derivatives(s.dpdu, s.dpdv, mean_normal_);
    if (!corner_normals_.empty()) {
        const double w[4] = {(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v};
        s.shading = interpolated_shading(corner_normals_.data(), w, 4, s.frame.z);
    }
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
            t.positions.insert(t.positions.end(), {p.x, p.y, p.z});
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
    size_ = std::max({length(p1 - p0), length(p2 - p1), length(p0 - p2)});
    check_area(this->name(), area_, size_);
    normal_ = normalize(n);
}

TrianglePatch::TrianglePatch(std::string name, const Vec3& p0, const Vec3& p1, const Vec3& p2,
                             const std::array<Vec3, 3>& corner_normals)
    : TrianglePatch(std::move(name), p0, p1, p2) {
    corner_normals_ = checked_corner_normals(this->name(), corner_normals.data(), 3);
}

SurfacePoint TrianglePatch::evaluate(double u, double v) const {
    SurfacePoint s;
    s.p = p0_ + (p1_ - p0_) * u + (p2_ - p1_) * (u * v);
    s.dpdu = (p1_ - p0_) + (p2_ - p1_) * v;
    s.dpdv = (p2_ - p1_) * u;
    s.jacobian = length(cross(s.dpdu, s.dpdv));
    s.frame = frame_from_derivatives(s.dpdu, s.dpdv, normal_);
    if (!corner_normals_.empty()) {
        // s = (1 - u) p0 + u (1 - v) p1 + u v p2: the barycentric weights.
        const double w[3] = {1 - u, u * (1 - v), u * v};
        s.shading = interpolated_shading(corner_normals_.data(), w, 3, s.frame.z);
    }
    return s;
}

Tessellation TrianglePatch::tessellate() const {
    // (u, v) is not affine over the triangle; refine_parameters recovers it from the hit point.
    Tessellation t;
    for (const Vec3& p : {p0_, p1_, p2_}) t.positions.insert(t.positions.end(), {p.x, p.y, p.z});
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
