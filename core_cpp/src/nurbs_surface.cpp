#include "bsgi/nurbs_surface.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace bsgi {

namespace {

constexpr int kMaxOrder = 6;

// Span index I with knots[I] <= x < knots[I+1], degree <= I < count; the right end of the
// range belongs to the last non-empty span before it.
int find_span(const std::vector<double>& knots, int degree, int count, double x) {
    int lo = degree, hi = count;  // knots[lo] <= x < knots[hi] once x is inside
    if (x >= knots[count]) {
        int i = count - 1;
        while (i > degree && knots[i] == knots[count]) --i;
        return i;
    }
    if (x <= knots[degree]) {
        int i = degree;
        while (i < count - 1 && knots[i + 1] == knots[degree]) ++i;
        return i;
    }
    while (hi - lo > 1) {
        const int mid = (lo + hi) / 2;
        if (x < knots[mid]) hi = mid;
        else lo = mid;
    }
    return lo;
}

// The degree+1 B-splines non-zero on span I at x, N[r] = B_{I-degree+r}, and their derivatives:
// Cox-de Boor's recurrence with the two-term derivative formula on the degree-1 values.
void basis_and_derivative(const std::vector<double>& knots, int I, int degree, double x, double* N, double* dN) {
    double lower[kMaxOrder] = {1.0};  // degree-(j-1) values on span I
    double left[kMaxOrder + 1], right[kMaxOrder + 1];
    for (int j = 1; j <= degree; ++j) {
        left[j] = x - knots[I + 1 - j];
        right[j] = knots[I + j] - x;
        if (j == degree) std::copy(lower, lower + degree, N);  // keep degree-1 values in N for now
        double carry = 0;
        for (int r = 0; r < j; ++r) {
            const double denom = right[r + 1] + left[j - r];
            const double q = denom != 0 ? lower[r] / denom : 0;
            lower[r] = carry + right[r + 1] * q;
            carry = left[j - r] * q;
        }
        lower[j] = carry;
    }
    // B'_{i,d} = d (B_{i,d-1} / (t_{i+d} - t_i) - B_{i+1,d-1} / (t_{i+d+1} - t_{i+1})).
    const double* prev = N;  // B_{I-d+1..I, d-1}
    double out_d[kMaxOrder];
    for (int r = 0; r <= degree; ++r) {
        const int i = I - degree + r;
        double a = 0, b = 0;
        if (r >= 1) {
            const double den = knots[i + degree] - knots[i];
            a = den != 0 ? prev[r - 1] / den : 0;
        }
        if (r < degree) {
            const double den = knots[i + degree + 1] - knots[i + 1];
            b = den != 0 ? prev[r] / den : 0;
        }
        out_d[r] = degree * (a - b);
    }
    std::copy(out_d, out_d + degree + 1, dN);
    std::copy(lower, lower + degree + 1, N);
}

std::string direction_name(char axis) { return std::string(1, axis); }

}  // namespace

std::string blender_nurbs_problem(const NurbsDirection& d) {
    std::ostringstream msg;
    if (d.order < 2 || d.order > kMaxOrder) {
        msg << "order " << d.order << " is outside 2..6";
    } else if (d.points < 2) {
        msg << "at least two control points are required, got " << d.points;
    } else if (d.points < d.order) {
        msg << d.points << " control points are fewer than the order " << d.order;
    } else if (d.bezier && d.cyclic && d.points % (d.order - 1) != 0) {
        msg << "cyclic Bezier needs a multiple of order-1 = " << d.order - 1 << " control points, got " << d.points;
    } else if (d.bezier && !d.cyclic && !d.endpoint && d.points <= d.order) {
        msg << "Bezier without endpoints needs more control points than the order " << d.order << ", got " << d.points;
    }
    return msg.str();
}

std::vector<double> blender_knots(const NurbsDirection& d) {
    const std::string problem = blender_nurbs_problem(d);
    if (!problem.empty()) throw std::invalid_argument(problem);
    const int k = d.order;
    const int count = d.points + k + (d.cyclic ? k - 1 : 0);
    // Multiplicity of inner knots, and of the first knot.
    const int inner = d.bezier ? k - 1 : 1;
    const int first = d.endpoint ? (d.cyclic ? k - 1 : k) : (d.bezier ? std::min(2, inner) : 1);
    // Cyclic and endpoint directions end by repeating the widths of the first knots.
    const int tail = d.cyclic ? 2 * k - 1 : (d.endpoint ? k : 0);
    std::vector<double> knots(count);
    double value = 0;
    int begin = 0;
    if (d.endpoint && d.cyclic) {  // a single leading knot before the repeated ones
        knots[0] = 0;
        value = 1;
        begin = 1;
    }
    int left = first;
    for (int i = begin; i < count - tail; ++i) {
        knots[i] = value;
        if (--left == 0) {
            value += 1;
            left = inner;
        }
    }
    for (int i = 0; i < tail; ++i) knots[count - tail + i] = value + (knots[i] - knots[0]);
    return knots;
}

