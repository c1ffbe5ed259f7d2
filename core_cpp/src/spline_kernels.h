// Evaluation kernels of tensor_spline.cpp specialised at compile time (internal header).
#pragma once
#include <cstddef>

#include "bsgi/hemisphere_map.h"

namespace bsgi::detail {

// What a kernel needs of one open (non-periodic) axis, read from its KnotVector.
struct AxisData {
    const double* knots;      // t_0 ...
    const double* poly;       // KnotVector::span_polynomial(degree)
    const double* inv_width;  // KnotVector::span_inverse_width, indexed by span - degree
    double lo, hi;            // domain
    double inv_h;             // 1 / span width when the spans are uniform, else 0
    int degree, last_span;
    size_t stride;            // in values
};

// Inputs of a batch: either parameters (count x dims), or uv (count x 2) and local directions
// (count x 3) mapped by `map` to (alpha, beta).
struct KernelArgs {
    const AxisData* axes;
    const void* coeffs;  // double or float
    const double* params;
    const double* uv;
    const double* dirs;
    const HemisphereMap* map;
};

using Kernel = void (*)(const KernelArgs&, size_t begin, size_t end, double* out);

// The specialised kernel for this shape, or nullptr: every axis has `order` = degree + 1, and
// with `uniform` every axis has uniform spans (AxisData::inv_h > 0).
Kernel find_kernel(int dims, int order, int channels, bool float32, bool directions, bool uniform);

// (u, v, alpha, beta) rows (n x 4) of n points given by uv (n x 2) and local directions (n x 3),
// through the inverse hemisphere map.
void map_to_params(const HemisphereMap& map, const double* uv, const double* dirs, size_t n, double* params);

// The instruction set of the kernels find_kernel returns: "x86-64-v4", "x86-64-v3" or "baseline".
const char* kernel_isa();

// 256-bit (4 x double) multiply-adds per second of this thread's CPU time: the arithmetic peak
// the benchmark compares the kernels with.
double measure_fma_rate();

}  // namespace bsgi::detail
