#include "bsgi/split_piece.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bsgi {

BoundaryCurve::BoundaryCurve(double u0, double u1, std::vector<double> samples)
    : u0_(u0), u1_(u1), samples_(std::move(samples)) {}

double BoundaryCurve::evaluate(double u, double& derivative) const {
    const size_t m = samples_.size() - 1;
    if (m == 0) {
        derivative = 0;
        return samples_[0];
    }
    const double x = std::clamp((u - u0_) / (u1_ - u0_), 0.0, 1.0) * double(m);
    const size_t i = std::min(size_t(x), m - 1);
    const double t = x - double(i);
    const auto& c = samples_;
    // Catmull-Rom tangents, one-sided at the ends.
    auto tangent = [&](size_t k) {
        if (k == 0) return c[1] - c[0];
        if (k == m) return c[m] - c[m - 1];
        return 0.5 * (c[k + 1] - c[k - 1]);
    };
    const double m0 = tangent(i), m1 = tangent(i + 1);
    const double t2 = t * t, t3 = t2 * t;
    const double h00 = 2 * t3 - 3 * t2 + 1, h10 = t3 - 2 * t2 + t, h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
    const double d00 = 6 * t2 - 6 * t, d10 = 3 * t2 - 4 * t + 1, d01 = -6 * t2 + 6 * t, d11 = 3 * t2 - 2 * t;
    derivative = (d00 * c[i] + d10 * m0 + d01 * c[i + 1] + d11 * m1) * double(m) / (u1_ - u0_);
    return h00 * c[i] + h10 * m0 + h01 * c[i + 1] + h11 * m1;
}

SplitPiece::SplitPiece(std::string name, std::shared_ptr<const Surface> parent, double u0, double u1,
                       std::vector<double> lower, std::vector<double> upper)
    : Surface(std::move(name)), parent_(std::move(parent)), u0_(u0), u1_(u1), lower_(u0, u1, lower), upper_(u0, u1, upper) {
    const std::string what = "surface '" + this->name() + "': ";
    if (!parent_) throw std::invalid_argument(what + "no parent surface");
    size_ = parent_->size();
    if (!(0 <= u0 && u0 < u1 && u1 <= 1)) throw std::invalid_argument(what + "its u range must satisfy 0 <= u0 < u1 <= 1");
    if (lower.empty() || upper.empty()) throw std::invalid_argument(what + "a boundary curve has no samples");
    for (const auto* curve : {&lower, &upper})
        for (double c : *curve)
            if (!(c >= 0 && c <= 1)) throw std::invalid_argument(what + "a boundary curve leaves [0, 1] (or is NaN)");
    // The band, checked and integrated on a grid finer than the samples: two-point Gauss-Legendre
    // per cell.
    const int cells = std::max(128, int(std::max(lower.size(), upper.size())) * 4);
    const double gauss[2] = {0.5 - 0.5 / std::sqrt(3.0), 0.5 + 0.5 / std::sqrt(3.0)};
    for (int i = 0; i <= 4 * cells; ++i) {
        const double u = u0 + (u1 - u0) * i / (4.0 * cells);
        if (lower_(u) > upper_(u) + 1e-12) throw std::invalid_argument(what + "its lower boundary curve crosses its upper one");
    }
    for (int i = 0; i < cells; ++i)
        for (int j = 0; j < cells; ++j)
            for (double x : gauss)
                for (double y : gauss) area_ += 0.25 / (double(cells) * cells) * evaluate((i + x) / cells, (j + y) / cells).jacobian;
}

void SplitPiece::parent_parameters(double a, double b, double& u, double& v) const {
    u = u0_ + a * (u1_ - u0_);
    const double lo = lower_(u), hi = upper_(u);
    v = lo + b * (hi - lo);
}

void SplitPiece::piece_parameters(double u, double v, double& a, double& b) const {
    a = std::clamp((u - u0_) / (u1_ - u0_), 0.0, 1.0);
    const double uc = u0_ + a * (u1_ - u0_), lo = lower_(uc), hi = upper_(uc);
    b = hi > lo ? std::clamp((v - lo) / (hi - lo), 0.0, 1.0) : 0.5;
}

SurfacePoint SplitPiece::evaluate(double a, double b) const {
    const double du = u1_ - u0_, u = u0_ + a * du;
    double dlo, dhi;
    const double lo = lower_.evaluate(u, dlo), hi = upper_.evaluate(u, dhi);
    const double v = lo + b * (hi - lo);
    const SurfacePoint s = parent_->evaluate(u, v);
    SurfacePoint out;
    out.p = s.p;
    out.dpdu = (s.dpdu + s.dpdv * (dlo + b * (dhi - dlo))) * du;
    out.dpdv = s.dpdv * (hi - lo);
    // The parent's normal, up to rounding (s_a x s_b = du (hi - lo) s_u x s_v), and its side
    // (a NURBS surface faces Blender's way, -(s_u x s_v)); where the band collapses (hi = lo),
    // the parent's normal itself.
    Vec3 n;
    if (!normal_from_derivatives(out.dpdu, out.dpdv, size_, n)) n = s.frame.z;
    else if (dot(n, s.frame.z) < 0) n = -n;
    out.frame = frame_with_normal(n, out.dpdu, out.dpdv);
    out.jacobian = length(cross(out.dpdu, out.dpdv));
    return out;
}

Tessellation SplitPiece::grid(bool lifted) const {
    // Neighbouring pieces of one band share their boundary curve's vertices (the same steps in a).
    const int steps = 48;
    std::vector<double> p(steps + 1);
    for (int i = 0; i <= steps; ++i) p[i] = double(i) / steps;
    return grid_tessellation(p, p, lifted);
}

}  // namespace bsgi
