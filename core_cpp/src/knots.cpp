#include "bsgi/knots.h"
#include "bsgi/memory_budget.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>

namespace bsgi {

namespace {

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("knot vector: " + what); }

void check_degree(int degree) {
    if (degree < 0 || degree > kMaxDegree)
        fail("degree must be in 0.." + std::to_string(kMaxDegree) + ", got " + std::to_string(degree));
}

void check_coeffs(int num_coeffs, int degree) {
    if (num_coeffs < degree + 1) {
        std::ostringstream msg;
        msg << "degree " << degree << " needs at least " << degree + 1 << " coefficients, got " << num_coeffs;
        fail(msg.str());
    }
}

// A generated knot vector's knots and per-span polynomial tables, checked against the memory
// budget before they are built (a count near INT_MAX would otherwise take minutes and gigabytes).
void check_size(int num_coeffs, int degree) {
    check_memory_budget("knot vector of " + std::to_string(num_coeffs) + " coefficients",
                        {size_t(num_coeffs) + size_t(degree) + 1, size_t(degree + 1) * size_t(degree + 1) + 1}, sizeof(double));
}

// Polynomials in s as coefficient arrays of length kMaxDegree + 1 (lowest power first).
struct Poly {
    double c[kMaxDegree + 1] = {};
};

// (a + b s) * p, dropping terms beyond the degree (they vanish for B-splines).
Poly times_linear(double a, double b, const Poly& p, int degree) {
    Poly r;
    for (int k = 0; k <= degree; ++k) {
        r.c[k] += a * p.c[k];
        if (k + 1 <= degree) r.c[k + 1] += b * p.c[k];
    }
    return r;
}

}  // namespace

KnotVector::KnotVector(std::vector<double> knots, int degree) : knots_(std::move(knots)), degree_(degree) {
    check_degree(degree_);
    num_coeffs_ = static_cast<int>(knots_.size()) - degree_ - 1;
    validate();
    precompute();
}

KnotVector::KnotVector(std::vector<double> knots, int degree, PeriodicTag) : knots_(std::move(knots)), degree_(degree) {
    periodic_ = true;
    num_coeffs_ = static_cast<int>(knots_.size()) - 2 * degree_ - 1;
    validate();
    precompute();
}

void KnotVector::validate() const {
    for (double t : knots_)
        if (!std::isfinite(t)) fail("knots must be finite");
    if (num_basis() < degree_ + 1) {
        std::ostringstream msg;
        msg << "degree " << degree_ << " needs at least " << degree_ + 1 << " coefficients (" << 2 * degree_ + 2
            << " knots), got " << knots_.size() << " knots";
        fail(msg.str());
    }
    int run = 1;
    for (size_t i = 1; i < knots_.size(); ++i) {
        if (knots_[i] < knots_[i - 1]) {
            std::ostringstream msg;
            msg << "knots must be non-decreasing, but knot " << i << " (" << knots_[i] << ") < knot " << i - 1 << " ("
                << knots_[i - 1] << ")";
            fail(msg.str());
        }
        // A span whose width or inverse width overflows would give NaN basis functions.
        const double w = knots_[i] - knots_[i - 1];
        if (w > 0 && !(std::isfinite(w) && std::isfinite(1.0 / w))) {
            std::ostringstream msg;
            msg << "knot span [" << knots_[i - 1] << ", " << knots_[i] << "] is too " << (std::isfinite(w) ? "narrow" : "wide")
                << " for double precision";
            fail(msg.str());
        }
        run = knots_[i] == knots_[i - 1] ? run + 1 : 1;
        if (run > degree_ + 1) {
            std::ostringstream msg;
            msg << "knot " << knots_[i] << " repeated " << run << " times, more than degree+1 = " << degree_ + 1;
            fail(msg.str());
        }
    }
    if (!(domain_end() > domain_begin())) fail("empty parameter domain [t_d, t_n]");
}

size_t KnotVector::bytes(int num_coeffs, int degree) {
    constexpr size_t kBlock = 16;
    const size_t d = size_t(std::max(degree, 0)), n = std::max(size_t(std::max(num_coeffs, 0)), d + 1), spans = n - d;
    // knots_, span_poly_ (padded by 4, as precompute makes it) and span_inv_width_
    return sizeof(KnotVector) + (n + d + 1) * sizeof(double) + (spans * (d + 1) * (d + 1) + 4) * sizeof(double) +
           spans * sizeof(double) + 3 * kBlock;
}

