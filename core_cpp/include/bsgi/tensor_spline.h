// Tensor-product B-spline with vector-valued (e.g. RGB) coefficients, paper eqs. (13)-(18).
#pragma once
#include <cstddef>
#include <vector>

#include "bsgi/knots.h"

namespace bsgi {

class TensorSpline {
public:
    // Coefficients start at zero. Their layout is C order over (n_0, ..., n_{D-1}, channels),
    // the last axis fastest, so numpy sees them as an array of that shape.
    TensorSpline(std::vector<KnotVector> axes, int channels);

    int dims() const { return static_cast<int>(axes_.size()); }
    int channels() const { return channels_; }
    const std::vector<KnotVector>& axes() const { return axes_; }
    const KnotVector& axis(int i) const { return axes_[i]; }
    std::vector<double>& coeffs() { return coeffs_; }
    const std::vector<double>& coeffs() const { return coeffs_; }
    std::vector<size_t> shape() const;  // (n_0, ..., n_{D-1}, channels)

    // Value at x (dims() parameters, clamped to the domain) into out (channels() values).
    void evaluate(const double* x, double* out) const;

    // Batched evaluation: xs is count x dims, out is count x channels; uses `threads` threads
    // (0 = all hardware threads).
    void evaluate_batch(const double* xs, size_t count, double* out, int threads = 0) const;

    // Bytes the coefficients of such a spline would take: checked before allocating.
    static size_t coefficient_bytes(const std::vector<KnotVector>& axes, int channels);

private:
    std::vector<KnotVector> axes_;
    int channels_;
    std::vector<size_t> strides_;  // in coefficients (not channels), per axis
    std::vector<double> coeffs_;
};

}  // namespace bsgi
