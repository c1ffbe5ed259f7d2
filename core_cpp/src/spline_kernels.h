// Evaluation kernels of tensor_spline.cpp specialised at compile time (internal header).
#pragma once
#include <cstddef>

#include "bsgi/hemisphere_map.h"
#include "bsgi/tensor_spline.h"

namespace bsgi::detail {

// Inputs of a batch: either parameters (count x dims), or uv (count x 2) and local directions
// (count x 3) mapped by `map` to (alpha, beta).
struct KernelArgs {
    const SplineLanes* lanes;
    const void* coeffs;  // double or float
    const double* params;
    const double* uv;
    const double* dirs;
    const HemisphereMap* map;
};

// The specialised kernel for this shape, or nullptr: every axis has `order` = degree + 1, and
// with `uniform` every axis has uniform spans (SplineLanes::inv_h > 0).
Kernel find_kernel(int dims, int order, int channels, bool float32, bool directions, bool uniform);
// The same for one point given by its parameters (the same arithmetic as the batch's, without
// its set-up).
PointKernel find_point_kernel(int dims, int order, int channels, bool float32, bool uniform);

// (u, v, alpha, beta) rows (n x 4) of n points given by uv (n x 2) and local directions (n x 3),
// through the inverse hemisphere map.
void map_to_params(const HemisphereMap& map, const double* uv, const double* dirs, size_t n, double* params);

// The instruction set of the kernels find_kernel returns: "x86-64-v4", "x86-64-v3" or "baseline".
const char* kernel_isa();

// 256-bit (4 x double) multiply-adds per second of this thread's CPU time: the arithmetic peak
// the benchmark compares the kernels with.
double measure_fma_rate();

}  // namespace bsgi::detail
