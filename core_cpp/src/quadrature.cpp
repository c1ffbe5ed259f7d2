#include "bsgi/quadrature.h"

#include <map>
#include <stdexcept>

namespace bsgi {

QuadratureRule schoenberg_quadrature(const KnotVector& knots) {
    return {knots.schoenberg_nodes(), knots.basis_integrals()};
}

QuadratureRule quasi_interpolant_quadrature(const KnotVector& knots) {
    if (knots.degree() != 2) throw std::invalid_argument("quasi-interpolant quadrature needs degree 2");
    const auto& t = knots.knots();
    const std::vector<double> w = knots.basis_integrals();
    std::map<double, double> rule;  // node -> weight, merging shared nodes
    for (int i = 0; i < knots.num_coeffs(); ++i) {
        const double a = t[i + 1], b = t[i + 2];
        rule[a] += -0.5 * w[i];
        rule[0.5 * (a + b)] += 2.0 * w[i];
        rule[b] += -0.5 * w[i];
    }
    QuadratureRule q;
    for (const auto& [x, weight] : rule)
        if (weight != 0) q.nodes.push_back(x), q.weights.push_back(weight);
    return q;
}

}  // namespace bsgi
