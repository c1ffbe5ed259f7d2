#include "bsgi/disk_patch.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bsgi {

namespace {
constexpr double kTwoPi = 6.283185307179586;
}

DiskPatch::DiskPatch(std::string name, const Vec3& center, const Vec3& axis_a, const Vec3& axis_b)
    : Surface(std::move(name)), c_(center), a_(axis_a), b_(axis_b) {
    for (const Vec3& x : {center, axis_a, axis_b})
        if (!is_finite(x)) throw std::invalid_argument("surface '" + this->name() + "': a point is NaN or infinite");
    const Vec3 n = cross(a_, b_);
    size_ = 2 * std::max(length(a_), length(b_));
    area_ = kTwoPi / 2 * length(n);
    if (!(length(n) > 1e-12 * size_ * size_))
        throw std::invalid_argument("surface '" + this->name() + "': zero area (degenerate disc)");
    normal_ = normalize(n);
}

SurfacePoint DiskPatch::evaluate(double u, double v) const {
    const double c = std::cos(kTwoPi * v), s = std::sin(kTwoPi * v);
    SurfacePoint p;
    p.dpdu = a_ * c + b_ * s;
    p.dpdv = (b_ * c - a_ * s) * (kTwoPi * u);
    p.p = c_ + p.dpdu * u;
    p.jacobian = length(cross(p.dpdu, p.dpdv));
    p.frame = frame_from_derivatives(p.dpdu, p.dpdv, normal_);
    return p;
}

Tessellation DiskPatch::tessellate() const {
    // A fan; each triangle has its own centre vertex with the angle of its middle, so that the
    // interpolated v stays inside the triangle's range (refine_parameters makes it exact).
    const int n = 64;
    Tessellation t;
    for (int k = 0; k < n; ++k) {
        const double v0 = double(k) / n, v1 = double(k + 1) / n;
        const Vec3 pts[3] = {c_, evaluate(1, v0).p, evaluate(1, v1).p};
        const double uvs[6] = {0, 0.5 * (v0 + v1), 1, v0, 1, v1};
        for (int i = 0; i < 3; ++i) {
            t.positions.insert(t.positions.end(), {pts[i].x, pts[i].y, pts[i].z});
            t.uvs.insert(t.uvs.end(), {float(uvs[2 * i]), float(uvs[2 * i + 1])});
        }
        t.triangles.insert(t.triangles.end(), {uint32_t(3 * k), uint32_t(3 * k + 1), uint32_t(3 * k + 2)});
    }
    return t;
}

void DiskPatch::refine_parameters(const Vec3& p, double& u, double& v) const {
    // Coordinates (x, y) of p - c in the (a, b) basis: u = |(x, y)|, v = angle / 2 pi.
    const Vec3 d = p - c_;
    const double aa = dot(a_, a_), ab = dot(a_, b_), bb = dot(b_, b_), det = aa * bb - ab * ab;
    const double ra = dot(a_, d), rb = dot(b_, d);
    const double x = (bb * ra - ab * rb) / det, y = (aa * rb - ab * ra) / det;
    u = std::min(1.0, std::sqrt(x * x + y * y));
    v = std::atan2(y, x) / kTwoPi;
    if (v < 0) v += 1;
}

}  // namespace bsgi
