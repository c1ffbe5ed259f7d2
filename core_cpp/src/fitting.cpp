#include "bsgi/fitting.h"

#include <algorithm>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string>

#include "bsgi/memory_budget.h"
#include "bsgi/parallel.h"

namespace bsgi {

namespace {

// Knot t_k of the stored vector, continued periodically beyond its ends when periodic.
double knot(const KnotVector& kv, int k) {
    const auto& t = kv.knots();
    if (!kv.is_periodic()) return t[std::clamp(k, 0, int(t.size()) - 1)];
    const int m = kv.num_coeffs();
    const double period = kv.domain_end() - kv.domain_begin();
    double shift = 0;
    while (k > int(t.size()) - 1) k -= m, shift += period;
    while (k < 0) k += m, shift -= period;
    return t[k] + shift;
}

// Weights w_k with blossom(p)(y_1..y_d) = sum_k w_k p(x_k) for every polynomial p of degree <= d,
// where x_0..x_d are distinct: the blossom of each Lagrange polynomial, the symmetrised product
// of its d linear factors.
std::vector<double> blossom_weights(const std::vector<double>& x, const std::vector<double>& y) {
    const int d = int(y.size());
    std::vector<double> w(x.size());
    for (size_t k = 0; k < x.size(); ++k) {
        std::vector<double> z;
        double denom = 1;
        for (size_t m = 0; m < x.size(); ++m)
            if (m != k) z.push_back(x[m]), denom *= x[k] - x[m];
        std::vector<int> perm(d);
        std::iota(perm.begin(), perm.end(), 0);
        double sum = 0;
        int count = 0;
        do {
            double prod = 1;
            for (int r = 0; r < d; ++r) prod *= y[perm[r]] - z[r];
            sum += prod, ++count;
        } while (std::next_permutation(perm.begin(), perm.end()));
        w[k] = sum / count / denom;
    }
    return w;
}

struct Row {
    std::vector<double> x, w;
};

// Quasi-interpolant row of coefficient i (degree 2 or 3): a local interval I inside the domain and
// the support of B_i, the polynomial interpolating f at nodes of I, its blossom at t_{i+1..i+d}.
Row quasi_interpolant_row(const KnotVector& kv, int i) {
    const int d = kv.degree();
    std::vector<double> y;
    for (int r = 1; r <= d; ++r) y.push_back(knot(kv, i + r));
    const double lo_dom = kv.domain_begin(), hi_dom = kv.domain_end();
    // All of t_{i+1..i+d} at one point c: the coefficient is f(c) (the blossom on the diagonal).
    if (y.front() == y.back() && (kv.is_periodic() || (y[0] >= lo_dom && y[0] <= hi_dom)))
        return {{y[0]}, {1.0}};
    int lo = i + 1, hi = i + d;
    const int n = kv.num_basis();
    if (!kv.is_periodic()) lo = std::max(lo, d), hi = std::min(hi, n), lo = std::min(lo, hi);
    auto distinct = [&] {
        int c = 1;
        for (int k = lo + 1; k <= hi; ++k) c += knot(kv, k) != knot(kv, k - 1);
        return c;
    };
    const int need = d == 2 ? 2 : 3;  // one span for the quadratic, two for the cubic
    for (bool grow_hi = true; distinct() < need; grow_hi = !grow_hi) {
        const bool can_hi = kv.is_periodic() || hi < n, can_lo = kv.is_periodic() || lo > d;
        if (!can_hi && !can_lo) break;
        if ((grow_hi && can_hi) || !can_lo) ++hi;
        else --lo;
    }
    const double a = knot(kv, lo), b = knot(kv, hi);
    std::vector<double> x;
    if (d == 2) {
        x = {a, 0.5 * (a + b), b};
    } else if (distinct() >= 3) {
        int first = lo;  // first non-empty span [t_first, t_first+1]
        while (knot(kv, first + 1) == knot(kv, first)) ++first;
        int last = hi - 1;
        while (knot(kv, last + 1) == knot(kv, last)) --last;
        x = {a, 0.5 * (knot(kv, first) + knot(kv, first + 1)), 0.5 * (knot(kv, last) + knot(kv, last + 1)), b};
    } else {  // the whole domain is a single span
        x = {a, a + (b - a) / 3, a + 2 * (b - a) / 3, b};
    }
    return {x, blossom_weights(x, y)};
}

}  // namespace

FitRule make_fit_rule(const KnotVector& kv, FitMethod method) {
    const int d = kv.degree();
    if (method == FitMethod::QuadraticQuasiInterpolant && d != 2)
        throw std::invalid_argument("fitting: the quadratic quasi-interpolant needs degree 2, got degree " + std::to_string(d));
    if (method == FitMethod::CubicQuasiInterpolant && d != 3)
        throw std::invalid_argument("fitting: the cubic quasi-interpolant needs degree 3, got degree " + std::to_string(d));
    std::vector<Row> rows;
    if (method == FitMethod::Schoenberg) {
        for (double x : kv.schoenberg_nodes()) rows.push_back({{x}, {1.0}});
    } else {
        for (int i = 0; i < kv.num_coeffs(); ++i) rows.push_back(quasi_interpolant_row(kv, i));
    }
    // Shared node list: each node appears once, however many rows use it.
    std::map<double, int> index;
    for (auto& r : rows)
        for (double& x : r.x) x = kv.is_periodic() ? kv.to_domain(x) : x, index[x] = 0;
    FitRule rule;
    rule.method = method;
    for (auto& [x, k] : index) k = int(rule.nodes.size()), rule.nodes.push_back(x);
    rule.row_start.push_back(0);
    for (const auto& r : rows) {
        std::map<int, double> terms;  // merges a node used twice in one row
        for (size_t k = 0; k < r.x.size(); ++k) terms[index[r.x[k]]] += r.w[k];
        for (const auto& [node, w] : terms) rule.node_index.push_back(node), rule.weight.push_back(w);
        rule.row_start.push_back(rule.node_index.size());
    }
    return rule;
}

std::vector<FitRule> make_fit_rules(const TensorSpline& spline, FitMethod method) {
    std::vector<FitRule> rules;
    for (const auto& a : spline.axes()) rules.push_back(make_fit_rule(a, method));
    return rules;
}

void fit_from_samples(TensorSpline& spline, const std::vector<FitRule>& rules, const double* samples) {
    const int D = spline.dims(), C = spline.channels();
    if (int(rules.size()) != D)
        throw std::invalid_argument("fitting: needs one rule per dimension (" + std::to_string(D) + "), got " +
                                    std::to_string(rules.size()));
    std::vector<size_t> ext;
    for (int k = 0; k < D; ++k) {
        if (rules[k].num_coeffs() != spline.axis(k).num_coeffs())
            throw std::invalid_argument("fitting: the rule of axis " + std::to_string(k) + " is for another knot vector");
        ext.push_back(rules[k].nodes.size());
    }
    ext.push_back(size_t(C));
    const size_t total = check_memory_budget("fitting samples", ext, sizeof(double)) / sizeof(double);
    std::vector<double> cur(samples, samples + total), next;
    // Axis k: (outer, m_k, inner) -> (outer, n_k, inner).
    for (int k = 0; k < D; ++k) {
        const FitRule& r = rules[k];
        const size_t m = r.nodes.size(), n = size_t(r.num_coeffs());
        size_t inner = size_t(C);
        for (int j = k + 1; j < D; ++j) inner *= rules[j].nodes.size();
        const size_t outer = cur.size() / (m * inner);
        next.assign(outer * n * inner, 0.0);
        for (size_t o = 0; o < outer; ++o)
            for (size_t i = 0; i < n; ++i) {
                double* dst = &next[(o * n + i) * inner];
                for (size_t t = r.row_start[i]; t < r.row_start[i + 1]; ++t) {
                    const double* src = &cur[(o * m + size_t(r.node_index[t])) * inner];
                    const double w = r.weight[t];
                    for (size_t q = 0; q < inner; ++q) dst[q] += w * src[q];
                }
            }
        cur.swap(next);
    }
    if (spline.precision() == Precision::Float32) {
        float* a = spline.coeffs_f32();
        for (size_t i = 0; i < cur.size(); ++i) a[i] = float(cur[i]);
    } else {
        spline.coeffs() = cur;
    }
}

void fit(TensorSpline& spline, const std::vector<FitRule>& rules, const FitFunction& f, int threads) {
    const int D = spline.dims(), C = spline.channels();
    if (int(rules.size()) != D) throw std::invalid_argument("fitting: needs one rule per dimension");
    std::vector<size_t> ext;
    for (const auto& r : rules) ext.push_back(r.nodes.size());
    ext.push_back(size_t(C));
    const size_t total = check_memory_budget("fitting samples", ext, sizeof(double)) / sizeof(double);
    std::vector<double> samples(total);
    const size_t points = total / C;
    parallel_for(points, 64, threads, [&](size_t begin, size_t end) {
        double x[TensorSpline::kMaxDims];
        for (size_t p = begin; p < end; ++p) {
            size_t rest = p;
            for (int k = D - 1; k >= 0; --k) {
                const size_t m = rules[k].nodes.size();
                x[k] = rules[k].nodes[rest % m];
                rest /= m;
            }
            f(x, &samples[p * C]);
        }
    });
    fit_from_samples(spline, rules, samples.data());
}

}  // namespace bsgi
