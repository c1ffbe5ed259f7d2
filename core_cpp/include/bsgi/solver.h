// The gathering solver of paper section 4.2 (Algorithm 1), for diffuse, glossy and transmitting
// surfaces.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "bsgi/progress.h"
#include "bsgi/radiance.h"
#include "bsgi/scene.h"

namespace bsgi {

struct SolverSettings {
    // Spatial representation: knots (19) on [eps, 1 - eps]. A surface as large as the scene gets
    // spatial_coeffs per direction; with coeffs_from_size smaller ones get fewer, in proportion
    // to their length (mean arc length of the parameter lines, against the longest receiver's),
    // but at least spatial_coeffs_min and a span per 0.5 rad of their normal's turning.
    int spatial_coeffs = 16;
    int spatial_degree = 2;
    double epsilon = 1e-3;
    bool coeffs_from_size = false;
    int spatial_coeffs_min = 4;
    // With coeffs_from_size, a surface whose direct light has detail gets more again: the light
    // is probed on a (2 spatial_coeffs_min + 1)^2 grid and the knot spacing is chosen so that a
    // quadratic's interpolation error, h^2 |f''| / 8, stays under detail_tolerance times the
    // surface's brightest probe (a shadow edge asks for spatial_coeffs). Glossy surfaces, whose
    // reflections' detail the probe does not see, then keep spatial_coeffs. 0: size alone.
    double detail_tolerance = 0;
    // Knots clustered where the direct light has detail (shadow edges, contact lines) instead
    // of uniform: costs a probe of the direct light on a (2n+1)^2 grid per surface.
    bool adaptive_knots = false;

    // Angular representation of glossy surfaces: knots (24) on [-R, R] in alpha and beta,
    // R = sqrt(1 - sin delta) so directions reach theta = pi/2 - delta. The count per direction
    // follows the BSDF's lobe: angular_resolution spans across a lobe width, clamped to
    // [angular_coeffs_min, angular_coeffs_max].
    int angular_degree = 2;
    double angular_delta = 0.05;
    double angular_resolution = 3.0;
    int angular_coeffs_min = 6;
    int angular_coeffs_max = 24;

    // Surface integral (8)/(35) over emitters: B-spline quadrature (11) with emitter_coeffs
    // coefficients per direction on each cell of the emitter's parameter domain; a cell wider
    // than emitter_cell_ratio times its distance from the receiver (or, for glossy receivers,
    // than a fraction of the lobe width) is split in four, at most emitter_max_depth times.
    int emitter_coeffs = 3;
    int emitter_degree = 2;
    double emitter_cell_ratio = 1.0;
    int emitter_max_depth = 16;

    // Hemispherical integral (26)-(32): cosine-weighted nodes in (cos^2 theta, phi); glossy
    // receivers add bsdf_samples stratified BSDF-sampled directions per outgoing direction,
    // combined with the cosine nodes by multiple importance sampling.
    int hemisphere_nodes_theta = 12;
    int hemisphere_nodes_phi = 24;
    int bsdf_samples = 16;
    // A world map's pixels brighter than world_bright_factor times the sky's mean (a sun, its
    // aureole) are light reached by shadow rays, in at most world_bright_samples directions
    // (EnvironmentMap::split); the rest of the map is gathered by the hemispherical integral.
    double world_bright_factor = 20;
    int world_bright_samples = 64;

    // Indirect phase: stop after max_bounces, or when the radiance still missing (estimated
    // from the geometric decay of the increments) is below tolerance times the radiance. With
    // extrapolate, that missing geometric tail is added instead of bounced, which makes albedos
    // near 1 converge in a few bounces.
    int max_bounces = 64;
    // Generalized form factors (36)-(37) for Lambertian receivers: their gathering rays are cast
    // once and kept as rows of the transport operator; later bounces are sparse products. Not
    // used in scenes with albedo textures (a row's scalar weights cannot carry a texel's colour).
    bool form_factors = false;
    double tolerance = 1e-3;
    bool extrapolate = true;

    // Final gather (Algorithm 1's last phase): every surface gathers once more, at
    // final_spatial_factor times the spatial coefficients and final_integration_factor times
    // the integration nodes, from the emitters and the cumulative radiance of the others.
    bool final_gather = false;
    int final_spatial_factor = 2;
    int final_integration_factor = 2;

    // Cycles shades both sides of an opaque surface with the same BSDF: the back side reflects
    // light arriving from below, mirrored. Sides no light reaches get no spline (sides.h). Off:
    // opaque surfaces reflect on their front side only.
    bool two_sided = true;

    int threads = 0;  // 0: all hardware threads
    double memory_budget_mb = 4096;

    // "draft", "preview" or "final": the presets whose measured cost and error the README lists.
    static SolverSettings preset(const std::string& name);
};

struct SolveStats {
    double seconds_direct = 0, seconds_indirect = 0, seconds_final = 0;
    int bounces = 0;
    double last_increment = 0;   // largest increment of the last bounce, relative to the radiance
    double estimated_error = 0;  // relative radiance still missing (or its uncertainty, if extrapolated)
    bool extrapolated = false;
    size_t coefficients = 0;     // RGB coefficients of all output splines
    size_t rays = 0;
    size_t bytes = 0;            // the memory estimate the solve was admitted with
    size_t transport_terms = 0;  // entries of the form-factor operator, if used
};

struct Solution {
    // Outgoing radiance (emission + reflected) per scene surface; empty for pure emitters.
    std::vector<std::optional<SurfaceRadiance>> radiance;
    std::vector<SurfaceReport> reports;
    SolveStats stats;
};

// Bytes the solve will allocate for the given scene and settings.
size_t estimate_solve_bytes(const Scene& scene, const SolverSettings& settings);

// Throws std::invalid_argument on unusable input (naming the surface), Cancelled if progress is
// cancelled, std::runtime_error when the memory estimate exceeds the budget (naming the surface
// that needs the most).
Solution solve(const Scene& scene, const SolverSettings& settings, Progress& progress);

}  // namespace bsgi
