#include "bsgi/tensor_spline.h"

#include <cfloat>
#include <cmath>
#include <stdexcept>
#include <string>

#include "bsgi/memory_budget.h"
#include "bsgi/parallel.h"
#include "spline_kernels.h"

namespace bsgi {

namespace {

constexpr size_t kChunk = 2048;  // points per parallel work item
// Big batches on 4D splines bigger than this are evaluated in the order of their knot cell on the
// first three axes, kCellChunk points at a time: then the 27 rows of coefficients a cell's points
// read (each row: all of the last axis, about 10 KB in all for the radiance spline) stay in the
// core's L1 cache while its points are evaluated, instead of every point reading from all over
// the table.
constexpr size_t kCellOrderBytes = size_t(1) << 19;
constexpr size_t kCellChunk = size_t(1) << 14;

// Span number (0 ..) of x on an open axis, x clamped to the domain (NaN: 0), branch-free where
// the spans are uniform.
struct SpanNumber {
    const KnotVector& a;
    double lo = a.domain_begin(), hi = a.domain_end(), inv_h = a.uniform_spans() ? a.inverse_span_width() : 0;
    int last = a.last_span() - a.degree();
    int operator()(double x) const {
        x = x >= lo ? x : lo;  // NaN too
        x = x <= hi ? x : hi;
        return inv_h > 0 ? std::min(int((x - lo) * inv_h), last) : a.find_span(x) - a.degree();
    }
};

size_t element_bytes(Precision p) { return p == Precision::Float32 ? sizeof(float) : sizeof(double); }

std::vector<size_t> extents(const std::vector<KnotVector>& axes, int channels) {
    std::vector<size_t> e;
    for (const auto& a : axes) e.push_back(size_t(a.num_coeffs()));
    e.push_back(size_t(channels));
    return e;
}

// Any shape, periodic axes, mixed degrees: the odometer over the (d_0+1) x ... x (d_{D-1}+1)
// block of non-zero coefficients, with the KnotVector doing span search and basis.
template <typename T, typename Loader>
void evaluate_generic(const TensorSpline& s, const T* coeffs, const Loader& load, size_t begin, size_t end, double* out) {
    const int D = s.dims(), C = s.channels();
    constexpr int kMaxDims = TensorSpline::kMaxDims;
    double x[kMaxDims], basis[kMaxDims][kMaxDegree + 1];
    int first[kMaxDims], order[kMaxDims];
    for (size_t i = begin; i < end; ++i) {
        load(i, x);
        bool finite = true;
        for (int k = 0; k < D; ++k) {
            const KnotVector& a = s.axis(k);
            finite &= std::fabs(x[k]) <= DBL_MAX;
            const double xk = a.to_domain(std::fabs(x[k]) <= DBL_MAX ? x[k] : a.domain_begin());
            const int span = a.find_span(xk);
            a.basis(xk, span, basis[k]);
            first[k] = span - a.degree();
            order[k] = a.degree() + 1;
        }
        double* o = out + i * C;
        for (int c = 0; c < C; ++c) o[c] = 0.0;
        int idx[kMaxDims] = {0};
        for (;;) {
            double w = 1.0;
            size_t offset = 0;
            for (int k = 0; k < D; ++k) {
                w *= basis[k][idx[k]];
                offset += size_t(s.axis(k).coeff_index(first[k] + idx[k])) * s.stride(k);
            }
            const T* a = coeffs + offset;
            for (int c = 0; c < C; ++c) o[c] += w * double(a[c]);
            int k = D - 1;
            while (k >= 0 && ++idx[k] == order[k]) idx[k--] = 0;
            if (k < 0) break;
        }
        if (!finite)
            for (int c = 0; c < C; ++c) o[c] = NAN;
    }
}

}  // namespace

size_t TensorSpline::coefficient_bytes(const std::vector<KnotVector>& axes, int channels, Precision precision) {
    return array_bytes(extents(axes, channels), element_bytes(precision));
}

void TensorSpline::check_memory_budget(const std::vector<KnotVector>& axes, int channels, Precision precision) {
    bsgi::check_memory_budget("tensor spline coefficients", extents(axes, channels), element_bytes(precision));
}

TensorSpline::TensorSpline(std::vector<KnotVector> axes, int channels, Precision precision)
    : TensorSpline(std::make_shared<const std::vector<KnotVector>>(std::move(axes)), channels, precision) {}

SplineLayout::SplineLayout(std::shared_ptr<const std::vector<KnotVector>> axes, int channels)
    : axes_(std::move(axes)), channels_(channels) {
    if (!axes_ || axes_->empty() || axes_->size() > size_t(TensorSpline::kMaxDims))
        throw std::invalid_argument("tensor spline: needs 1.." + std::to_string(TensorSpline::kMaxDims) + " dimensions, got " +
                                    std::to_string(axes_ ? axes_->size() : 0));
    if (channels_ < 1) throw std::invalid_argument("tensor spline: needs at least one channel");
    const int D = dims();
    strides_.assign(size_t(D), size_t(channels_));
    for (int i = D - 2; i >= 0; --i) strides_[i] = strides_[i + 1] * (*axes_)[i + 1].num_coeffs();
    values_ = strides_[0] * (*axes_)[0].num_coeffs();
    // The lanes of the specialised kernels: open axes of one degree, at most four.
    const int degree = (*axes_)[0].degree();
    bool uniform = true;
    for (const auto& a : *axes_)
        if (a.is_periodic() || a.degree() != degree || D > 4) return;
    has_lanes_ = true;
    for (int k = 0; k < D; ++k) {
        const KnotVector& a = (*axes_)[k];
        uniform = uniform && a.uniform_spans();
        lanes_.lo[k] = a.domain_begin(), lanes_.hi[k] = a.domain_end();
        lanes_.inv_h[k] = a.uniform_spans() ? a.inverse_span_width() : 0.0;
        lanes_.last[k] = a.last_span() - a.degree();
        lanes_.poly[k] = a.span_polynomial(a.degree()), lanes_.knots[k] = a.knots().data();
        lanes_.inv_width[k] = a.span_inverse_widths(), lanes_.stride[k] = strides_[k];
    }
    for (int f32 = 0; f32 < 2; ++f32)
        if (detail::find_kernel(D, degree + 1, channels_, f32, false, false))
            point_kernel_[f32] = detail::find_point_kernel(D, degree + 1, channels_, f32, uniform);
}

TensorSpline::TensorSpline(std::shared_ptr<const std::vector<KnotVector>> axes, int channels, Precision precision)
    : TensorSpline(std::make_shared<const SplineLayout>(std::move(axes), channels), precision) {}

TensorSpline::TensorSpline(std::shared_ptr<const SplineLayout> layout, Precision precision)
    : layout_(std::move(layout)), precision_(precision) {
    if (!layout_) throw std::invalid_argument("tensor spline: no layout");
    check_memory_budget(axes(), channels(), precision_);
    const size_t n = layout_->num_values();
    if (precision_ == Precision::Float32) coeffs32_.assign(n + kFloat32Padding, 0.0f);
    else coeffs_.assign(n, 0.0);
}

std::vector<size_t> TensorSpline::shape() const { return extents(axes(), channels()); }
size_t TensorSpline::num_values() const { return layout_->num_values(); }
size_t TensorSpline::bytes() const { return num_values() * element_bytes(precision_); }

std::vector<double>& TensorSpline::coeffs() {
    if (precision_ != Precision::Float64) throw std::logic_error("tensor spline: coefficients are float32, use coeffs_f32()");
    return coeffs_;
}
const std::vector<double>& TensorSpline::coeffs() const { return const_cast<TensorSpline*>(this)->coeffs(); }
float* TensorSpline::coeffs_f32() {
    if (precision_ != Precision::Float32) throw std::logic_error("tensor spline: coefficients are float64, use coeffs()");
    return coeffs32_.data();
}
const float* TensorSpline::coeffs_f32() const { return const_cast<TensorSpline*>(this)->coeffs_f32(); }
const void* TensorSpline::data() const {
    return precision_ == Precision::Float32 ? static_cast<const void*>(coeffs32_.data()) : coeffs_.data();
}

TensorSpline TensorSpline::with_precision(Precision precision) const {
    TensorSpline s(layout_, precision);
    if (precision == Precision::Float32) {
        if (precision_ == Precision::Float32) s.coeffs32_ = coeffs32_;
        else
            for (size_t i = 0; i < coeffs_.size(); ++i) s.coeffs32_[i] = float(coeffs_[i]);
    } else {
        if (precision_ == Precision::Float64) s.coeffs_ = coeffs_;
        else
            for (size_t i = 0; i < num_values(); ++i) s.coeffs_[i] = coeffs32_[i];
    }
    return s;
}

bool TensorSpline::has_fast_kernel() const {
    return layout_->has_lanes() && detail::find_kernel(dims(), axes()[0].degree() + 1, channels(), precision_ == Precision::Float32, false, false) != nullptr;
}

// Points b .. e of a 4D batch in the order of their knot cell on the first three axes (a counting
// sort), through `params_kernel`: directions are mapped to (alpha, beta) first, the parameters
// gathered into that order, and the values put back in the caller's. `kernel` is the one for the
// input as given (parameters or directions).
void TensorSpline::evaluate_in_cell_order(detail::Kernel kernel, detail::Kernel params_kernel, const detail::KernelArgs& args,
                                          size_t b, size_t e, double* out) const {
    struct Scratch {
        std::vector<uint32_t> cell, count;
        std::vector<double> mapped, sorted, values;
    };
    static thread_local Scratch sc;
    const size_t m = e - b;
    const int C = channels();
    const bool directions = args.dirs != nullptr;
    const KnotVector &a0 = axes()[0], &a1 = axes()[1], &a2 = axes()[2];
    const size_t n1 = size_t(a1.last_span() - a1.degree() + 1), n2 = size_t(a2.last_span() - a2.degree() + 1);
    const size_t cells = size_t(a0.last_span() - a0.degree() + 1) * n1 * n2;
    sc.cell.resize(m);
    const SpanNumber span0{a0}, span1{a1}, span2{a2};
    // Points that come in runs of a (u, v) cell already (an image of a surface, a grid), judged on
    // the first ones, are evaluated as they are.
    const double* uv = directions ? args.uv : args.params;
    const size_t uv_stride = directions ? 2 : 4;
    const size_t probe = std::min<size_t>(m, 512);
    size_t changes = 0;
    for (size_t i = 1; i < probe; ++i) {
        const double *x = uv + (b + i) * uv_stride, *y = x - uv_stride;
        changes += span0(x[0]) != span0(y[0]) || span1(x[1]) != span1(y[1]);
    }
    if (changes * 16 < probe) {
        kernel(args, b, e, out);
        return;
    }
    // Parameters (u, v, alpha, beta) of every point, in the caller's order.
    const double* x = args.params + 4 * b;
    if (directions) {
        sc.mapped.resize(m * 4);
        detail::map_to_params(*args.map, uv + 2 * b, args.dirs + 3 * b, m, sc.mapped.data());
        x = sc.mapped.data();
    }
    sc.count.assign(cells + 1, 0);
    for (size_t i = 0; i < m; ++i) {
        const double* xi = x + 4 * i;
        const uint32_t c = uint32_t((span0(xi[0]) * n1 + span1(xi[1])) * n2 + span2(xi[2]));
        sc.cell[i] = c;
        ++sc.count[c + 1];
    }
    for (size_t c = 1; c <= cells; ++c) sc.count[c] += sc.count[c - 1];
    // Parameters copied into cell order in one sequential pass over them (writes to scattered
    // places cost less than reads from them), rank = each point's place in that order.
    sc.sorted.resize(m * 4), sc.values.resize(m * C);
    uint32_t* const rank = sc.cell.data();  // the cell is no longer needed once ranked
    for (size_t i = 0; i < m; ++i) {
        const uint32_t p = sc.count[sc.cell[i]]++;
        rank[i] = p;
        for (int k = 0; k < 4; ++k) sc.sorted[4 * size_t(p) + k] = x[4 * i + k];
    }
    detail::KernelArgs sorted = args;
    sorted.params = sc.sorted.data(), sorted.uv = nullptr, sorted.dirs = nullptr;
    params_kernel(sorted, 0, m, sc.values.data());
    for (size_t i = 0; i < m; ++i)
        for (int c = 0; c < C; ++c) out[(b + i) * C + c] = sc.values[size_t(rank[i]) * C + c];
}

template <typename Loader>
void TensorSpline::evaluate_with(const Loader& loader, size_t count, double* out, int threads, bool directions,
                                 const HemisphereMap* map) const {
    detail::Kernel kernel = nullptr;
    bool uniform = true;
    if (has_fast_kernel()) {
        for (const auto& a : axes()) uniform = uniform && a.uniform_spans();
        kernel = detail::find_kernel(dims(), axes()[0].degree() + 1, channels(), precision_ == Precision::Float32, directions,
                                     uniform);
    }
    if (kernel && dims() == 4 && bytes() > kCellOrderBytes && count >= kCellChunk) {
        detail::KernelArgs args{&layout_->lanes(), data(), nullptr, nullptr, nullptr, map};
        loader.bind(args);
        const detail::Kernel params_kernel = detail::find_kernel(4, axes()[0].degree() + 1, channels(),
                                                                 precision_ == Precision::Float32, false, uniform);
        parallel_for(count, kCellChunk, threads,
                     [&](size_t b, size_t e) { evaluate_in_cell_order(kernel, params_kernel, args, b, e, out); });
    } else if (kernel) {
        detail::KernelArgs args{&layout_->lanes(), data(), nullptr, nullptr, nullptr, map};
        loader.bind(args);
        parallel_for(count, kChunk, threads, [&](size_t b, size_t e) { kernel(args, b, e, out); });
    } else if (precision_ == Precision::Float32) {
        parallel_for(count, kChunk, threads, [&](size_t b, size_t e) { evaluate_generic(*this, coeffs32_.data(), loader, b, e, out); });
    } else {
        parallel_for(count, kChunk, threads, [&](size_t b, size_t e) { evaluate_generic(*this, coeffs_.data(), loader, b, e, out); });
    }
}

namespace {

struct ParamLoader {
    const double* xs;
    int dims;
    void operator()(size_t i, double* x) const {
        for (int k = 0; k < dims; ++k) x[k] = xs[i * dims + k];
    }
    void bind(detail::KernelArgs& a) const { a.params = xs; }
};

struct DirectionLoader {
    const double* uv;
    const double* dirs;
    const HemisphereMap* map;
    void operator()(size_t i, double* x) const {
        x[0] = uv[2 * i], x[1] = uv[2 * i + 1];
        map->to_disc(dirs[3 * i], dirs[3 * i + 1], dirs[3 * i + 2], x + 2);
    }
    void bind(detail::KernelArgs& a) const { a.uv = uv, a.dirs = dirs; }
};

}  // namespace

void TensorSpline::evaluate(const double* x, double* out) const {
    // One point (the solver's gathering calls this per ray): the kernel chosen at construction,
    // no threads, nothing allocated.
    if (const detail::PointKernel kernel = layout_->point_kernel(precision_ == Precision::Float32)) {
        kernel(layout_->lanes(), data(), x, out);
        return;
    }
    const ParamLoader load{x, dims()};
    if (precision_ == Precision::Float32) evaluate_generic(*this, coeffs32_.data(), load, 0, 1, out);
    else evaluate_generic(*this, coeffs_.data(), load, 0, 1, out);
}

void TensorSpline::evaluate_batch(const double* xs, size_t count, double* out, int threads) const {
    evaluate_with(ParamLoader{xs, dims()}, count, out, threads, false, nullptr);
}

void TensorSpline::evaluate_directions(const double* uv, const double* dirs, size_t count, const HemisphereMap& map,
                                       double* out, int threads) const {
    if (dims() != 4)
        throw std::invalid_argument("evaluate_directions: needs a 4D spline L(u, v, alpha, beta), this one has " +
                                    std::to_string(dims()) + " dimensions");
    evaluate_with(DirectionLoader{uv, dirs, &map}, count, out, threads, true, &map);
}

// out[c] = sum over all coefficients of a[i_0 .. i_{D-1}, c] * prod_k weights[k][i_k], contracting
// the last axis first so that the work is about one pass over the coefficients.
void TensorSpline::contract(const std::vector<std::vector<double>>& weights, double* out) const {
    const int C = channels();
    std::vector<double> cur;
    if (precision_ == Precision::Float32) cur.assign(coeffs32_.begin(), coeffs32_.begin() + num_values());
    else cur = coeffs_;
    for (int k = dims() - 1; k >= 0; --k) {
        const size_t n = size_t(axes()[k].num_coeffs()), outer = cur.size() / (n * C);
        std::vector<double> next(outer * C, 0.0);
        for (size_t o = 0; o < outer; ++o)
            for (size_t i = 0; i < n; ++i)
                for (int c = 0; c < C; ++c) next[o * C + c] += weights[k][i] * cur[(o * n + i) * C + c];
        cur.swap(next);
    }
    for (int c = 0; c < C; ++c) out[c] = cur[c];
}

void TensorSpline::integral(double* out) const {
    std::vector<std::vector<double>> w;
    for (const auto& a : axes())
        w.push_back(a.clamped() || a.is_periodic() ? a.basis_integrals() : a.basis_integrals_over(a.domain_begin(), a.domain_end()));
    contract(w, out);
}

void TensorSpline::integral_over(const double* lo, const double* hi, double* out) const {
    std::vector<std::vector<double>> w;
    for (int k = 0; k < dims(); ++k) w.push_back(axes()[k].basis_integrals_over(lo[k], hi[k]));
    contract(w, out);
}

}  // namespace bsgi
