// The gathering solver of paper section 4.2 (Algorithm 1), for diffuse, glossy and transmitting
// surfaces.
#pragma once
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bsgi/progress.h"
#include "bsgi/radiance.h"
#include "bsgi/scene.h"

namespace bsgi {

struct SurfaceSides;

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
    // surface's brightest probe (a shadow edge asks for spatial_coeffs). The final gather's
    // receivers are planned again once the bounces are done, from the converged coarse spline on
    // the same grid: the light a face turned from the lamps gets from its neighbours, which the
    // direct light's probe cannot see; a glossy surface's from its coarse spline along each
    // angular node (the reflections' detail, which the irradiance probe cannot see). A decomposed
    // surface's parts then keep spatial_coeffs. 0: size alone.
    double detail_tolerance = 0;
    // The most a surface's light's detail may ask for, as a density: spans no shorter than
    // 1/detail_density_max of the longest receiver's (its spatial_coeffs - spatial_degree spans;
    // the final gather halves both), and never more than spatial_coeffs. A shadow edge asks every
    // surface it crosses for spatial_coeffs, whatever its size: a book's 7 cm face then got the
    // 12 coefficients a 12 m floor gets, and the faces of the 1,000-object interior under 0.4 m
    // (23% of its area) 93% of its final gather's nodes. An edge's squared error over a surface
    // grows with its length times the blur (the span), so spans as fine on a small face as on a
    // large one buy it little of what is seen (bench/bench_detail_density.py: against Mitsuba 3,
    // no loss the reference can tell at 16).
    double detail_density_max = 16;
    // Knots clustered where the direct light has detail (shadow edges, contact lines) instead
    // of uniform: costs a probe of the direct light on a (2n+1)^2 grid per surface.
    bool adaptive_knots = false;
    // The share of the adaptive knots' density that follows the detail; the rest is uniform, so
    // no span is wider than 1 / (1 - share) uniform ones. Half at final: the final gather's spans
    // stay within the coarse ones where only the indirect light has detail (three quarters left
    // the Cornell box's short box face beside the other's contact line 7.3% off at final
    // instead of 2.3%); a quarter at preview, whose fewer knots the indirect light needs more.
    double knot_detail_share = 0.5;
    // A node that sees only the unlit inside of a closed mesh (a floor under a block resting on
    // it) gathers instead at the nearest point of its surface that is seen, on the contact line:
    // the hidden 0 no longer drags the spline down across the line, and the light at the line
    // (darkened by the contact, or nearly 0 in a crevice) is what the spline takes there.
    bool hidden_nodes_to_contact = true;
    // Knots on the lines where the direct light is not smooth, found from the polygonal emitters'
    // and occluders' geometry (discontinuities.h: EV and VE events, contact lines) where they
    // are parameter lines of a planar receiver, with the multiplicity of their order; the other
    // knots spread between them (by the probe's density with adaptive_knots). On in the final
    // and reference presets.
    bool discontinuity_knots = false;
    // Knots graded across the outlines of occluders' faces parallel to a planar receiver a little
    // off it (discontinuities.h: near contacts, a painting hung off a wall), where its light falls
    // within a few gap heights; alone where discontinuity_knots is off. On in the preview, final
    // and reference presets.
    bool near_contact_knots = false;
    // Diffuse NURBS surfaces that other surfaces pass through are split along those lines into
    // pieces (split_piece.h), each with its own spline, so the light's jump there is not smoothed
    // (paper section 5.1). Done by bsgi.solve in Python (bsgi/split.py), which answers for the
    // scene it was given; the core solves whatever scene it gets. On in every preset.
    bool split_crossings = true;
    // The coarse receivers' light from lights at infinity (a sun: Blender's, a world map's) at a
    // node as its mean weighed by the node's basis function B_i(u) B_k(v) where one of the
    // light's shadow edges crosses its support (the light at 4 x 4 points over it differs by
    // more than Gatherer::kEdgeContrast of the brightest), not sharpened, nor are the samples
    // beside it; the support's points no viewer sees (under a block) left out. Such means keep
    // the light's integral over the parts seen (sum c_i int B_i = int f). A sun's edges
    // are sharper than any span: sampled at points, a patch of sun keeps or loses light as the
    // nodes fall about its edges, and the final gather carries that to the room it lights (a
    // sunlit room's walls 6-13% dark at preview). Only where a final gather reads them: the
    // finals, which are seen, keep point samples (as means over cells they blurred an open
    // box's sun shadows, 6.5% -> 8.1% at preview). On in every preset.
    bool distant_support_means = false;
    // Each gathered spline's samples at its spatial Schoenberg nodes become the limited quadratic
    // correction of Schoenberg's fit (sharpen.h): under a peak of light Schoenberg's spline is low
    // by h^2 |f''| / 8, which the bounces add up; sharpened, quadratics are reproduced where the
    // light is smooth, from the same rays. Off: the samples are the coefficients (12), as in the
    // paper.
    bool sharpen_fit = true;

