#include "bsgi/tensor_spline.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "bsgi/parallel.h"

namespace bsgi {

namespace {
constexpr int kMaxDims = 8;
}

size_t TensorSpline::coefficient_bytes(const std::vector<KnotVector>& axes, int channels) {
    size_t n = static_cast<size_t>(channels) * sizeof(double);
    for (const auto& a : axes) n *= static_cast<size_t>(a.num_coeffs());
    return n;
}

TensorSpline::TensorSpline(std::vector<KnotVector> axes, int channels) : axes_(std::move(axes)), channels_(channels) {
    if (axes_.empty() || axes_.size() > kMaxDims)
        throw std::invalid_argument("tensor spline: needs 1.." + std::to_string(kMaxDims) + " dimensions");
    if (channels_ < 1) throw std::invalid_argument("tensor spline: needs at least one channel");
    strides_.assign(axes_.size(), 1);
    for (int i = dims() - 2; i >= 0; --i) strides_[i] = strides_[i + 1] * axes_[i + 1].num_coeffs();
    coeffs_.assign(strides_[0] * axes_[0].num_coeffs() * channels_, 0.0);
}

std::vector<size_t> TensorSpline::shape() const {
    std::vector<size_t> s;
    for (const auto& a : axes_) s.push_back(a.num_coeffs());
    s.push_back(channels_);
    return s;
}

void TensorSpline::evaluate(const double* x, double* out) const {
    const int D = dims();
    double basis[kMaxDims][kMaxDegree + 1];
    size_t first[kMaxDims];  // index of the first non-zero coefficient per axis
    int order[kMaxDims];
    for (int k = 0; k < D; ++k) {
        const KnotVector& a = axes_[k];
        const int span = a.find_span(x[k]);
        a.basis(x[k], span, basis[k]);
        first[k] = static_cast<size_t>(span - a.degree());
        order[k] = a.degree() + 1;
    }
    for (int c = 0; c < channels_; ++c) out[c] = 0.0;
    // Odometer over the (d_0+1) x ... x (d_{D-1}+1) block of non-zero coefficients.
    int idx[kMaxDims] = {0};
    for (;;) {
        double w = 1.0;
        size_t offset = 0;
        for (int k = 0; k < D; ++k) {
            w *= basis[k][idx[k]];
            offset += (first[k] + idx[k]) * strides_[k];
        }
        const double* a = &coeffs_[offset * channels_];
        for (int c = 0; c < channels_; ++c) out[c] += w * a[c];
        int k = D - 1;
        while (k >= 0 && ++idx[k] == order[k]) idx[k--] = 0;
        if (k < 0) break;
    }
}

void TensorSpline::evaluate_batch(const double* xs, size_t count, double* out, int threads) const {
    const int D = dims();
    parallel_for(count, 4096, threads, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) evaluate(xs + i * D, out + i * channels_);
    });
}

}  // namespace bsgi
