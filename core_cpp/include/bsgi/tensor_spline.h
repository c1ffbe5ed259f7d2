// Tensor-product B-spline with vector-valued (e.g. RGB) coefficients, paper eqs. (13)-(18).
#pragma once
#include <cstddef>
#include <memory>
#include <vector>

#include "bsgi/hemisphere_map.h"
#include "bsgi/knots.h"

namespace bsgi {

namespace detail {
struct KernelArgs;
using Kernel = void (*)(const KernelArgs&, size_t begin, size_t end, double* out);  // spline_kernels.h

// What the evaluation kernels read of a spline of at most four open axes besides its
// coefficients, one lane per axis, kept with the spline: the solver evaluates one point per ray,
// and gathering these from the knot vectors per call (pointer chases, and stores the kernel then
// reloaded) took more than half of the evaluation's time. Pointers into the axes, which copies
// of the spline share.
struct alignas(32) SplineLanes {
    double lo[4], hi[4];  // domain
    double inv_h[4];      // 1 / span width where the spans are uniform, else 0
    int last[4];          // last span index - degree
    const double* poly[4];       // KnotVector::span_polynomial(degree)
    const double* knots[4];      // t_0 ...
    const double* inv_width[4];  // KnotVector::span_inverse_widths()
    size_t stride[4];            // in values
};
using PointKernel = void (*)(const SplineLanes&, const void* coeffs, const double* x, double* out);
}  // namespace detail

// Storage of the coefficients. Float32 halves the memory and the cache traffic of evaluation;
// the specialised kernels then also do the contraction in float (twice the lanes per
// instruction). Bound, from the arithmetic: every term B(x) a of the sum goes through at most
// d + 2 roundings per axis (its basis value rounded to float, then d + 1 products and sums of the
// nested contraction (18)) plus the rounding of the coefficient itself, so with u = 2^-24 and
// K = D (d + 2) + 1,
//     |L_float32(x) - L(x)| <= K u / (1 - K u) * sum |B(x) a| <= K u / (1 - K u) * max |a|,
// where L has the float64 coefficients; e.g. 1.0e-6 max|a| for the 4D quadratic radiance spline.
// Float64 agrees with exact arithmetic to a few units of 1e-16 relative.
enum class Precision { Float64, Float32 };

// What evaluating a spline reads besides its coefficients, fixed by its axes and channels: the
// strides, the kernels' lanes (pointers into the axes, which it owns) and the point kernels.
// Splines made from one layout share it (a receiver's spline sets and sides, and the solver's
// receivers of equal knots): held by each spline it was 384 bytes, more than a small surface's
// coefficients.
class SplineLayout {
public:
    // Throws std::invalid_argument for no axes, more than TensorSpline::kMaxDims or channels < 1.
    SplineLayout(std::shared_ptr<const std::vector<KnotVector>> axes, int channels);
    SplineLayout(const SplineLayout&) = delete;  // the lanes point into the axes it holds
    SplineLayout& operator=(const SplineLayout&) = delete;

    const std::shared_ptr<const std::vector<KnotVector>>& axes() const { return axes_; }
    int channels() const { return channels_; }
    int dims() const { return static_cast<int>(axes_->size()); }
    size_t stride(int axis) const { return strides_[axis]; }
    size_t num_values() const { return values_; }
    const detail::SplineLanes& lanes() const { return lanes_; }
    // Whether the axes are what the specialised kernels take (open, of one degree, at most four):
    // the lanes are filled.
    bool has_lanes() const { return has_lanes_; }
    // The specialised kernel for one point at this storage, if any.
    detail::PointKernel point_kernel(bool float32) const { return point_kernel_[float32]; }

private:
    std::shared_ptr<const std::vector<KnotVector>> axes_;
    int channels_;
    std::vector<size_t> strides_;
    size_t values_ = 0;
    detail::SplineLanes lanes_{};
    bool has_lanes_ = false;
    detail::PointKernel point_kernel_[2] = {nullptr, nullptr};  // float64, float32
};

class TensorSpline {
public:
    static constexpr int kMaxDims = 8;

    // Coefficients start at zero. Their layout is C order over (n_0, ..., n_{D-1}, channels),
    // the last axis fastest, so numpy sees them as an array of that shape. The size is checked
    // against the memory budget (memory_budget.h) before anything is allocated.
    TensorSpline(std::vector<KnotVector> axes, int channels, Precision precision = Precision::Float64);
    // Splines of the same axes (a receiver's spline sets, copies) share them: a small surface's
    // knot vectors and their span tables take more memory than its coefficients.
    TensorSpline(std::shared_ptr<const std::vector<KnotVector>> axes, int channels,
                 Precision precision = Precision::Float64);
    // Splines of one layout share it (and its axes).
    explicit TensorSpline(std::shared_ptr<const SplineLayout> layout, Precision precision = Precision::Float64);

