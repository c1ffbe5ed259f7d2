#include "bsgi/knots.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace bsgi {

KnotVector::KnotVector(std::vector<double> knots, int degree) : knots_(std::move(knots)), degree_(degree) {
    if (degree_ < 0 || degree_ > kMaxDegree)
        throw std::invalid_argument("knot vector: degree must be in 0.." + std::to_string(kMaxDegree) + ", got " +
                                    std::to_string(degree_));
    for (double t : knots_)
        if (!std::isfinite(t)) throw std::invalid_argument("knot vector: knots must be finite");
    const int n = num_coeffs();
    if (n < degree_ + 1) {
        std::ostringstream msg;
        msg << "knot vector: degree " << degree_ << " needs at least " << degree_ + 1 << " coefficients (" << 2 * degree_ + 2
            << " knots), got " << knots_.size() << " knots";
        throw std::invalid_argument(msg.str());
    }
    int run = 1;
    for (size_t i = 1; i < knots_.size(); ++i) {
        if (knots_[i] < knots_[i - 1]) throw std::invalid_argument("knot vector: knots must be non-decreasing");
        run = knots_[i] == knots_[i - 1] ? run + 1 : 1;
        if (run > degree_ + 1) {
            std::ostringstream msg;
            msg << "knot vector: knot " << knots_[i] << " repeated " << run << " times, more than degree+1 = " << degree_ + 1;
            throw std::invalid_argument(msg.str());
        }
    }
    if (!(domain_end() > domain_begin())) throw std::invalid_argument("knot vector: empty parameter domain");
}

KnotVector KnotVector::clamped_uniform(int num_coeffs, int degree, double a, double b) {
    if (degree < 0) throw std::invalid_argument("knot vector: degree must be >= 0");
    if (num_coeffs < degree + 1) {
        std::ostringstream msg;
        msg << "knot vector: degree " << degree << " needs at least " << degree + 1 << " coefficients, got " << num_coeffs;
        throw std::invalid_argument(msg.str());
    }
    if (!(b > a)) throw std::invalid_argument("knot vector: domain [a, b] needs b > a");
    const int inner = num_coeffs - degree - 1;
    const double h = (b - a) / (inner + 1);
    std::vector<double> t;
    t.reserve(num_coeffs + degree + 1);
    for (int i = 0; i <= degree; ++i) t.push_back(a);
    for (int i = 1; i <= inner; ++i) t.push_back(a + i * h);
    for (int i = 0; i <= degree; ++i) t.push_back(b);
    return KnotVector(std::move(t), degree);
}

int KnotVector::find_span(double x) const {
    const int n = num_coeffs();
    if (!(x > knots_[degree_])) return degree_;  // also catches NaN: callers validate parameters
    if (x >= knots_[n]) {
        int span = n - 1;
        while (knots_[span] == knots_[span + 1]) --span;  // last non-empty span
        return span;
    }
    // upper_bound over [t_d, t_n]: first knot > x, minus one.
    auto it = std::upper_bound(knots_.begin() + degree_, knots_.begin() + n + 1, x);
    return static_cast<int>(it - knots_.begin()) - 1;
}

void KnotVector::basis(double x, int span, double* out) const {
    const int d = degree_;
    x = std::clamp(x, domain_begin(), domain_end());
    double left[kMaxDegree + 1], right[kMaxDegree + 1];
    out[0] = 1.0;
    for (int j = 1; j <= d; ++j) {
        left[j] = x - knots_[span + 1 - j];
        right[j] = knots_[span + j] - x;
        double saved = 0.0;
        for (int r = 0; r < j; ++r) {
            const double denom = right[r + 1] + left[j - r];
            const double temp = denom > 0 ? out[r] / denom : 0.0;
            out[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        out[j] = saved;
    }
}

std::vector<double> KnotVector::schoenberg_nodes() const {
    const int n = num_coeffs();
    std::vector<double> nodes(n);
    for (int i = 0; i < n; ++i) {
        if (degree_ == 0) {
            nodes[i] = 0.5 * (knots_[i] + knots_[i + 1]);
        } else {
            double s = 0;
            for (int k = 1; k <= degree_; ++k) s += knots_[i + k];
            nodes[i] = s / degree_;
        }
    }
    return nodes;
}

std::vector<double> KnotVector::basis_integrals() const {
    const int n = num_coeffs();
    std::vector<double> w(n);
    for (int i = 0; i < n; ++i) w[i] = (knots_[i + degree_ + 1] - knots_[i]) / (degree_ + 1);
    return w;
}

}  // namespace bsgi
