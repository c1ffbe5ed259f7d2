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

SplitPiece::SplitPiece(std::string name, std::shared_ptr<const Surface> parent, double t0, double t1,
                       std::vector<double> lower, std::vector<double> upper, bool along_v)
    : Surface(std::move(name)), parent_(std::move(parent)), t0_(t0), t1_(t1), along_v_(along_v),
      lower_(t0, t1, lower), upper_(t0, t1, upper) {
    const std::string what = "surface '" + this->name() + "': ";
    if (!parent_) throw std::invalid_argument(what + "no parent surface");
    size_ = parent_->size();
    if (!(0 <= t0 && t0 < t1 && t1 <= 1)) throw std::invalid_argument(what + "its range must satisfy 0 <= t0 < t1 <= 1");
    if (lower.empty() || upper.empty()) throw std::invalid_argument(what + "a boundary curve has no samples");
    for (const auto* curve : {&lower, &upper})
        for (double c : *curve)
            if (!(c >= 0 && c <= 1)) throw std::invalid_argument(what + "a boundary curve leaves [0, 1] (or is NaN)");
    // The band, checked on a grid four times finer than its samples and integrated on one as fine
    // (two-point Gauss-Legendre per cell): the area to about 1e-5 (kinks of the parent's speed at
    // its knots fall inside cells), which the solver's uses of it (coefficients by size, weights
    // of the estimate) need, at a few thousand evaluations.
    const int cells = std::max(32, int(std::max(lower.size(), upper.size())));
    const double gauss[2] = {0.5 - 0.5 / std::sqrt(3.0), 0.5 + 0.5 / std::sqrt(3.0)};
    for (int i = 0; i <= 4 * cells; ++i) {
        const double t = t0 + (t1 - t0) * i / (4.0 * cells);
        if (lower_(t) > upper_(t) + 1e-12) throw std::invalid_argument(what + "its lower boundary curve crosses its upper one");
    }
    for (int i = 0; i < cells; ++i)
        for (int j = 0; j < cells; ++j)
            for (double x : gauss)
                for (double y : gauss) area_ += 0.25 / (double(cells) * cells) * evaluate((i + x) / cells, (j + y) / cells).jacobian;
}

void SplitPiece::map(double a, double b, double& u, double& v, double d[4]) const {
    // Along u: (t, w) = (a, b) -> (u, v); along v: (t, w) = (b, a) -> (v, u).
    const double t = along_v_ ? b : a, w = along_v_ ? a : b;
    const double dt = t1_ - t0_, along = t0_ + t * dt;
    double dlo, dhi;
    const double lo = lower_.evaluate(along, dlo), hi = upper_.evaluate(along, dhi);
    const double across = lo + w * (hi - lo);
    const double dacross_dt = (dlo + w * (dhi - dlo)) * dt, dacross_dw = hi - lo;
    if (!along_v_) {
        u = along, v = across;
        d[0] = dt, d[1] = 0, d[2] = dacross_dt, d[3] = dacross_dw;
    } else {
        v = along, u = across;
        d[0] = dacross_dw, d[1] = dacross_dt, d[2] = 0, d[3] = dt;
    }
}

void SplitPiece::parent_parameters(double a, double b, double& u, double& v) const {
    double d[4];
    map(a, b, u, v, d);
}

void SplitPiece::band_parameters(const BoundaryCurve& lower, const BoundaryCurve& upper, double t0, double t1, bool along_v,
                                 double u, double v, double& a, double& b) {
    const double along = along_v ? v : u, across = along_v ? u : v;
    const double t = (along - t0) / (t1 - t0);
    const double at = t0 + std::clamp(t, 0.0, 1.0) * (t1 - t0), lo = lower(at), hi = upper(at);
    const double w = hi > lo ? (across - lo) / (hi - lo) : across < lo ? -1.0 : across > hi ? 2.0 : 0.5;
    a = along_v ? w : t;
    b = along_v ? t : w;
}

void SplitPiece::piece_parameters(double u, double v, double& a, double& b) const {
    band_parameters(lower_, upper_, t0_, t1_, along_v_, u, v, a, b);
    a = std::clamp(a, 0.0, 1.0);
    b = std::clamp(b, 0.0, 1.0);
}

SurfacePoint SplitPiece::evaluate(double a, double b) const {
    double u, v, d[4];
    map(a, b, u, v, d);
    const SurfacePoint s = parent_->evaluate(u, v);
    SurfacePoint out;
    out.p = s.p;
    out.dpdu = s.dpdu * d[0] + s.dpdv * d[2];
    out.dpdv = s.dpdu * d[1] + s.dpdv * d[3];
    // The parent's normal, up to rounding (s_a x s_b = (u_a v_b - u_b v_a) s_u x s_v, the factor
    // positive), and its side (a NURBS surface faces Blender's way, -(s_u x s_v)); where the band
    // collapses (hi = lo), the parent's normal itself.
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