    // Angular representation of glossy surfaces: knots (24) on [-R, R] in alpha and beta,
    // R = sqrt(1 - sin delta) so directions reach theta = pi/2 - delta. The count per direction
    // follows the BSDF's lobe: angular_resolution spans across a lobe width, clamped to
    // [angular_coeffs_min, angular_coeffs_max].
    int angular_degree = 2;
    double angular_delta = 0.05;
    double angular_resolution = 3.0;
    int angular_coeffs_min = 6;
    int angular_coeffs_max = 24;
    // A wide lobe (0.5 rad and wider) gets at least the angular coefficients whose fit of its
    // directional albedo over the disc stays within this fraction of its largest value (its
    // light's change with the view, which its width does not say); 0: off.
    double angular_albedo_tolerance = 0.01;

    // Surface integral (8)/(35) over emitters: B-spline quadrature (11) with emitter_coeffs
    // coefficients per direction on each cell of the emitter's parameter domain; a cell wider
    // than emitter_cell_ratio times its distance from the receiver (or, for glossy receivers,
    // than a fraction of the lobe width) is split in four, at most emitter_max_depth times.
    int emitter_coeffs = 3;
    int emitter_degree = 2;
    double emitter_cell_ratio = 1.0;
    int emitter_max_depth = 16;
    // A cell whose nodes the receiver sees partly shadowed is split in four while it is, down
    // to this depth (0: never): the visible part of an emitter in a penumbra is resolved there.
    int emitter_shadow_depth = 0;

    // Hemispherical integral (26)-(32): cosine-weighted nodes in (cos^2 theta, phi); glossy
    // receivers add bsdf_samples BSDF-sampled directions (a Fibonacci lattice) per outgoing direction,
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
    // Bounces after the first late_bounces_after gather with half the hemisphere nodes (and BSDF
    // samples) along each axis, a quarter of the rays: a late bounce's increment is smooth and a
    // small share of the light, so its coarser integration costs little (0: every bounce full).
    int late_bounces_after = 0;
    // Generalized form factors (36)-(37) for Lambertian receivers: their gathering rays are cast
    // once and kept as rows of the transport operator; later bounces are sparse products. Not
    // used in scenes with albedo textures (a row's scalar weights cannot carry a texel's colour).
    bool form_factors = false;
    double tolerance = 1e-3;
    bool extrapolate = true;
    // A receiver whose own light has settled stops gathering (0: every receiver gathers every
    // bounce): once, in every channel with light, the decay rho2 of its pairs of increments has
    // been below 1 for three bounces, steady within 5% and within 5% of the whole scene's, its
    // tail's uncertainty is below settle_factor times the tolerance, and its pair of increments
    // is, coefficient by coefficient, rho2 times the pair two bounces before (to the same bound
    // over the tail), each of its further increments is rho2 times its increment two bounces
    // before. Others go on gathering from it. Interiors settle receiver by receiver.
    double settle_factor = 0;