void KnotVector::precompute() {
    const int d = degree_, n = num_basis(), P = d + 1;
    last_span_ = n - 1;
    while (knots_[last_span_] == knots_[last_span_ + 1]) --last_span_;

    // Power form of the basis on each span by Cox-de Boor run on polynomials in
    // s = (x - t_I) / w: the same recurrence, so the same stability, done once per span.
    span_poly_.assign(size_t(n - d) * P * P + 4, 0.0);  // padded: kernels load 4 at a time
    span_inv_width_.assign(n - d, 0.0);
    for (int I = d; I < n; ++I) {
        const double tI = knots_[I], w = knots_[I + 1] - tI;
        if (!(w > 0)) continue;
        span_inv_width_[I - d] = 1.0 / w;
        Poly N[kMaxDegree + 1];
        N[0].c[0] = 1.0;
        for (int j = 1; j <= d; ++j) {
            Poly saved;
            for (int r = 0; r < j; ++r) {
                const double denom = knots_[I + r + 1] - knots_[I + 1 - j + r];
                Poly temp;
                if (denom > 0)
                    for (int k = 0; k <= d; ++k) temp.c[k] = N[r].c[k] / denom;
                // right_{r+1} = t_{I+r+1} - x, left_{j-r} = x - t_{I+1-j+r}, with x = t_I + w s.
                const Poly a = times_linear(knots_[I + r + 1] - tI, -w, temp, d);
                for (int k = 0; k <= d; ++k) N[r].c[k] = saved.c[k] + a.c[k];
                saved = times_linear(tI - knots_[I + 1 - j + r], w, temp, d);
            }
            N[j] = saved;
        }
        double* table = &span_poly_[size_t(I - d) * P * P];
        for (int k = 0; k < P; ++k)
            for (int j = 0; j < P; ++j) {
                if (!std::isfinite(N[j].c[k])) fail("knot spans around [" + std::to_string(tI) + ", " + std::to_string(tI + w) +
                                                    "] differ too much in width for double precision");
                table[k * P + j] = N[j].c[k];
            }
    }

    // Equal spans over the whole domain (no empty span inside it) allow span = floor((x - a) / h).
    const double a = domain_begin(), b = domain_end();
    int first = d;
    while (knots_[first + 1] == knots_[first]) ++first;
    const int spans = last_span_ - first + 1;
    const double h = (b - a) / spans;
    uniform_ = true;
    for (int I = first; I <= last_span_ && uniform_; ++I)
        uniform_ = std::abs((knots_[I + 1] - knots_[I]) - h) <= 1e-12 * (b - a);
    uniform_ = uniform_ && first == d;
    inv_h_ = uniform_ ? 1.0 / h : 0.0;
}

KnotVector KnotVector::clamped_uniform(int num_coeffs, int degree, double a, double b) {
    check_degree(degree);
    check_coeffs(num_coeffs, degree);
    check_size(num_coeffs, degree);
    if (!(std::isfinite(a) && std::isfinite(b) && b > a)) fail("domain [a, b] needs finite a < b");
    const int inner = num_coeffs - degree - 1;
    const double h = (b - a) / (inner + 1);
    std::vector<double> t;
    t.reserve(num_coeffs + degree + 1);
    for (int i = 0; i <= degree; ++i) t.push_back(a);
    for (int i = 1; i <= inner; ++i) t.push_back(a + i * h);
    for (int i = 0; i <= degree; ++i) t.push_back(b);
    return KnotVector(std::move(t), degree);
}

KnotVector KnotVector::symmetric(int num_coeffs, int degree, double R) {
    if (!(R > 0 && std::isfinite(R))) fail("symmetric knots on [-R, R] need R > 0");
    check_degree(degree);
    check_coeffs(num_coeffs, degree);
    check_size(num_coeffs, degree);
    // Knot i is (2i - (m+1)) R / (m+1): an integer times one constant, so exactly symmetric about 0.
    const int inner = num_coeffs - degree - 1;
    const double step = R / (inner + 1);
    std::vector<double> t;
    for (int i = 0; i <= degree; ++i) t.push_back(-R);
    for (int i = 1; i <= inner; ++i) t.push_back(double(2 * int64_t(i) - (inner + 1)) * step);
    for (int i = 0; i <= degree; ++i) t.push_back(R);
    return KnotVector(std::move(t), degree);
}

KnotVector KnotVector::periodic(const std::vector<double>& breakpoints, int degree) {
    check_degree(degree);
    const int m = static_cast<int>(breakpoints.size()) - 1;
    if (m < 1) fail("a periodic knot vector needs at least 2 breakpoints (one period)");
    for (double b : breakpoints)
        if (!std::isfinite(b)) fail("knots must be finite");
    const double period = breakpoints.back() - breakpoints.front();
    if (!(period > 0)) fail("periodic breakpoints need b_m > b_0");
    // t_k = b_(k mod m) + floor(k / m) * period for k = -d .. m + d.
    std::vector<double> t;
    for (int k = -degree; k <= m + degree; ++k) {
        const int q = (k >= 0 ? k / m : -((-k + m - 1) / m));
        t.push_back(breakpoints[k - q * m] + q * period);
    }
    return KnotVector(std::move(t), degree, PeriodicTag{});
}

