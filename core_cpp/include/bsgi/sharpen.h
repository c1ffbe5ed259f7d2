// Sharpening Schoenberg's approximation (12) from its own samples.
//
// A spline whose coefficients are the samples f(t*_i) at the knot averages reproduces linear f
// only: under a peak of light it is low by h^2 |f''| / 8 (degree 2, uniform knots), which over
// the bounces of a closed room adds up to about 1% with 16 coefficients. The quadratic p that
// interpolates a sample and its two neighbours gives f'' there; taking p's dual functional (its
// blossom at the coefficient's d inner knots) instead of p(t*_i),
//     a_i = f(t*_i) + f[t*_{i-1}, t*_i, t*_{i+1}] * beta_i,
//     beta_i = -sum_k (t_{i+k} - t*_i)^2 / (d (d - 1)),  k = 1..d,
// reproduces quadratics (O(h^3) where f is smooth) from the same samples: no new rays.
// Across a shadow edge or a contact line the correction alone would ring (7% of the jump above
// and below it). So the coefficient may leave the range of its three samples only by as much
// as the curvature it shares with both neighbours (minmod of the three second differences:
// all of the correction on a quadratic, none across an edge, where the curvature changes sign),
// or, at a peak or a trough of the samples, by as much as the sample stands out there (a peak
// gets its lift; minmod alone left the peak of a light on a floor as low as Schoenberg's).
// Every bound is continuous in the samples, so rounding (a scene scaled by 10^4) changes the
// result by rounding only.
#pragma once
#include <cstdint>
#include <vector>

#include "bsgi/tensor_spline.h"

namespace bsgi {

// In place along `axis` of a Float64 spline whose coefficients are samples of f at `nodes` along
// that axis (one per coefficient; empty: the axis's Schoenberg nodes). Degrees 0 and 1 are left
// as they are (their Schoenberg fit already reproduces what a quadratic correction would), and so
// are open axes of fewer than 6 coefficients (too few samples clear of the ends). A
// coefficient whose three samples are all >= 0 stays >= 0, so a non-negative radiance keeps
// non-negative coefficients. `keep`, where given (one entry per spatial node: the first two axes,
// u slowest), marks the coefficients left as their samples (a local mean already holds what the
// correction would add back, and its neighbours' corrections would read it as a point value).
// Throws std::invalid_argument for a bad axis or node count.
void sharpen_samples(TensorSpline& spline, int axis, const std::vector<double>& nodes = {},
                     const std::vector<uint8_t>& keep = {});

}  // namespace bsgi