std::pair<double, double> blender_range(const NurbsDirection& d, const std::vector<double>& knots) {
    const int k = d.order;
    return {knots[k - 1], d.cyclic ? knots[d.points + k - 1] : knots[d.points]};
}

NurbsSurface::NurbsSurface(std::string name, std::vector<double> control, NurbsDirection u, NurbsDirection v, int subdivisions,
                           NurbsFront front)
    : Surface(std::move(name)), u_(u), v_(v), subdivisions_(subdivisions), front_(front) {
    auto fail = [&](const std::string& what) { throw std::invalid_argument("surface '" + this->name() + "': " + what); };
    for (const NurbsDirection* d : {&u_, &v_}) {
        const std::string problem = blender_nurbs_problem(*d);
        if (!problem.empty()) fail("direction " + direction_name(d == &u_ ? 'u' : 'v') + ": " + problem);
    }
    if (subdivisions_ < 0 || subdivisions_ > 256) fail("subdivisions must be in 0..256 (0: automatic)");
    const size_t n = size_t(u_.points) * v_.points;
    if (control.size() != 4 * n) {
        std::ostringstream msg;
        msg << "expected " << u_.points << " x " << v_.points << " = " << n << " control points (x, y, z, w), got "
            << control.size() / 4.0;
        fail(msg.str());
    }
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (size_t i = 0; i < n; ++i) {
        const double* c = &control[4 * i];
        const int iu = int(i % u_.points), iv = int(i / u_.points);
        std::ostringstream where;
        where << "control point " << i << " (u " << iu << ", v " << iv << ")";
        for (int a = 0; a < 4; ++a)
            if (!std::isfinite(c[a])) fail(where.str() + " is NaN or infinite");
        if (!(c[3] > 0)) {
            std::ostringstream msg;
            msg << where.str() << " has weight " << c[3] << "; weights must be > 0";
            fail(msg.str());
        }
        lo = {std::min(lo.x, c[0]), std::min(lo.y, c[1]), std::min(lo.z, c[2])};
        hi = {std::max(hi.x, c[0]), std::max(hi.y, c[1]), std::max(hi.z, c[2])};
    }
    size_ = length(hi - lo);
    if (!(size_ > 0)) fail("all control points coincide (no surface)");
    control_.resize(4 * n);
    for (size_t i = 0; i < n; ++i) {
        const double w = control[4 * i + 3];
        for (int a = 0; a < 3; ++a) control_[4 * i + a] = w * control[4 * i + a];
        control_[4 * i + 3] = w;
    }
    knots_u_ = blender_knots(u_);
    knots_v_ = blender_knots(v_);
    range_u_ = blender_range(u_, knots_u_);
    range_v_ = blender_range(v_, knots_v_);

    // Area: Gauss-Legendre on every knot span, enough nodes for smooth rational patches.
    static const double gx[5] = {-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831, 0.9061798459386640};
    static const double gw[5] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665,
                                 0.2369268850561891};
    // Four pieces per span: rational patches are not polynomials.
    auto pieces = [](const std::vector<double>& b) {
        std::vector<double> out;
        for (size_t i = 0; i + 1 < b.size(); ++i)
            for (int k = 0; k < 4; ++k) out.push_back(b[i] + (b[i + 1] - b[i]) * k / 4);
        out.push_back(1.0);
        return out;
    };
    const std::vector<double> bu = pieces(breakpoints(knots_u_, range_u_)), bv = pieces(breakpoints(knots_v_, range_v_));
    for (size_t a = 0; a + 1 < bu.size(); ++a)
        for (size_t b = 0; b + 1 < bv.size(); ++b)
            for (int i = 0; i < 5; ++i)
                for (int j = 0; j < 5; ++j) {
                    const double su = 0.5 * (bu[a] + bu[a + 1]) + 0.5 * (bu[a + 1] - bu[a]) * gx[i];
                    const double sv = 0.5 * (bv[b] + bv[b + 1]) + 0.5 * (bv[b + 1] - bv[b]) * gx[j];
                    Vec3 p, du, dv, duv;
                    derivatives(su, sv, p, du, dv, duv);
                    area_ += 0.25 * (bu[a + 1] - bu[a]) * (bv[b + 1] - bv[b]) * gw[i] * gw[j] * length(cross(du, dv));
                }
}

