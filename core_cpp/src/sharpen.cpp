#include "bsgi/sharpen.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace bsgi {

namespace {

// The positions of one line of samples along the axis: increasing, continued across a periodic
// seam.
struct Line {
    std::vector<double> x;
    bool periodic = false;
    double period = 0;
    int n() const { return int(x.size()); }
    // Index of sample j (j may be -1 or n on a periodic axis), its position in `at`; -1 if none.
    int index(int j, double& at) const {
        if (j >= 0 && j < n()) {
            at = x[j];
            return j;
        }
        if (!periodic) return -1;
        const int w = (j + n()) % n();
        at = x[w] + (j < 0 ? -period : period);
        return w;
    }
    int index(int j) const {
        double unused;
        return index(j, unused);
    }
};

double minmod(double a, double b) {
    return a > 0 && b > 0 ? std::min(a, b) : a < 0 && b < 0 ? std::max(a, b) : 0;
}

}  // namespace

void sharpen_samples(TensorSpline& spline, int axis, const std::vector<double>& nodes, const std::vector<uint8_t>& keep) {
    if (axis < 0 || axis >= spline.dims())
        throw std::invalid_argument("sharpen: axis " + std::to_string(axis) + " of a " + std::to_string(spline.dims()) +
                                    "-dimensional spline");
    if (spline.precision() != Precision::Float64) throw std::invalid_argument("sharpen: needs Float64 coefficients");
    const KnotVector& kv = spline.axis(axis);
    const int d = kv.degree(), n = kv.num_coeffs();
    Line line{nodes.empty() ? kv.schoenberg_nodes() : nodes, kv.is_periodic(), kv.domain_end() - kv.domain_begin()};
    if (line.n() != n)
        throw std::invalid_argument("sharpen: " + std::to_string(nodes.size()) + " nodes for " + std::to_string(n) +
                                    " coefficients");
    // With fewer than 6 coefficients the samples are too few to tell a peak from what the end
    // samples see past the surface's edge (a floor under a pane, its edges seeing the sky past it).
    if (d < 2 || (!line.periodic && n < 6)) return;
    // A periodic axis's nodes are wrapped into the period (the first lies at its end).
    if (line.periodic)
        for (int j = 1; j < n; ++j)
            while (line.x[j] <= line.x[j - 1]) line.x[j] += line.period;
    // beta_i: the blossom of (x - t*_i)^2 at the coefficient's inner knots t_{i+1..i+d}.
    const auto& t = kv.knots();
    std::vector<double> beta(n);
    for (int i = 0; i < n; ++i) {
        double c = 0, s = 0;
        for (int k = 1; k <= d; ++k) c += t[i + k];
        c /= d;
        for (int k = 1; k <= d; ++k) s += (t[i + k] - c) * (t[i + k] - c);
        beta[i] = -s / (d * (d - 1));
    }
    // Stencils are the sample and its two neighbours. A coefficient with no sample beyond it (the
    // ends: for clamped knots they interpolate and need no correction) takes the curvature its
    // two stencils inward share. End samples, at epsilon from the surface's edge, see past it at
    // close range, so they count as no peak or trough. (has[j]: sample j has neighbours on both
    // sides, so an end sample's curvature never enters a minmod.)
    const std::vector<size_t> shape = spline.shape();
    size_t per_node = 1;  // values per spatial node
    for (size_t k = 2; k < shape.size(); ++k) per_node *= shape[k];
    if (!keep.empty() && (shape.size() < 3 || keep.size() * per_node != spline.coeffs().size()))
        throw std::invalid_argument("sharpen: " + std::to_string(keep.size()) + " marks for " +
                                    std::to_string(spline.coeffs().size() / per_node) + " spatial nodes");
    size_t inner = 1, outer = 1;
    for (size_t k = size_t(axis) + 1; k < shape.size(); ++k) inner *= shape[k];
    for (int k = 0; k < axis; ++k) outer *= shape[k];
    std::vector<double>& a = spline.coeffs();
    std::vector<double> f(n), dd(n), out(n);
    std::vector<uint8_t> has(n);
    // How far sample i stands out from the samples beside it (0 if it does not): above (sign 1)
    // or below (-1) both neighbours, or, with a neighbour, as a pair (a peak between two nodes
    // samples two nearly equal values). End samples are left out.
    auto standing_out = [&](int i, double sign) {
        auto at = [&](int j) {
            const int w = line.index(j);
            return w < 0 || (!line.periodic && (w == 0 || w == n - 1)) ? std::numeric_limits<double>::infinity() : sign * f[w];
        };
        const double fi = sign * f[i];
        return std::max({0.0, fi - std::max(at(i - 1), at(i + 1)), std::min(fi, at(i - 1)) - std::max(at(i - 2), at(i + 1)),
                         std::min(fi, at(i + 1)) - std::max(at(i - 1), at(i + 2))});
    };
    for (size_t o = 0; o < outer; ++o)
        for (size_t q = 0; q < inner; ++q) {
            const size_t base = o * size_t(n) * inner + q;
            for (int i = 0; i < n; ++i) f[i] = a[base + size_t(i) * inner];
            // Second divided differences f[x_{i-1}, x_i, x_{i+1}]: half the local quadratic's f''.
            for (int i = 0; i < n; ++i) {
                double xl = 0, xr = 0;
                const int l = line.index(i - 1, xl), r = line.index(i + 1, xr);
                const double xi = line.x[i];
                has[i] = l >= 0 && r >= 0 && xl < xi && xi < xr;
                dd[i] = has[i] ? ((f[r] - f[i]) / (xr - xi) - (f[i] - f[l]) / (xi - xl)) / (xr - xl) : 0;
            }
            for (int i = 0; i < n; ++i) {
                out[i] = f[i];
                if (beta[i] == 0 || (!keep.empty() && keep[(base + size_t(i) * inner) / per_node])) continue;
                // The stencil: the sample and its neighbours, moved inward next to an end.
                const int c = line.periodic ? i : std::clamp(i, 1, n - 2);
                if (!has[c]) continue;
                if (c != i) {
                    // Next to an end: the curvature the two stencils inward share, no more (taken
                    // from elsewhere, a peak's curvature would lift the coefficient beside it).
                    const int inward = c + (c > i ? 1 : -1);
                    out[i] = f[i] + beta[i] * (has[inward] ? minmod(dd[c], dd[inward]) : 0.0);
                    if (f[i] >= 0 && f[c] >= 0) out[i] = std::max(out[i], 0.0);
                    continue;
                }
                out[i] = f[i] + dd[c] * beta[i];
                const int l = line.index(c - 1), r = line.index(c + 1);
                // The coefficient may leave its stencil's range by as much as the curvature the
                // stencil's neighbours share (all of the correction on a quadratic, none across an
                // edge, where the curvature changes sign) or, at a peak or a trough, by as much as
                // the sample stands out there. Each bound is continuous in non-negative samples (a
                // radiance): a rounding's difference makes no more than a rounding's difference.
                double shared = dd[c];
                for (int w : {l, r})
                    if (has[w]) shared = minmod(shared, dd[w]);
                const double correction = out[i] - f[i];
                const double stands = std::min(std::abs(correction), standing_out(i, correction > 0 ? 1 : -1));
                const double slack = std::max(std::abs(shared * beta[i]), stands);
                const double lo = std::min({f[l], f[c], f[r]}), hi = std::max({f[l], f[c], f[r]});
                out[i] = std::clamp(out[i], lo - slack, hi + slack);
                if (lo >= 0) out[i] = std::max(out[i], 0.0);  // non-negative samples, non-negative coefficient
            }
            for (int i = 0; i < n; ++i) a[base + size_t(i) * inner] = out[i];
        }
}

}  // namespace bsgi