    // Final gather (Algorithm 1's last phase): every surface gathers once more, at
    // final_spatial_factor times the spatial coefficients and final_integration_factor times
    // the integration nodes, from the emitters and the cumulative radiance of the others.
    bool final_gather = false;
    int final_spatial_factor = 2;
    int final_integration_factor = 2;
    // Final gathers in all, 1 to 4: the second corrects the first by what reading the indirect
    // light from its finer splines instead of the coarse ones changes (a shadow or contact line
    // too narrow for the coarse grid no longer lights what faces it), gathered with half the
    // integration nodes per axis (a quarter of a final gather's rays); each further one does so
    // again from the latest finals (F_k+1 = F_1 + G(F_k - C)), carrying the finer light a bounce
    // further into a cavity lit through a narrow opening.
    int final_passes = 1;
    // Coarse bounces that carry the coarse light's error before the second final gather (a
    // two-grid correction): the first final gather less the coarse light, F_1 - C, is C's
    // residual at the fine level; its error (I - K)^-1 (F_1 - C) is that residual plus its
    // bounces, taken here on the coarse receivers (K_c). The regather then reads F_1 + E instead
    // of F_1, E the bounces' sum: what the coarse iteration let through a blurred opening into a
    // cavity leaves it at once, not a bounce a pass. 0: none (the regathers alone); at most
    // max_bounces are taken.
    int final_correction_bounces = 0;

    // Cycles shades both sides of an opaque surface with the same BSDF: the back side reflects
    // light arriving from below, mirrored. Sides no light reaches get no spline (sides.h). Off:
    // opaque surfaces reflect on their front side only.
    bool two_sided = true;

    // Per-surface error estimate (SurfaceReport::estimated_error): after the last phase, the
    // gathered radiance at error_checks points per surface that no node sits on (and, on glossy
    // surfaces, along directions between the angular nodes) against the spline there; at half
    // of them the error of the others' splines the last gather read (their final less their
    // coarse splines, gathered, scaled by the order each surface's own checks show), at a
    // quarter the gather at doubled integration nodes, against which the spline's own error is
    // taken; plus the bounces' tail. Off: the reports' estimated_error is NaN.
    bool estimate_error = true;
    // More checks, a steadier estimate: a surface's error sits in thin bands (contact lines,
    // shadow edges) that few checks hit or miss by chance (the final preset takes 128).
    int error_checks = 48;
    // Where the checks' low-discrepancy sequence starts: another seed, another set of checks
    // (the estimate's own sampling noise shows across seeds).
    int error_checks_seed = 0;

    // Refinement driven by the error estimate, done by bsgi.solve (Python, around this solve, so
    // that it also runs on a Ray cluster): while a surface's estimated error is over
    // refine_to_error (relative; 0: off) and mostly its own spline's fit (error_parts), it gets
    // refine_factor times its spatial coefficients
    // per direction and the scene is solved again, at most refine_passes times, while the memory
    // estimate fits memory_budget_mb and (if > 0) the passes' time stays within refine_seconds
    // and their rays within refine_cost times the first solve's. Where a pass would overrun a
    // budget, the surfaces with the highest estimates are refined, as many as it allows.
    double refine_to_error = 0;
    int refine_passes = 2;
    double refine_factor = 1.5;
    double refine_seconds = 0;
    double refine_cost = 0;

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
    double seconds_estimate = 0;  // of the per-surface error estimate (not in the phases' times)
    size_t estimate_rays = 0;     // rays of the error estimate (not in `rays`)
    // Of `rays`, the final gathers' at the finals' nodes (not the coarse correction's bounces):
    // what a surface's integration nodes multiply (bsgi.refine's prediction of a pass).
    size_t final_rays = 0;
    size_t settled_nodes = 0;     // nodes of settled receivers, summed over the bounces they did not gather
};

struct Solution {
    // Outgoing radiance (emission + reflected) per scene surface; empty for pure emitters.
    std::vector<std::optional<SurfaceRadiance>> radiance;
    std::vector<SurfaceReport> reports;
    SolveStats stats;
};

// The rays' scene of a scene: what the solve casts rays at (and the sides probe, sides.h).
class RayCaster;
RayCaster ray_caster_of(const Scene& scene);

// Bytes the solve will allocate for the given scene and settings. `sides`: the sides already
// probed (probe_sides, SolveSteps::sides) for a solve that takes them; null: probed here, and the
// probe's own peak counted (a solve that probes holds it first).
size_t estimate_solve_bytes(const Scene& scene, const SolverSettings& settings, const std::vector<SurfaceSides>* sides = nullptr);

