// The gathering solver of paper section 4.2 (Algorithm 1).
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "bsgi/progress.h"
#include "bsgi/scene.h"
#include "bsgi/tensor_spline.h"

namespace bsgi {

struct SolverSettings {
    // Radiance representation: 2D spline per diffuse surface, knots (19) on [eps, 1 - eps].
    int spatial_coeffs = 16;
    int spatial_degree = 2;
    double epsilon = 1e-3;
    // Knots clustered where the direct light has detail (shadow edges, contact lines) instead
    // of uniform: costs a probe of the direct light on a (2n+1)^2 grid per surface.
    bool adaptive_knots = false;
    // Surface integral (8)/(35) over emitters: B-spline quadrature (11) with emitter_coeffs
    // coefficients per direction on each cell of the emitter's parameter domain; a cell wider
    // than emitter_cell_ratio times its distance from the receiver is split in four, at most
    // emitter_max_depth times.
    int emitter_coeffs = 3;
    int emitter_degree = 2;
    double emitter_cell_ratio = 1.0;
    int emitter_max_depth = 16;
    // Hemispherical integral (26)-(32): nodes in (cos^2 theta, phi), cosine-weighted.
    int hemisphere_nodes_theta = 12;
    int hemisphere_nodes_phi = 24;
    // Indirect phase: stop after max_bounces, or when the radiance still missing (estimated
    // from the geometric decay of the increments) is below tolerance times the radiance. With
    // extrapolate, that missing geometric tail is added instead of bounced, which makes albedos
    // near 1 converge in a few bounces.
    int max_bounces = 4;
    double tolerance = 1e-3;
    bool extrapolate = true;
    int threads = 0;  // 0: all hardware threads
    double memory_budget_mb = 4096;
};

struct SolveStats {
    double seconds_direct = 0, seconds_indirect = 0;
    int bounces = 0;
    double last_increment = 0;   // largest increment of the last bounce, relative to the radiance
    double estimated_error = 0;  // relative radiance still missing (or its uncertainty, if extrapolated)
    bool extrapolated = false;
    size_t coefficients = 0;
    size_t rays = 0;
};

struct Solution {
    // Outgoing radiance (emission + reflected) per scene surface; empty for pure emitters.
    std::vector<std::optional<TensorSpline>> radiance;
    SolveStats stats;
};

// Bytes the solve will allocate for the given scene and settings.
size_t estimate_solve_bytes(const Scene& scene, const SolverSettings& settings);

// Throws std::invalid_argument on unusable input (naming the surface), Cancelled if progress is
// cancelled, std::runtime_error when the memory estimate exceeds the budget.
Solution solve(const Scene& scene, const SolverSettings& settings, Progress& progress);

}  // namespace bsgi