    int dims() const { return layout_->dims(); }
    int channels() const { return layout_->channels(); }
    Precision precision() const { return precision_; }
    const std::vector<KnotVector>& axes() const { return *layout_->axes(); }
    // The axes as shared: a spline made from them shares them too.
    const std::shared_ptr<const std::vector<KnotVector>>& shared_axes() const { return layout_->axes(); }
    // The layout as shared: a spline made from it shares it (and the axes).
    const std::shared_ptr<const SplineLayout>& layout() const { return layout_; }
    const KnotVector& axis(int i) const { return (*layout_->axes())[i]; }
    std::vector<size_t> shape() const;  // (n_0, ..., n_{D-1}, channels)
    size_t num_values() const;          // product of shape()
    size_t bytes() const;               // of the coefficients

    // The coefficients of a Float64 spline (std::logic_error for Float32), and the num_values()
    // coefficients of a Float32 one (std::logic_error for Float64).
    std::vector<double>& coeffs();
    const std::vector<double>& coeffs() const;
    float* coeffs_f32();
    const float* coeffs_f32() const;
    // Float32 storage ends with this many zeros, so that the kernels may load whole vectors.
    static constexpr size_t kFloat32Padding = 16;
    // Copy with the other storage.
    TensorSpline with_precision(Precision precision) const;

    // Value at x (dims() parameters) into out (channels() values). Parameters outside the domain
    // are clamped to it (wrapped on periodic axes); a NaN or infinite parameter gives NaN in
    // every channel. Same kernel as evaluate_batch where one exists (the solver calls this per
    // ray), without the batch's threads and allocations.
    void evaluate(const double* x, double* out) const;

    // Batched evaluation: xs is count x dims, out is count x channels, from `threads` threads
    // (0 = all hardware threads). Same rules as evaluate().
    void evaluate_batch(const double* xs, size_t count, double* out, int threads = 0) const;

    // Radiance L(u, v, alpha, beta) of a 4D spline at surface parameters uv (count x 2) seen along
    // local directions dirs (count x 3, frame (1)-(3), any positive length), through the inverse
    // hemisphere map: (alpha, beta) = map.to_disc(direction). A zero or non-finite direction
    // gives NaN.
    void evaluate_directions(const double* uv, const double* dirs, size_t count, const HemisphereMap& map, double* out,
                             int threads = 0) const;

    // Integral over the whole domain, per channel: (11) on clamped and periodic axes.
    void integral(double* out) const;
    // Integral over the box [lo_k, hi_k] (inside the domain) per channel.
    void integral_over(const double* lo, const double* hi, double* out) const;

    // Bytes the coefficients of such a spline would take: checked before allocating.
    static size_t coefficient_bytes(const std::vector<KnotVector>& axes, int channels,
                                    Precision precision = Precision::Float64);
    // Throws MemoryBudgetExceeded (memory_budget.h) where such a spline's coefficients would be
    // over the budget, as constructing it would, without allocating.
    static void check_memory_budget(const std::vector<KnotVector>& axes, int channels,
                                    Precision precision = Precision::Float64);

    // Whether evaluate_batch uses a compiled kernel specialised for this shape (else the generic
    // one): all axes open with one degree <= 3, 2 or 4 dimensions, 1 or 3 channels.
    bool has_fast_kernel() const;

    // Strides of the axes, in values (coefficients x channels).
    size_t stride(int axis) const { return layout_->stride(axis); }

private:
    const void* data() const;
    void evaluate_in_cell_order(detail::Kernel kernel, detail::Kernel params_kernel, const detail::KernelArgs& args,
                                size_t b, size_t e, double* out) const;
    template <typename Loader>
    void evaluate_with(const Loader& loader, size_t count, double* out, int threads, bool directions,
                       const HemisphereMap* map) const;
    void contract(const std::vector<std::vector<double>>& weights, double* out) const;

    std::shared_ptr<const SplineLayout> layout_;  // immutable, shared by copies
    Precision precision_;
    std::vector<double> coeffs_;
    std::vector<float> coeffs32_;
};

}  // namespace bsgi