std::vector<double> NurbsSurface::breakpoints(const std::vector<double>& knots, std::pair<double, double> range) const {
    // Distinct knots inside the range, normalised to [0, 1].
    std::vector<double> b{0.0};
    const double a = range.first, w = range.second - range.first;
    for (double k : knots)
        if (k > a && k < range.second && (k - a) / w > b.back()) b.push_back((k - a) / w);
    b.push_back(1.0);
    return b;
}

std::array<std::vector<double>, 2> NurbsSurface::creases() const {
    // A knot line is a crease where the normals just before and after it differ anywhere along
    // it (sampled; by more than about half a degree).
    constexpr double kStep = 1e-7, kSameNormal = 0.99996;
    std::array<std::vector<double>, 2> out;
    for (int along_u = 0; along_u < 2; ++along_u) {
        const std::vector<double> b = along_u ? breakpoints(knots_u_, range_u_) : breakpoints(knots_v_, range_v_);
        for (size_t i = 1; i + 1 < b.size(); ++i) {
            bool crease = false;
            for (int j = 0; j <= 16 && !crease; ++j) {
                const double x = b[i], y = j / 16.0;
                const Vec3 before = along_u ? evaluate(x - kStep, y).frame.z : evaluate(y, x - kStep).frame.z;
                const Vec3 after = along_u ? evaluate(x + kStep, y).frame.z : evaluate(y, x + kStep).frame.z;
                crease = dot(before, after) < kSameNormal;
            }
            if (crease) out[along_u ? 0 : 1].push_back(b[i]);
        }
    }
    return out;
}

void NurbsSurface::derivatives(double u, double v, Vec3& p, Vec3& su, Vec3& sv, Vec3& suv) const {
    const double wu = range_u_.second - range_u_.first, wv = range_v_.second - range_v_.first;
    if (u_.cyclic) u -= std::floor(u);
    if (v_.cyclic) v -= std::floor(v);
    const double x = range_u_.first + std::clamp(u, 0.0, 1.0) * wu;
    const double y = range_v_.first + std::clamp(v, 0.0, 1.0) * wv;
    const int du = u_.degree(), dv = v_.degree();
    const int I = find_span(knots_u_, du, u_.basis_count(), x);
    const int J = find_span(knots_v_, dv, v_.basis_count(), y);
    double Nu[kMaxOrder], dNu[kMaxOrder], Nv[kMaxOrder], dNv[kMaxOrder];
    basis_and_derivative(knots_u_, I, du, x, Nu, dNu);
    basis_and_derivative(knots_v_, J, dv, y, Nv, dNv);
    // Homogeneous sums A = sum N_i N_j w P and W = sum N_i N_j w, with their derivatives.
    double A[4] = {0, 0, 0, 0}, Au[4] = {0, 0, 0, 0}, Av[4] = {0, 0, 0, 0}, Auv[4] = {0, 0, 0, 0};
    for (int s = 0; s <= dv; ++s) {
        const int jv = (J - dv + s) % v_.points;  // cyclic: basis j >= points uses point j - points
        double row[4] = {0, 0, 0, 0}, row_u[4] = {0, 0, 0, 0};
        for (int r = 0; r <= du; ++r) {
            const int iu = (I - du + r) % u_.points;
            const double* c = &control_[4 * (size_t(jv) * u_.points + iu)];
            for (int a = 0; a < 4; ++a) {
                row[a] += Nu[r] * c[a];
                row_u[a] += dNu[r] * c[a];
            }
        }
        for (int a = 0; a < 4; ++a) {
            A[a] += Nv[s] * row[a];
            Au[a] += Nv[s] * row_u[a];
            Av[a] += dNv[s] * row[a];
            Auv[a] += dNv[s] * row_u[a];
        }
    }
    // Quotient rule for S = A / W, then the chain rule for the normalised parameters.
    const double W = A[3], Wu = Au[3], Wv = Av[3], Wuv = Auv[3];
    p = Vec3(A[0], A[1], A[2]) / W;
    const Vec3 Su = (Vec3(Au[0], Au[1], Au[2]) - p * Wu) / W;
    const Vec3 Sv = (Vec3(Av[0], Av[1], Av[2]) - p * Wv) / W;
    const Vec3 Suv = (Vec3(Auv[0], Auv[1], Auv[2]) - p * Wuv - Su * Wv - Sv * Wu) / W;
    su = Su * wu;
    sv = Sv * wv;
    suv = Suv * (wu * wv);
}

