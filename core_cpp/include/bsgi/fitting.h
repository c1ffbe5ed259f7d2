// Fitting splines to functions by local rules (paper section 2.2.1, (12), (25)): every
// coefficient is a fixed combination of values of f at a few nodes near its B-spline, so a
// tensor-product fit is the univariate rule applied along one dimension after another.
#pragma once
#include <functional>
#include <vector>

#include "bsgi/knots.h"
#include "bsgi/tensor_spline.h"

namespace bsgi {

enum class FitMethod {
    // a_i = f(t*_i) at the knot averages (12): any degree, reproduces linear functions, O(h^2).
    Schoenberg,
    // Degree 2: a_i = -f(t_{i+1})/2 + 2 f((t_{i+1} + t_{i+2})/2) - f(t_{i+2})/2 (section 2.2.1),
    // reproduces quadratics, O(h^3).
    QuadraticQuasiInterpolant,
    // Degree 3, after Lee, Lyche and Morken (2000): a_i is the dual functional (the blossom at
    // t_{i+1}, t_{i+2}, t_{i+3}) of the cubic interpolating f at the ends and the two span
    // midpoints of [t_{i+1}, t_{i+3}]; reproduces cubics, O(h^4). It samples f at the same kind
    // of nodes (knots and span midpoints) as the quadratic one.
    CubicQuasiInterpolant,
};

// The rule of one axis: a_i = sum over its terms of weight * f(nodes[node_index]).
struct FitRule {
    FitMethod method;
    std::vector<double> nodes;      // distinct, increasing, inside the domain (wrapped when periodic)
    std::vector<size_t> row_start;  // num_coeffs() + 1 offsets into node_index / weight
    std::vector<int> node_index;
    std::vector<double> weight;
    int num_coeffs() const { return static_cast<int>(row_start.size()) - 1; }
};

// Throws std::invalid_argument when the method does not fit the degree (the quasi-interpolants
// are defined for degrees 2 and 3).
FitRule make_fit_rule(const KnotVector& knots, FitMethod method);

// One rule per axis of the spline, all with the same method.
std::vector<FitRule> make_fit_rules(const TensorSpline& spline, FitMethod method);

// Sets the coefficients from samples of f on the grid nodes_0 x ... x nodes_{D-1} of the rules,
// C order with the channels last (so (25) for the Schoenberg rule).
void fit_from_samples(TensorSpline& spline, const std::vector<FitRule>& rules, const double* samples);

// f(x, value): x has dims() parameters, value receives channels() numbers. Called once per grid
// node, from `threads` threads (0 = all), so it must be thread-safe.
using FitFunction = std::function<void(const double* x, double* value)>;
void fit(TensorSpline& spline, const std::vector<FitRule>& rules, const FitFunction& f, int threads = 0);

}  // namespace bsgi