bool KnotVector::clamped() const {
    const int d = degree_, n = num_basis();
    return !periodic_ && knots_[0] == knots_[d] && knots_[n] == knots_[n + d];
}

double KnotVector::to_domain(double x) const {
    const double a = domain_begin(), b = domain_end();
    if (periodic_) {
        const double period = b - a;
        double y = x - period * std::floor((x - a) / period);
        if (y >= b || y < a) y = a;  // rounding at the seam: b is a again
        return std::isnan(x) ? x : y;
    }
    return x < a ? a : (x > b ? b : x);
}

int KnotVector::find_span(double x) const {
    const int d = degree_;
    x = to_domain(x);
    if (!(x < knots_[last_span_ + 1])) return last_span_;  // the right end, and NaN
    if (uniform_) {
        int span = d + static_cast<int>((x - knots_[d]) * inv_h_);
        span = std::min(std::max(span, d), last_span_);
        // The product can be off by one ulp-sized step; the knots decide.
        if (x < knots_[span]) --span;
        else if (x >= knots_[span + 1]) ++span;
        return span;
    }
    // First knot > x among t_{d+1} .. t_{last+1}, minus one.
    auto it = std::upper_bound(knots_.begin() + d + 1, knots_.begin() + last_span_ + 1, x);
    return static_cast<int>(it - knots_.begin()) - 1;
}

void KnotVector::basis(double x, int span, double* out) const {
    const int P = degree_ + 1;
    const double s = (to_domain(x) - knots_[span]) * span_inverse_width(span);
    const double* c = span_polynomial(span);
    for (int j = 0; j < P; ++j) out[j] = c[(P - 1) * P + j];
    for (int k = P - 2; k >= 0; --k)
        for (int j = 0; j < P; ++j) out[j] = out[j] * s + c[k * P + j];
}

std::vector<double> KnotVector::schoenberg_nodes() const {
    std::vector<double> nodes(num_coeffs_);
    for (int i = 0; i < num_coeffs_; ++i) {
        double s = 0;
        if (degree_ == 0) {
            s = 0.5 * knots_[i] + 0.5 * knots_[i + 1];
        } else {
            for (int k = 1; k <= degree_; ++k) s += knots_[i + k];
            s /= degree_;
            if (!std::isfinite(s)) {  // the sum of knots near the largest double overflows
                s = 0;
                for (int k = 1; k <= degree_; ++k) s += knots_[i + k] / degree_;
            }
            // An average lies within its knots; the rounding of a sum of thirds of the largest
            // double does not (it rounded to infinity).
            s = std::clamp(s, knots_[i + 1], knots_[i + degree_]);
        }
        nodes[i] = periodic_ ? to_domain(s) : s;
    }
    return nodes;
}

std::vector<double> KnotVector::basis_integrals() const {
    std::vector<double> w(num_coeffs_);
    for (int i = 0; i < num_coeffs_; ++i) w[i] = (knots_[i + degree_ + 1] - knots_[i]) / (degree_ + 1);
    return w;
}

std::vector<double> KnotVector::basis_integrals_over(double a, double b) const {
    const double lo = domain_begin(), hi = domain_end();
    if (!(a >= lo && b <= hi && a <= b)) {
        std::ostringstream msg;
        msg << "integration interval [" << a << ", " << b << "] must be ordered and inside the domain [" << lo << ", " << hi
            << "]";
        fail(msg.str());
    }
    const int d = degree_, P = d + 1;
    std::vector<double> w(num_coeffs_, 0.0);
    for (int I = d; I <= last_span_; ++I) {
        const double t0 = knots_[I], t1 = knots_[I + 1];
        if (!(t1 > t0) || t1 <= a || t0 >= b) continue;
        const double inv = span_inverse_width(I), width = t1 - t0;
        const double s0 = (std::max(a, t0) - t0) * inv, s1 = (std::min(b, t1) - t0) * inv;
        const double* c = span_polynomial(I);
        double p0 = s0, p1 = s1;  // s^(k+1)
        double moment[kMaxDegree + 1];
        for (int k = 0; k < P; ++k) moment[k] = (p1 - p0) / (k + 1), p0 *= s0, p1 *= s1;
        for (int j = 0; j < P; ++j) {
            double sum = 0;
            for (int k = 0; k < P; ++k) sum += c[k * P + j] * moment[k];
            w[coeff_index(I - d + j)] += width * sum;
        }
    }
    return w;
}

}  // namespace bsgi