Vec3 NurbsSurface::limit_normal(double u, double v, const Vec3& su, const Vec3& sv, const Vec3& suv) const {
    // The normal at (u + h, v) is along s_u x s_v(u + h) ~ h (s_u x s_uv): the sign of h is the
    // direction into the domain. Same for a vanishing s_u.
    const double small = kVanishingDerivative * size_;
    Vec3 a, b;
    double sign = 1;
    if (length(sv) <= small && length(su) > small) a = su, b = suv, sign = u < 0.5 ? 1.0 : -1.0;
    else if (length(su) <= small && length(sv) > small) a = suv, b = sv, sign = v < 0.5 ? 1.0 : -1.0;
    const Vec3 n = cross(a, b);
    const double ln = length(n);
    if (ln > 1e-8 * length(a) * length(b) && ln > 0 && std::isfinite(ln)) return n * (sign / ln);
    return nudged_normal(u, v);  // s_u parallel to s_v, or both vanish: look nearby
}

SurfacePoint NurbsSurface::evaluate(double u, double v) const {
    SurfacePoint s;
    Vec3 suv;
    derivatives(u, v, s.p, s.dpdu, s.dpdv, suv);
    s.jacobian = length(cross(s.dpdu, s.dpdv));
    Vec3 n, limit_su;
    if (!normal_from_derivatives(s.dpdu, s.dpdv, size_, n)) {
        if (!unit_or_fail(limit_normal(u, v, s.dpdu, s.dpdv, suv), 0.0, n)) n = {0, 0, 1};
        // Where s_u vanishes its direction in the limit is that of s_uv (s_u ~ (v - v0) s_uv).
        limit_su = suv * (v < 0.5 ? 1.0 : -1.0);
    }
    s.frame = frame_with_normal(front_ == NurbsFront::Blender ? -n : n, s.dpdu, s.dpdv, limit_su);
    return s;
}

std::vector<double> NurbsSurface::grid_parameters(bool along_u) const {
    const std::vector<double> b = along_u ? breakpoints(knots_u_, range_u_) : breakpoints(knots_v_, range_v_);
    const std::vector<double> across = along_u ? breakpoints(knots_v_, range_v_) : breakpoints(knots_u_, range_u_);
    // Iso-lines across which chords are checked: the breakpoints and the span middles.
    std::vector<double> lines;
    for (size_t i = 0; i + 1 < across.size(); ++i) {
        lines.push_back(across[i]);
        lines.push_back(0.5 * (across[i] + across[i + 1]));
    }
    lines.push_back(1.0);
    auto at = [&](double a, double c) {
        Vec3 p, su, sv, suv;
        derivatives(along_u ? a : c, along_u ? c : a, p, su, sv, suv);
        return p;
    };
    const double tolerance = 2e-4 * size_;
    std::vector<double> out;
    for (size_t i = 0; i + 1 < b.size(); ++i) {
        int steps = subdivisions_;
        if (steps == 0) {
            // Double the steps until every chord's middle is within tolerance of the surface.
            for (steps = 2; steps < 64; steps *= 2) {
                double worst = 0;
                for (int k = 0; k < steps && worst <= tolerance; ++k) {
                    const double a0 = b[i] + (b[i + 1] - b[i]) * k / steps, a1 = b[i] + (b[i + 1] - b[i]) * (k + 1) / steps;
                    for (double c : lines) worst = std::max(worst, length(at(0.5 * (a0 + a1), c) - (at(a0, c) + at(a1, c)) * 0.5));
                }
                if (worst <= tolerance) break;
            }
        }
        for (int k = 0; k < steps; ++k) out.push_back(b[i] + (b[i + 1] - b[i]) * k / steps);
    }
    out.push_back(1.0);
    return out;
}

Tessellation NurbsSurface::grid(bool lifted) const {
    // Cyclic seams get their own vertices (u = 1 next to u = 0) so (u, v) interpolate without
    // wrapping.
    return grid_tessellation(grid_parameters(true), grid_parameters(false), lifted);
}

Tessellation NurbsSurface::tessellate() const { return grid(false); }

Tessellation NurbsSurface::tessellate_for_rays() const { return grid(true); }

}  // namespace bsgi