// Algorithm 1 in its phases, each a gather that every receiving surface does on its own from
// the previous step's coefficients of all receivers: the direct light, each indirect bounce
// (from the last increment L) and the final gather (from the cumulative Le). A phase can thus
// be split over groups of receivers gathered elsewhere (other processes, other machines), each
// holding SolveSteps of the same scene and settings, which plan the same receivers with the same
// knots. Coefficients travel flat: receiver after receiver, each one's spline sides in order.
class SolveSteps {
public:
    // The error estimate's two passes (SolverSettings::estimate_error) are phases too: its checks
    // (the spline against the gathers), and with a final gather the error of the input read.
    enum class Phase { Direct = 0, Bounce = 1, Final = 2, Regather = 3, LateBounce = 4, EstimateChecks = 5, EstimateInput = 6 };
    // Gathers a phase for every receiver (in groups wherever it likes): the coefficients of all
    // receivers of the phase, given `input` (empty, L or Le) and the nodes each receiver gathers
    // (the work; 0 for a settled receiver, which does not gather: its coefficients in the result
    // are not read); adds the rays cast to `rays`.
    using Runner = std::function<std::vector<double>(Phase, const std::vector<double>& input,
                                                     const std::vector<size_t>& nodes, size_t& rays)>;

    // Validates, plans the receivers and places their knots (the final gather's when first
    // needed). Throws as solve() does. The scene must outlive the steps. `sides`: the sides
    // another SolveSteps of the scene and settings probed (sides()), not probed again.
    SolveSteps(const Scene& scene, const SolverSettings& settings, Progress& progress,
               const std::vector<SurfaceSides>* sides = nullptr);
    ~SolveSteps();
    SolveSteps(const SolveSteps&) = delete;
    SolveSteps& operator=(const SolveSteps&) = delete;

    // Which sides of each surface are solved (the probe of sides.h).
    const std::vector<SurfaceSides>& sides() const;
    // Spatial nodes of each receiver of a phase.
    std::vector<size_t> nodes(Phase phase, Progress& progress);
    // The gather of a phase for receivers [begin, end), given the previous step's coefficients
    // of all receivers (none for the direct light; L for a bounce, late or not; Le for the final
    // gather; to regather, the finals' Le of the final gather followed by the coarse Le it read):
    // their new coefficients. `settled`: receivers of a bounce that do not gather (their
    // coefficients are returned as they were). Advances `progress` by nodes; throws Cancelled if
    // it is cancelled. The error estimate's passes read the estimated splines' Le (the finals',
    // or the coarse ones' without a final gather), then with a final gather the coarse Le; the
    // input pass then also each scene surface's input scale, the checks pass's result for all
    // receivers and its length; they give per receiver its checks' record (the checks pass) or each check's
    // input error (the input pass), and count their rays as the estimate's. With
    // coeffs_from_size and a detail tolerance the finals are planned from the coarse Le that the
    // first of these phases reads (and nodes() of a final phase or an estimate pass, on the
    // steps that run the solve, needs its bounces done).
    // `input` is read where it lies (a runner's buffer, not copied). `unpacked`: these steps were
    // given this phase's very input by an earlier call (a worker's earlier group of the phase),
    // so the splines already hold it and it is not unpacked again (the estimate's input pass still
    // reads its scales and records from it).
    struct Input {
        const double* data = nullptr;
        size_t size = 0;
    };
    std::vector<double> gather(Phase phase, size_t begin, size_t end, Input input, Progress& progress, size_t& rays,
                               const std::vector<size_t>& settled = {}, bool unpacked = false);
    // The whole solve, each phase's gather run by `run` (here, on all threads, if empty), the
    // bounces' bookkeeping (the sums, when to stop, the extrapolated tail) here. Once: the
    // solution takes the splines.
    Solution solve(Progress& progress, const Runner& run = {});

private:
    // gather() with `input` null where the splines it would unpack already hold it (the local
    // solve): no packed copy of the input beside them.
    std::vector<double> gather_from(Phase phase, size_t begin, size_t end, const Input* input, Progress& progress,
                                    size_t& rays, const std::vector<size_t>& settled, bool unpacked = false);
    struct State;
    std::unique_ptr<State> state_;
};

// Throws std::invalid_argument on unusable input (naming the surface), Cancelled if progress is
// cancelled, std::runtime_error when the memory estimate exceeds the budget (naming the surface
// that needs the most). `sides`: as SolveSteps takes them (a refinement's passes probe once).
Solution solve(const Scene& scene, const SolverSettings& settings, Progress& progress,
               const std::vector<SurfaceSides>* sides = nullptr);

}  // namespace bsgi
