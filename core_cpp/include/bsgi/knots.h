// Knot vectors and the B-spline basis on them (paper section 2).
#pragma once
#include <string>
#include <vector>

namespace bsgi {

constexpr int kMaxDegree = 15;

class KnotVector {
public:
    // Validates: degree >= 0, non-decreasing, no knot repeated more than degree+1 times,
    // at least degree+1 coefficients. Throws std::invalid_argument naming the problem.
    KnotVector(std::vector<double> knots, int degree);

    // Clamped uniform knots (19) on [a, b] with n coefficients: d+1 knots at each end.
    static KnotVector clamped_uniform(int num_coeffs, int degree, double a, double b);

    int degree() const { return degree_; }
    int num_coeffs() const { return static_cast<int>(knots_.size()) - degree_ - 1; }
    const std::vector<double>& knots() const { return knots_; }
    double domain_begin() const { return knots_[degree_]; }
    double domain_end() const { return knots_[num_coeffs()]; }

    // Index I of the knot span [t_I, t_{I+1}) holding x, with degree <= I < num_coeffs().
    // x is clamped to the domain; the right end belongs to the last non-empty span, so the
    // spline is continuous from the left there.
    int find_span(double x) const;

    // The degree+1 basis functions B_{I-d}, ..., B_I non-zero at x in span I (Cox-de Boor).
    void basis(double x, int span, double* out) const;

    // Schoenberg nodes (12): knot averages t*_i = (t_{i+1} + ... + t_{i+d}) / d.
    // Degree 0 has no inner knots to average; its nodes are the span midpoints.
    std::vector<double> schoenberg_nodes() const;

    // Integrals of the basis functions (11): (t_{i+d+1} - t_i) / (d + 1).
    std::vector<double> basis_integrals() const;

private:
    std::vector<double> knots_;
    int degree_;
};

}  // namespace bsgi
