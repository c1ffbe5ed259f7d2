// Knot vectors and the B-spline basis on them (paper section 2.2).
#pragma once
#include <string>
#include <vector>

namespace bsgi {

// Degrees 0..5: beyond quintic the per-span power form below loses accuracy, and radiance
// never needs it (the paper uses quadratics).
constexpr int kMaxDegree = 5;

class KnotVector {
public:
    // Validates: 0 <= degree <= kMaxDegree, finite and non-decreasing knots, no knot repeated
    // more than degree+1 times, at least degree+1 coefficients (2 degree + 2 knots), a
    // non-empty domain [t_d, t_n]. Throws std::invalid_argument naming the problem.
    KnotVector(std::vector<double> knots, int degree);

    // Clamped uniform knots (19) on [a, b] with n coefficients: d+1 knots at each end. The
    // spatial knots of the paper are clamped_uniform(n, d, eps, 1 - eps).
    static KnotVector clamped_uniform(int num_coeffs, int degree, double a, double b);

    // The angular knots (24): clamped uniform on [-R, R].
    static KnotVector symmetric(int num_coeffs, int degree, double R);

    // The bytes an open knot vector of num_coeffs coefficients of this degree holds: the object,
    // its knots and its span tables, with each heap block's own few bytes (for memory estimates).
    static size_t bytes(int num_coeffs, int degree);

    // Periodic extension (paper section 3.2) of the breakpoints b_0 <= ... <= b_m over one period
    // [b_0, b_m]: the stored knots are extended by d knots on each side, repeating the spacing,
    // and basis function j uses coefficient j mod m. There are m coefficients, parameters wrap
    // into [b_0, b_m) and the spline is C^(d-multiplicity) across the seam.
    static KnotVector periodic(const std::vector<double>& breakpoints, int degree);

    int degree() const { return degree_; }
    // Independent coefficients: n for an open knot vector, m (the number of knot spans in one
    // period) for a periodic one.
    int num_coeffs() const { return num_coeffs_; }
    // Basis functions on the stored knots (num_coeffs() + degree() when periodic).
    int num_basis() const { return static_cast<int>(knots_.size()) - degree_ - 1; }
    const std::vector<double>& knots() const { return knots_; }
    bool is_periodic() const { return periodic_; }
    // d+1 equal knots at both ends: the basis interpolates at the ends and (11) is the domain
    // integral.
    bool clamped() const;
    double domain_begin() const { return knots_[degree_]; }
    double domain_end() const { return knots_[num_basis()]; }
    // Coefficient of basis function j (wraps when periodic).
    int coeff_index(int j) const { return periodic_ ? j % num_coeffs_ : j; }

    // The parameter actually used for x: clamped to the domain, or wrapped into one period.
    // NaN stays NaN.
    double to_domain(double x) const;

    // Index I of the knot span [t_I, t_{I+1}) holding to_domain(x), with degree <= I < num_basis().
    // The right end belongs to the last non-empty span, so the spline is continuous from the left
    // there; inner knots belong to the span on their right. NaN gives the last span.
    int find_span(double x) const;

    // The degree+1 basis functions B_{I-d}, ..., B_I at to_domain(x) in span I.
    void basis(double x, int span, double* out) const;

    // Schoenberg nodes (12): knot averages t*_i = (t_{i+1} + ... + t_{i+d}) / d, one per
    // coefficient (wrapped into the period when periodic). Degree 0 has no inner knots to
    // average; its nodes are the span midpoints.
    std::vector<double> schoenberg_nodes() const;

    // Integrals of the basis functions over their support (11): (t_{i+d+1} - t_i) / (d + 1).
    std::vector<double> basis_integrals() const;

    // Integrals of the num_coeffs() basis functions over [a, b] (inside the domain, a <= b),
    // exact from the per-span polynomials. Over the domain of a clamped or periodic knot vector
    // they equal (11).
    std::vector<double> basis_integrals_over(double a, double b) const;

    // The basis functions as polynomials on each non-empty span, used by the evaluators:
    // on span I, B_{I-d+j}(x) = sum_k c[k][j] s^k with s = (x - t_I) / (t_{I+1} - t_I) in [0, 1].
    // span_polynomial(I) points at the (d+1) x (d+1) table c, k-major, so one Horner step updates
    // all d+1 functions at once.
    const double* span_polynomial(int span) const { return &span_poly_[(span - degree_) * (degree_ + 1) * (degree_ + 1)]; }
    double span_inverse_width(int span) const { return span_inv_width_[span - degree_]; }
    const double* span_inverse_widths() const { return span_inv_width_.data(); }  // from span d
    int last_span() const { return last_span_; }
    // Equal spans over the domain: find_span is a multiplication instead of a search.
    bool uniform_spans() const { return uniform_; }
    double inverse_span_width() const { return inv_h_; }

private:
    struct PeriodicTag {};
    KnotVector(std::vector<double> knots, int degree, PeriodicTag);
    void validate() const;
    void precompute();

    std::vector<double> knots_;
    int degree_;
    int num_coeffs_ = 0;
    bool periodic_ = false;
    int last_span_ = 0;
    bool uniform_ = false;
    double inv_h_ = 0;
    std::vector<double> span_poly_, span_inv_width_;
};

}  // namespace bsgi
