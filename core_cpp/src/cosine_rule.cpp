#include "bsgi/cosine_rule.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>

namespace bsgi {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Gauss-Legendre nodes x and weights on [-1, 1] (Newton on P_n from the asymptotic guesses).
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
    x.assign(n, 0), w.assign(n, 0);
    for (int i = 0; i < n; ++i) {
        double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 1;
        for (int iteration = 0; iteration < 100; ++iteration) {
            double p0 = 1, p1 = z;  // P_0, P_1, then up to P_{n-1}, P_n
            for (int k = 2; k <= n; ++k) {
                const double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k;
                p0 = p1, p1 = p2;
            }
            if (n == 1) p0 = 1, p1 = z;
            dp = n * (z * p1 - p0) / (z * z - 1);
            const double step = p1 / dp;
            z -= step;
            if (std::abs(step) < 1e-15) break;
        }
        x[n - 1 - i] = z;  // increasing
        w[n - 1 - i] = 2 / ((1 - z * z) * dp * dp);
    }
}

}  // namespace

CosineRule::CosineRule(int nt, int np) : nt_(nt), np_(np) {
    if (nt < 1 || np < 1) throw std::invalid_argument("cosine rule: needs at least one node per axis");
    std::vector<double> x, w;
    gauss_legendre(nt, x, w);
    for (const auto& [i, k] : tile_order(nt, np)) {
        const double s = 0.5 * (x[i] + 1), sin_t = std::sqrt(std::max(0.0, 1 - s * s));
        const double phi = 2 * kPi * (k + 0.5 * (1 + (i & 1))) / np;
        directions_.push_back({sin_t * std::cos(phi), sin_t * std::sin(phi), s});
        weights_.push_back(0.5 * w[i] * 2 * s * nt);  // on [0, 1], times 2 s
    }
}

std::vector<std::pair<int, int>> tile_order(int nt, int np) {
    constexpr int kTile = CosineRule::kTile;
    std::vector<std::pair<int, int>> order;
    order.reserve(size_t(nt) * np);
    for (int i0 = 0; i0 < nt; i0 += kTile)
        for (int k0 = 0; k0 < np; k0 += kTile)
            for (int i = i0; i < std::min(nt, i0 + kTile); ++i)
                for (int k = k0; k < std::min(np, k0 + kTile); ++k) order.emplace_back(i, k);
    return order;
}

const CosineRule& cosine_rule(int nt, int np) {
    thread_local std::map<std::pair<int, int>, std::unique_ptr<CosineRule>> rules;
    auto& rule = rules[{nt, np}];
    if (!rule) rule = std::make_unique<CosineRule>(nt, np);
    return *rule;
}

}  // namespace bsgi
