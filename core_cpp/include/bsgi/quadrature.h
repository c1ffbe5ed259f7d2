// B-spline quadrature (paper (11)): integrate the spline approximation of the integrand exactly.
#pragma once
#include <vector>

#include "bsgi/knots.h"

namespace bsgi {

struct QuadratureRule {
    std::vector<double> nodes, weights;
};

// Integral of Schoenberg's approximation (12): nodes are the knot averages, weights the basis
// integrals (11). Order h^2.
QuadratureRule schoenberg_quadrature(const KnotVector& knots);

// Integral of the quadratic quasi-interpolant of paper section 2.2.1,
// a_i = -f(t_{i+1})/2 + 2 f((t_{i+1} + t_{i+2})/2) - f(t_{i+2})/2, which reproduces quadratics:
// nodes are the distinct knots and span midpoints. Needs degree 2.
QuadratureRule quasi_interpolant_quadrature(const KnotVector& knots);

}  // namespace bsgi
