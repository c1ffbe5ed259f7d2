#include "bsgi/solver.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>
#include <unordered_map>

#include "bsgi/discontinuities.h"
#include "bsgi/gather.h"
#include "bsgi/memory_budget.h"
#include "bsgi/parallel.h"
#include "bsgi/sharpen.h"
#include "bsgi/sides.h"

namespace bsgi {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The error estimate's checks a receiver at most, and the candidates it chooses each from
// (check_points).
constexpr int kMaxErrorChecks = 4096;
constexpr size_t kCandidatesPerCheck = 16;

void validate(const SolverSettings& s) {
    auto need = [](bool ok, const char* what) {
        if (!ok) throw std::invalid_argument(std::string("solver settings: ") + what);
    };
    need(s.spatial_degree >= 0 && s.spatial_degree <= 5, "spatial_degree must be in 0..5");
    need(s.spatial_coeffs >= s.spatial_degree + 1, "spatial_coeffs must be at least spatial_degree + 1");
    need(s.spatial_coeffs_min >= s.spatial_degree + 1, "spatial_coeffs_min must be at least spatial_degree + 1");
    need(s.detail_tolerance >= 0, "detail_tolerance must be >= 0");
    need(s.detail_density_max >= 1, "detail_density_max must be >= 1");
    need(s.knot_detail_share >= 0 && s.knot_detail_share <= 1, "knot_detail_share must be in [0, 1]");
    need(s.epsilon >= 0 && s.epsilon < 0.5, "epsilon must be in [0, 0.5)");
    need(s.angular_degree >= 0 && s.angular_degree <= 5, "angular_degree must be in 0..5");
    need(s.angular_coeffs_min >= s.angular_degree + 1 && s.angular_coeffs_max >= s.angular_coeffs_min,
         "angular_coeffs_min must be at least angular_degree + 1 and at most angular_coeffs_max");
    need(s.angular_delta >= 0 && s.angular_delta < 1.5, "angular_delta must be in [0, 1.5)");
    need(s.angular_resolution > 0, "angular_resolution must be > 0");
    need(s.angular_albedo_tolerance >= 0 && std::isfinite(s.angular_albedo_tolerance), "angular_albedo_tolerance must be >= 0 (0: off)");
    need(s.emitter_coeffs >= s.emitter_degree + 1, "emitter_coeffs must be at least emitter_degree + 1");
    // Upper bounds on the work per integral: far beyond any preset, short of a solve that never
    // ends (emitter_coeffs = 10^6 is 10^12 nodes per emitter cell) or of int overflow.
    need(s.emitter_coeffs <= 64, "emitter_coeffs must be at most 64");
    need(s.spatial_coeffs <= 4096 && s.angular_coeffs_max <= 4096, "spatial_coeffs and angular_coeffs_max must be at most 4096");
    need(s.emitter_degree >= 0 && s.emitter_degree <= 3, "emitter_degree must be in 0..3");
    need(s.emitter_max_depth >= 0 && s.emitter_max_depth <= 20, "emitter_max_depth must be in 0..20");
    need(s.emitter_shadow_depth >= 0 && s.emitter_shadow_depth <= 12, "emitter_shadow_depth must be in 0..12");
    need(s.emitter_cell_ratio > 0, "emitter_cell_ratio must be > 0");
    need(s.hemisphere_nodes_theta >= 1 && s.hemisphere_nodes_phi >= 1, "hemisphere nodes must be >= 1");
    need(s.hemisphere_nodes_theta <= 1024 && s.hemisphere_nodes_phi <= 1024, "hemisphere nodes must be at most 1024");
    need(s.bsdf_samples >= 0 && s.bsdf_samples <= 4096, "bsdf_samples must be in 0..4096");
    need(s.world_bright_factor > 1, "world_bright_factor must be > 1");
    need(s.world_bright_samples >= 1, "world_bright_samples must be >= 1");
    need(s.max_bounces >= 0, "max_bounces must be >= 0");
    need(s.late_bounces_after >= 0, "late_bounces_after must be >= 0 (0: every bounce with all hemisphere nodes)");
    need(s.tolerance >= 0, "tolerance must be >= 0");
    need(s.settle_factor >= 0 && s.settle_factor <= 1,
         "settle_factor must be in [0, 1] (0: every receiver gathers every bounce; above 1 a receiver would settle with "
         "its tail less certain than the tolerance)");
    need(s.final_spatial_factor >= 1 && s.final_integration_factor >= 1, "final gather factors must be >= 1");
    need(s.final_spatial_factor <= 16 && s.final_integration_factor <= 16, "final gather factors must be at most 16");
    need(s.final_passes >= 1 && s.final_passes <= 4, "final_passes must be from 1 to 4");
    need(s.final_correction_bounces >= 0 && s.final_correction_bounces <= 64, "final_correction_bounces must be in 0..64");
    need(s.memory_budget_mb > 0, "memory_budget_mb must be > 0");
    need(s.error_checks >= 1 && s.error_checks <= kMaxErrorChecks, "error_checks must be in 1..4096");
    static_assert(kMaxErrorChecks == 4096, "the message above names the bound");
    need(s.error_checks_seed >= 0 && s.error_checks_seed <= 65535, "error_checks_seed must be in 0..65535");
    need(s.refine_to_error >= 0 && s.refine_passes >= 0 && s.refine_seconds >= 0 && s.refine_cost >= 0,
         "refine_to_error, refine_passes, refine_seconds and refine_cost must be >= 0");
    need(s.refine_factor > 1 && s.refine_factor <= 4, "refine_factor must be in (1, 4]");
}

// What the solver decided for one receiving surface, before anything is allocated.
struct Plan {
    int surface = -1;
    Representation kind = Representation::Diffuse;
    std::shared_ptr<const Bsdf> bsdf;
    int nu = 0, nv = 0, na = 1, sides = 1;  // spline slots: 2 if the back side is solved
    double map_delta = 0;  // the hemisphere map's: SolverSettings::angular_delta, a bumped surface's its cap's
    std::array<bool, 2> live{true, false};  // the sides solved (sides.h)
    std::string reason;
    int partner_of = -1;  // the glossy part S of (38): index of the plan of its diffuse part D
    size_t coefficients() const { return size_t(nu) * nv * na * na * (live[0] + live[1]); }
};

// A surface's shape along u and v for coeffs_from_size: the mean arc length of its parameter
// lines, and the largest turning of its normal along one (radians), on a 9 x 9 grid.
struct Shape {
    std::array<double, 2> length{0, 0}, turning{0, 0};
};

Shape shape_of(const Surface& surface) {
    constexpr int m = 9;
    std::vector<SurfacePoint> g;
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) g.push_back(surface.evaluate((i + 0.5) / m, (j + 0.5) / m));
    Shape shape;
    for (int along = 0; along < 2; ++along)
        for (int j = 0; j < m; ++j) {
            double turning = 0;
            for (int i = 0; i < m; ++i) {
                const SurfacePoint& a = along == 0 ? g[size_t(i) * m + j] : g[size_t(j) * m + i];
                shape.length[along] += length(along == 0 ? a.dpdu : a.dpdv) / (m * m);
                if (i + 1 == m) continue;
                const SurfacePoint& b = along == 0 ? g[size_t(i + 1) * m + j] : g[size_t(j) * m + i + 1];
                turning += std::acos(std::clamp(dot(a.frame.z, b.frame.z), -1.0, 1.0));
            }
            // The ends of the grid lie half a cell inside: the turning over the whole line.
            shape.turning[along] = std::max(shape.turning[along], turning * m / (m - 1));
        }
    return shape;
}

// The longest receiver, as shape_of measures it: the one that gets spatial_coeffs.
double scene_extent(const Scene& scene) {
    double extent = 0;
    for (const auto& s : scene.surfaces())
        if (s.receiver) {
            const Shape shape = shape_of(*s.surface);
            extent = std::max({extent, shape.length[0], shape.length[1]});
        }
    return extent;
}

// A BSDF's lobe width in the angular disc: near the pole r ~ theta / sqrt 2.
double lobe_in_disc(const Bsdf& b) { return std::max(b.lobe_width(), 1e-3) / std::sqrt(2.0); }

// The view-dependence of a wide lobe's light asks for angular knots its width does not: under a
// uniform sky a roughness-1 metal with Cycles' shadowing reflects 0.31 of it along the normal and
// 0.79 near grazing, and 7 x 7 angular coefficients were 7% low at 45 degrees, 10% high at 75.
// The count: the fewest from `start` whose fit of the BSDF's directional albedo over the disc
// (Schoenberg's, sharpened as the solve sharpens it) stays within `tolerance` of `scale`, per
// channel. The albedo by the gather's cosine rule (directional_albedo) at 33 cosines, read
// linearly between them. (Until 7 December a midpoint rule in cos^2 theta of 32 x 64 nodes,
// which undersamples the horizon: a roughness-1 metal's albedo at grazing 5% low.)
constexpr double kWideLobe = 0.5;  // radians: narrower lobes' widths ask for more knots than this would
struct AlbedoCurve {
    static constexpr int kCosines = 33;  // at mu = (k / (n - 1))^2
    std::vector<Vec3> values;
    double largest = 0;
    Vec3 at(const HemisphereMap& map, double alpha, double beta) const {
        double d[3];
        map.to_direction(alpha, beta, d);
        const double x = std::sqrt(std::clamp(d[2], 0.0, 1.0)) * (kCosines - 1);
        const int k = std::min(int(x), kCosines - 2);
        return values[size_t(k)] + (values[size_t(k) + 1] - values[size_t(k)]) * (x - k);
    }
};

AlbedoCurve albedo_curve(const Bsdf& b) {
    AlbedoCurve curve;
    curve.values.resize(AlbedoCurve::kCosines);
    for (int k = 0; k < AlbedoCurve::kCosines; ++k) {
        const double x = double(k) / (AlbedoCurve::kCosines - 1), mu = std::max(x * x, 1e-3);
        curve.values[size_t(k)] = directional_albedo(b, {std::sqrt(1 - mu * mu), 0, mu});
        curve.largest = std::max(curve.largest, max_component(curve.values[size_t(k)]));
    }
    return curve;
}

int view_dependence_count(const AlbedoCurve& curve, double lobe, const HemisphereMap& map, int degree, int start, int most,
                          double tolerance, double scale) {
    if (!(scale > 0)) return start;
    const double R = map.radius();
    for (int n = start; n < most; ++n) {
        const KnotVector knots = KnotVector::clamped_uniform(n, degree, -R, R);
        const std::vector<double> nodes = knots.schoenberg_nodes();
        TensorSpline fit({knots, knots}, 3);
        std::vector<double>& c = fit.coeffs();
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                const Vec3 a = curve.at(map, nodes[size_t(i)], nodes[size_t(j)]);
                double* out = &c[3 * (size_t(i) * n + j)];
                out[0] = a.x, out[1] = a.y, out[2] = a.z;
            }
        if ((n - degree) * lobe >= 2 * 2 * R)  // as lobe_resolved: the solve sharpens it then
            for (int axis = 0; axis < 2; ++axis) sharpen_samples(fit, axis);
        double worst = 0;
        constexpr int kChecks = 25;
        for (int i = 0; i < kChecks && worst <= tolerance; ++i)
            for (int j = 0; j < kChecks; ++j) {
                const double x[2] = {R * (2.0 * i / (kChecks - 1) - 1), R * (2.0 * j / (kChecks - 1) - 1)};
                if (x[0] * x[0] + x[1] * x[1] > R * R) continue;
                double got[3];
                fit.evaluate(x, got);
                const Vec3 want = curve.at(map, x[0], x[1]);
                for (int ch = 0; ch < 3; ++ch) worst = std::max(worst, std::abs(got[ch] - want[ch]) / scale);
            }
        if (worst <= tolerance) return n;
    }
    return most;
}

// A lobe with a colour (Fresnel's f0) is a blend T W + (1 - T) B of its lobes at f0 = 1 and 0:
// the count that fits both within the tolerance of W's light fits every colour within it, the
// same count for a texture's blend and for each of its texels' own colour.
int view_dependence_count(const Bsdf& bsdf, double lobe, const SolverSettings& s, int start) {
    const HemisphereMap map = HemisphereMap::for_max_angle(s.angular_delta);
    const auto white = bsdf.with_specular_colour({1, 1, 1}), black = bsdf.with_specular_colour({0, 0, 0});
    const AlbedoCurve own = albedo_curve(white ? *white : bsdf);
    auto count = [&](const AlbedoCurve& curve, int from) {
        return view_dependence_count(curve, lobe, map, s.angular_degree, from, s.angular_coeffs_max,
                                     s.angular_albedo_tolerance, own.largest);
    };
    const int n = count(own, start);
    return black ? count(albedo_curve(*black), n) : n;
}

// The count once per material and angular settings, not per surface and plan: its two albedo
// curves and fits cost about 4 ms for a wide lobe, and a solve makes its plans up to five times
// (400 patches of one roughness-0.8 metal spent 4.6 s there before this cache, 0.18 s with it). Keyed by the BSDF object, which a
// material's surfaces share; an entry whose BSDF is gone no longer matches (its weak pointer).
int material_view_dependence_count(const std::shared_ptr<const Bsdf>& bsdf, double lobe, const SolverSettings& s, int start) {
    using Key = std::tuple<const Bsdf*, double, int, int, int, double>;
    struct Entry {
        std::weak_ptr<const Bsdf> bsdf;
        int count;
    };
    static std::mutex mutex;
    static std::map<Key, Entry> made;
    const Key key{bsdf.get(), s.angular_delta, s.angular_degree, start, s.angular_coeffs_max, s.angular_albedo_tolerance};
    {
        std::lock_guard<std::mutex> lock(mutex);
        const auto it = made.find(key);
        if (it != made.end() && it->second.bsdf.lock() == bsdf) return it->second.count;
    }
    const int count = view_dependence_count(*bsdf, lobe, s, start);
    std::lock_guard<std::mutex> lock(mutex);
    for (auto it = made.begin(); it != made.end();) it = it->second.bsdf.expired() ? made.erase(it) : std::next(it);
    made[key] = Entry{bsdf, count};
    return count;
}

// "Model only what the scene requires": the representation from the material, the knots from
// the BSDF's lobe and the surface's size, unless the surface's options say otherwise.
// `detail`: the coefficients per direction the surface's direct light asks for (0: not probed).
Plan plan_surface(const Scene& scene, int i, const SolverSettings& s, double extent, int spatial_scale,
                  const SurfaceSides& lit, std::array<int, 2> detail) {
    const SceneSurface& ss = scene[i];
    Plan p;
    p.surface = i;
    p.bsdf = ss.material.bsdf ? ss.material.bsdf : std::make_shared<Lambert>(ss.material.albedo);
    const bool lambertian = dynamic_cast<const Lambert*>(p.bsdf.get()) != nullptr;
    std::ostringstream why;
    const bool sum = p.bsdf->glossy_part() && max_component(p.bsdf->diffuse_albedo()) > 0;
    // (38) is for mildly glossy surfaces: the glossy part then needs few spatial knots. Where
    // the lobe reflects as much as the base (a strong coat), the full 4D spline is kept.
    const bool mild = sum && max_component(directional_albedo(*p.bsdf->glossy_part())) <= 0.5 * max_component(p.bsdf->diffuse_albedo());
    const bool textured = bool(ss.material.albedo_texture);
    const bool bumped = bool(ss.material.normal_texture);
    if (bumped) {
        // Its radiance changes with its bumped normal, not with the view (Scene::set_normal_texture
        // has checked it is Lambertian).
        p.kind = Representation::Glossy;
        const Vec3 albedo = textured ? Vec3{1, 1, 1} : static_cast<const Lambert&>(*p.bsdf).albedo();
        p.bsdf = std::make_shared<BumpedLambert>(albedo, ss.material.bump_correction);
        why << "Lambertian material under a normal map " << ss.material.normal_texture->width() << " x "
            << ss.material.normal_texture->height() << ": 4D over its bumped normal";
    } else if (ss.options.representation == Representation::Auto) {
        // An albedo texture colours the diffuse base, which only D of (38) keeps apart.
        p.kind = lambertian ? Representation::Diffuse
                            : (mild || textured ? Representation::Decomposed : Representation::Glossy);
        why << (lambertian ? "Lambertian material: 2D"
                           : p.bsdf->name() + (mild ? " BSDF, a diffuse base under a mild glossy lobe: D(u,v) + S(u,v,alpha,beta) (38)"
                                                    : textured ? " BSDF with a textured diffuse base: D(u,v) + S(u,v,alpha,beta) (38)"
                                                               : " BSDF: view-dependent 4D"));
    } else if (ss.options.representation == Representation::Decomposed && !sum) {
        throw std::invalid_argument("surface '" + ss.surface->name() + "': the decomposition (38) needs a BSDF with a "
                                    "diffuse base and a glossy lobe (e.g. DiffuseGgx), not " + p.bsdf->name());
    } else {
        p.kind = ss.options.representation;
        why << "representation set on the surface";
    }
    if (textured) {
        // D holds irradiance / pi (albedo 1); the texture multiplies it where it is seen.
        why << "; albedo texture " << ss.material.albedo_texture->width() << " x " << ss.material.albedo_texture->height();
        if (p.kind == Representation::Diffuse) p.bsdf = std::make_shared<Lambert>(Vec3{1, 1, 1});
    }
    if (const auto& tint = ss.material.specular_texture)
        why << "; specular texture " << tint->width() << " x " << tint->height()
            << ": its blend of the radiance at f0 = 1 and at f0 = 0 (two 4D splines)";
    // The sides the scene lights (a transmitting surface's lower hemisphere is paper 4.3).
    p.live = lit.live;
    if (p.bsdf->transmits()) p.live = {true, p.kind == Representation::Glossy};
    p.sides = p.live[1] ? 2 : 1;
    if (p.bsdf->transmits()) {
        if (p.sides == 2) why << ", transmits: second spline for the lower hemisphere";
    } else if (s.two_sided) {
        why << "; front side: " << (p.live[0] ? "" : "no spline, ") << lit.why[0] << "; back side: "
            << (p.live[1] ? "" : "no spline, ") << lit.why[1];
    }
    // Spatial coefficients per direction. A decomposed surface's glossy part S shares its
    // diffuse part's knots, planned from the irradiance D holds: it keeps spatial_coeffs when the
    // probe is on. A glossy surface's are planned from its size and irradiance like a diffuse
    // one's and its finals from its converged coarse light along every angular node.
    const bool from_size = s.coeffs_from_size && extent > 0 && !(s.detail_tolerance > 0 && p.kind == Representation::Decomposed);
    const Shape shape = from_size ? shape_of(*ss.surface) : Shape{};
    auto spatial = [&](int along, int from_detail) {
        if (ss.options.spatial_coeffs) return std::max(ss.options.spatial_coeffs, s.spatial_degree + 1) * spatial_scale;
        int n = s.spatial_coeffs;
        if (from_size) {
            // Light that varies with the normal (any light but one from straight above) asks a
            // curved surface for a span every kTurningPerSpan of its normal's turning.
            constexpr double kTurningPerSpan = 0.5;  // radians, about 30 degrees
            const double wanted = std::max(s.spatial_coeffs * shape.length[along] / extent,
                                           shape.turning[along] / kTurningPerSpan + s.spatial_degree);
            n = std::clamp(int(std::ceil(wanted)), std::min(s.spatial_coeffs_min, s.spatial_coeffs), s.spatial_coeffs);
        }
        // The light's detail asks for spans down to 1/detail_density_max of the longest
        // receiver's, at most spatial_coeffs.
        int most = s.spatial_coeffs;
        if (from_size)
            most = std::min<double>(most, std::ceil(s.detail_density_max * (s.spatial_coeffs - s.spatial_degree) *
                                                    shape.length[along] / extent - 1e-9) + s.spatial_degree);
        return std::max(n, std::min(from_detail, most)) * spatial_scale;
    };
    p.nu = spatial(0, detail[0]);
    p.nv = spatial(1, detail[1]);
    why << "; " << p.nu << " x " << p.nv << " spatial coefficients";
    if (from_size && !ss.options.spatial_coeffs)
        why << (detail[0] || detail[1] ? " (from its size and its light's detail)" : " (from its size)");
    p.map_delta = s.angular_delta;
    if (bumped) {
        // Its normals lie within the scene's largest tilt: the spline spans that cap alone (the
        // map pulls any normal beyond it to its rim).
        constexpr double kCapMargin = 0.087;  // radians: 5 degrees
        const double cap = std::min(1.5 * scene.bumped_tilt() + kCapMargin, kPiD / 2 - s.angular_delta);
        p.map_delta = kPiD / 2 - cap;
    }
    if (p.kind != Representation::Diffuse) {
        // A bumped surface's irradiance over its normal has a kink along each small light's
        // terminator (n . omega = 0), which the spans must follow rather than the lobe: spans of
        // 0.52 in the disc at angular_resolution 1 (a washboard map against Cycles at preview,
        // ridges of 35 degrees on a 57.5-degree cap under a sun: 11 x 11 angular 0.29% per pixel,
        // the lobe's 7 x 7 1.3%, 13 x 13 0.24% with Cycles' noise 0.2%).
        constexpr double kBumpedSpan = 0.52;
        const double lobe = bumped ? kBumpedSpan : lobe_in_disc(*p.bsdf);
        const double R = std::sqrt(1 - std::sin(p.map_delta));
        p.na = ss.options.angular_coeffs
                   ? std::max(ss.options.angular_coeffs, s.angular_degree + 1)
                   : std::clamp(int(std::ceil(s.angular_resolution * 2 * R / lobe)) + s.angular_degree,
                                s.angular_coeffs_min, s.angular_coeffs_max);
        const int from_width = p.na;
        if (!ss.options.angular_coeffs && s.angular_albedo_tolerance > 0 && !p.bsdf->transmits() &&
            p.bsdf->lobe_width() >= kWideLobe && p.na < s.angular_coeffs_max && !bumped) {
            p.na = material_view_dependence_count(p.bsdf, lobe, s, p.na);
        }
        if (bumped)
            why << ", " << p.na << " x " << p.na << " angular over its bumped normal (within "
                << std::lround((kPiD / 2 - p.map_delta) * 180 / kPiD) << " degrees)";
        else
            why << ", " << p.na << " x " << p.na << " angular (lobe width " << p.bsdf->lobe_width() << " rad"
                << (p.na > from_width ? "; its light's change with the view" : "") << ")";
    }
    p.reason = why.str();
    return p;
}

// A spline set of a receiver: its RGB coefficients, and per side a TensorSpline (in the set's
// vector, one heap block) and its coefficients' block header (and a float32 one's padding). Its
// layout is shared (layout_bytes).
size_t set_bytes(const Plan& p, Precision precision = Precision::Float64) {
    const bool f32 = precision == Precision::Float32;
    return p.coefficients() * 3 * (f32 ? sizeof(float) : sizeof(double)) +
           size_t(p.sides) * (sizeof(TensorSpline) + 16 + (f32 ? TensorSpline::kFloat32Padding * sizeof(float) : 0)) + 16;
}

// A receiver's nodes: their grid (SpatialNodes, two heap blocks) and the nodes moved out from
// under closed meshes (move_hidden_nodes), kept in a map: about 12 bytes a node over the
// furnished interior's receivers, measured at 300 and 2,000 objects with 3 x 3 to 12 x 12 nodes.
size_t node_bytes(const Plan& p) { return size_t(p.nu + p.nv) * sizeof(double) + 32 + size_t(p.nu) * p.nv * 12; }

// A receiver besides its spline sets, nodes and layout: the object and a glossy one's angular
// node directions.
size_t receiver_bytes(const Plan& p) {
    size_t bytes = sizeof(Receiver) + 64;
    if (p.kind == Representation::Glossy) bytes += size_t(p.na) * p.na * sizeof(Vec3) + 16;
    return bytes;
}

// A receiver's spline layout (shared by receivers of equal knots, LayoutInterner): the layout
// and its strides, the axes' vector and the knot vectors, each heap block with its header.
size_t layout_bytes(const Plan& p, const SolverSettings& s) {
    const bool glossy = p.kind == Representation::Glossy;
    size_t bytes = sizeof(SplineLayout) + 32 + (glossy ? 4 : 2) * sizeof(size_t) + 16 + 2 * 32 +
                   KnotVector::bytes(p.nu, s.spatial_degree) + KnotVector::bytes(p.nv, s.spatial_degree);
    if (glossy) bytes += 2 * KnotVector::bytes(p.na, s.angular_degree);
    return bytes;
}

// The layouts of these plans' receivers: one per distinct knots. Without adaptive or
// discontinuity knots a plan's knots follow from its counts; with them, each its own. (Near-
// contact knots alone give their own layout only to the few receivers beside a near contact,
// about a kilobyte and a half each, left out.)
size_t layouts_bytes(const std::vector<Plan>& plans, const SolverSettings& s) {
    const bool by_counts = !s.adaptive_knots && !s.discontinuity_knots;
    std::set<std::array<int, 3>> seen;
    size_t bytes = 0;
    for (const Plan& p : plans) {
        // (Without inner knots the knots are the counts' whatever the light: the small faces of
        // an interior, most of its surfaces.)
        const bool own = !by_counts && (p.nu > s.spatial_degree + 1 || p.nv > s.spatial_degree + 1);
        if (own || seen.insert({p.nu, p.nv, p.kind == Representation::Glossy ? p.na : 0}).second) bytes += layout_bytes(p, s);
    }
    return bytes;
}

size_t plan_bytes(const Plan& p) {
    // Three spline sets (Le, L, Ltmp), the nodes and the receiver.
    return 3 * set_bytes(p) + node_bytes(p) + receiver_bytes(p);
}

// `detail`: per scene surface, the coefficients its direct light asks for (empty: none probed).
std::vector<Plan> plan_scene(const Scene& scene, const SolverSettings& s, int spatial_scale,
                             const std::vector<SurfaceSides>& sides, const std::vector<std::array<int, 2>>& detail = {}) {
    const double extent = s.coeffs_from_size ? scene_extent(scene) : 0;  // 81 evaluations a surface: only if used
    std::vector<Plan> plans;
    for (size_t i = 0; i < scene.size(); ++i) {
        if (!scene[i].receiver) continue;
        Plan p = plan_surface(scene, int(i), s, extent, spatial_scale, sides[i], detail.empty() ? std::array<int, 2>{} : detail[i]);
        if (scene[i].material.specular_texture) {
            // Schlick's Fresnel is affine in f0: the surface at f0 = 1 and, as its partner, at
            // f0 = 0, on the same knots; the texture blends them.
            Plan black = p;
            p.bsdf = scene[i].material.bsdf->with_specular_colour({1, 1, 1});
            black.bsdf = scene[i].material.bsdf->with_specular_colour({0, 0, 0});
            black.partner_of = int(plans.size());
            plans.push_back(std::move(p));
            plans.push_back(std::move(black));
            continue;
        }
        if (p.kind != Representation::Decomposed) {
            plans.push_back(std::move(p));
            continue;
        }
        // (38): D, the diffuse part, at the full spatial resolution, 2D; S, the glossy
        // remainder, 4D on half as many spatial knots ("mildly glossy surfaces with detail").
        Plan glossy = p;
        glossy.kind = Representation::Glossy;
        glossy.bsdf = p.bsdf->glossy_part();
        glossy.nu = std::max(s.spatial_degree + 1, p.nu / 2);
        glossy.nv = std::max(s.spatial_degree + 1, p.nv / 2);
        glossy.partner_of = int(plans.size());
        p.kind = Representation::Diffuse;
        p.bsdf = std::make_shared<Lambert>(scene[i].material.albedo_texture ? Vec3{1, 1, 1} : p.bsdf->diffuse_albedo());
        p.na = 1;
        p.reason += "; S on " + std::to_string(glossy.nu) + " x " + std::to_string(glossy.nv) + " spatial coefficients";
        plans.push_back(std::move(p));
        plans.push_back(std::move(glossy));
    }
    return plans;
}

// Interior knots equidistributing a density given on `cells` equal cells of [a, b]: each knot
// span holds the same share of the density's integral. Clamped, like (19).
KnotVector equidistributed_knots(const std::vector<double>& density, int num_coeffs, int degree, double a, double b) {
    const size_t cells = density.size();
    std::vector<double> cumulative(cells + 1, 0.0);
    for (size_t k = 0; k < cells; ++k) cumulative[k + 1] = cumulative[k] + density[k];
    const int inner = num_coeffs - degree - 1;
    std::vector<double> t(degree + 1, a);
    size_t cell = 0;
    for (int j = 1; j <= inner; ++j) {
        const double target = cumulative[cells] * j / (inner + 1);
        while (cell + 1 < cells && cumulative[cell + 1] < target) ++cell;
        const double within = (target - cumulative[cell]) / std::max(density[cell], 1e-300);
        t.push_back(a + (b - a) * (cell + std::clamp(within, 0.0, 1.0)) / cells);
    }
    t.insert(t.end(), degree + 1, b);
    return KnotVector(std::move(t), degree);
}

// Knots where detail is (paper 3.1: "if there is extra detail in one part of the surface the
// knots can be clustered there"): the direct light is probed on a grid twice as fine as the
// coefficients, and knots in u (v) are equidistributed by the square root of the light's second
// differences along u (v), which concentrates them at shadow edges and contact lines. Of the
// density, 1 - knot_detail_share stays uniform (solver.h), so no span is wider than 1 / that of
// the uniform one. No span gets narrower than about an eighth of it.
// detail_density: the probe's densities along u and v on equal cells of [eps, 1 - eps] (empty
// where the light is flat or dark: uniform), which adaptive_knots equidistributes.
std::array<std::vector<double>, 2> detail_density(const Gatherer& gather, const Scene& scene, const Plan& p,
                                                  const SolverSettings& settings, size_t& rays) {
    const double a = settings.epsilon, b = 1 - settings.epsilon;
    const int pu = 2 * p.nu + 1, pv = 2 * p.nv + 1;
    std::vector<double> f(size_t(pu) * pv);
    double fmax = 0;
    const Surface& surface = *scene[p.surface].surface;
    for (int i = 0; i < pu; ++i)
        for (int j = 0; j < pv; ++j) {
            // The sides solved: a room's walls are lit from behind.
            const Vec3 e = gather.irradiance(p.surface, surface.evaluate(a + (b - a) * i / (pu - 1), a + (b - a) * j / (pv - 1)),
                                             rays, p.live);
            fmax = std::max(fmax, f[size_t(i) * pv + j] = e.x + e.y + e.z);
        }
    if (!(fmax > 0)) return {};
    auto density_along = [&](bool along_u) {
        const int n = along_u ? pu : pv, m = along_u ? pv : pu;
        std::vector<double> second(n, 0.0);
        for (int i = 1; i + 1 < n; ++i)
            for (int j = 0; j < m; ++j) {
                auto at = [&](int k) { return along_u ? f[size_t(k) * pv + j] : f[size_t(j) * pv + k]; };
                second[i] += std::abs(at(i - 1) - 2 * at(i) + at(i + 1)) / (m * fmax);
            }
        std::vector<double> density(n - 1);
        double mean = 0;
        for (int k = 0; k + 1 < n; ++k) mean += density[k] = std::sqrt(0.5 * (second[k] + second[k + 1]));
        mean /= n - 1;
        if (!(mean > 1e-6)) return std::vector<double>{};
        const double share = settings.knot_detail_share;
        for (double& x : density) x = std::min((1 - share) + share * x / mean, 8.0);
        return density;
    };
    return {density_along(true), density_along(false)};
}

// A receiver's knots along u and v, and the jumps among them that stand for a narrow penumbra.
struct SpatialKnots {
    KnotVector u, v;
    std::array<std::vector<DiscontinuityLine>, 2> bands;
};

SpatialKnots adaptive_knots(const Gatherer& gather, const Scene& scene, const Plan& p, const SolverSettings& settings,
                            size_t& rays) {
    const int d = settings.spatial_degree;
    const double a = settings.epsilon, b = 1 - settings.epsilon;
    const auto density = detail_density(gather, scene, p, settings, rays);
    auto along = [&](int n, const std::vector<double>& f) {
        return n > d + 1 && !f.empty() ? equidistributed_knots(f, n, d, a, b) : KnotVector::clamped_uniform(n, d, a, b);
    };
    return {along(p.nu, density[0]), along(p.nv, density[1])};
}

// Knots on the lines where the direct light is not smooth (discontinuities.h), the others spread
// uniformly or, with adaptive_knots, by the probe's density; what was found goes into the
// plan's reason.
SpatialKnots knots_at_discontinuities(const DiscontinuityFinder& finder, const Gatherer& gather, const Scene& scene,
                                      Plan& p, const SolverSettings& settings, size_t& rays) {
    const int d = settings.spatial_degree;
    const double a = settings.epsilon, b = 1 - settings.epsilon;
    // A segment is a parameter line if it stays within a tenth of a span of one.
    const std::array<double, 2> tolerance{0.1 * (b - a) / std::max(p.nu - d, 1), 0.1 * (b - a) / std::max(p.nv - d, 1)};
    const ReceiverDiscontinuities found = finder.find(p.surface, p.live, tolerance, rays);
    std::array<std::vector<double>, 2> density;
    if (settings.adaptive_knots) density = detail_density(gather, scene, p, settings, rays);
    std::array<std::vector<DiscontinuityLine>, 2> placed;
    SpatialKnots out{discontinuity_knots(found.lines[0], p.nu, d, a, b, density[0], placed[0]),
                     discontinuity_knots(found.lines[1], p.nv, d, a, b, density[1], placed[1]), {}};
    for (int k = 0; k < 2; ++k)
        for (const DiscontinuityLine& line : placed[k])
            if (line.order == 0 && line.band > 0) out.bands[k].push_back(line);
    std::ostringstream why;
    why << (finder.kinds().events ? "; discontinuity knots: " : "; near-contact knots: ");
    if (!found.planar) why << found.note;
    else {
        why << placed[0].size() << " lines in u, " << placed[1].size() << " in v";
        if (found.oblique) why << ", " << found.oblique << " oblique event segments left to " << (settings.adaptive_knots ? "the probe" : "uniform knots");
        if (!found.note.empty()) why << "; " << found.note;
    }
    p.reason += why.str();
    return out;
}

// The spatial coefficients per direction that light sampled on an m x m grid over [eps, 1 - eps]^2
// (`f`, u slowest) asks for (paper 3.1: knots where there is detail): its largest second
// difference along u (v), w = h_p^2 |f''|, sets the knot spacing h at which a quadratic's
// interpolation error h^2 |f''| / 8 is detail_tolerance times the brightest sample. A shadow
// edge or a light close by asks for many, a face evenly lit by a distant light for few.
// `brightest`: the sample the tolerance is relative to where f is one of several (0: f's own).
std::array<int, 2> coeffs_for_samples(const std::vector<double>& f, int m, const SolverSettings& s, double brightest = 0) {
    const double fmax = brightest > 0 ? brightest : *std::max_element(f.begin(), f.end());
    if (!(fmax > 0)) return {0, 0};  // no light: its size decides
    std::array<int, 2> n{0, 0};
    for (int along = 0; along < 2; ++along) {
        double w = 0;
        for (int i = 1; i + 1 < m; ++i)
            for (int j = 0; j < m; ++j) {
                auto at = [&](int k) { return along == 0 ? f[size_t(k) * m + j] : f[size_t(j) * m + k]; };
                w = std::max(w, std::abs(at(i - 1) - 2 * at(i) + at(i + 1)));
            }
        const double spans = (m - 1) * std::sqrt(w / (8 * s.detail_tolerance * fmax));
        n[along] = int(std::min<double>(std::ceil(spans) + s.spatial_degree, s.spatial_coeffs));
    }
    return n;
}

// The probe's grid: 2 spatial_coeffs_min + 1 samples per axis, twice the fewest coefficients'.
int detail_grid(const SolverSettings& s) { return 2 * s.spatial_coeffs_min + 1; }
double detail_grid_at(const SolverSettings& s, int i) {
    const double a = s.epsilon, b = 1 - s.epsilon;
    return a + (b - a) * i / (detail_grid(s) - 1);
}

// The spatial coefficients per direction a surface's direct light asks for, where its size
// alone gave it fewer than spatial_coeffs: its irradiance probed on the detail grid.
std::array<int, 2> coeffs_for_detail(const Gatherer& gather, const Scene& scene, const Plan& p,
                                     const SolverSettings& s, size_t& rays) {
    const int m = detail_grid(s);
    const Surface& surface = *scene[p.surface].surface;
    std::vector<double> f(size_t(m) * m);
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
            const Vec3 e = gather.irradiance(p.surface, surface.evaluate(detail_grid_at(s, i), detail_grid_at(s, j)), rays, p.live);
            f[size_t(i) * m + j] = e.x + e.y + e.z;
        }
    return coeffs_for_samples(f, m, s);
}

// The spatial coefficients per direction the converged coarse light of a receiver asks its final
// gather for: its spline Le on the detail grid, each side's on its own (they are lit apart), and
// a glossy receiver's along each of its angular nodes, against the brightest sample of all its
// directions (a dim grazing direction asks for no more than its share of the light). This sees
// the light the direct probe cannot, free of rays: a face turned from the lamp, lit by its
// neighbours, brightening toward the floor it stands on; the room reflected in a metal ball.
std::array<int, 2> coeffs_for_coarse_light(const Receiver& r, const SolverSettings& s) {
    const int m = detail_grid(s);
    const size_t directions = r.kind == Representation::Diffuse ? 1 : r.directions.size();
    std::array<int, 2> n{0, 0};
    std::vector<std::vector<double>> f(directions, std::vector<double>(size_t(m) * m));
    for (int side = 0; side < r.sides; ++side) {
        if (!r.solves(side)) continue;
        double brightest = 0;
        for (size_t a = 0; a < directions; ++a)
            for (int i = 0; i < m; ++i)
                for (int j = 0; j < m; ++j) {
                    const Vec3 L = r.own_radiance(&Receiver::Le, detail_grid_at(s, i), detail_grid_at(s, j), r.outgoing(side, a));
                    brightest = std::max(brightest, f[a][size_t(i) * m + j] = L.x + L.y + L.z);
                }
        for (size_t a = 0; a < directions; ++a) {
            const std::array<int, 2> d = coeffs_for_samples(f[a], m, s, brightest);
            n = {std::max(n[0], d[0]), std::max(n[1], d[1])};
        }
    }
    return n;
}

// Per scene surface, coeffs_for_detail where the size-based plan gave fewer than spatial_coeffs.
std::vector<std::array<int, 2>> detail_of_scene(const Gatherer& gather, const Scene& scene, const std::vector<Plan>& plans,
                                                const SolverSettings& s, Progress& progress, size_t& rays) {
    std::vector<std::array<int, 2>> detail(scene.size(), std::array<int, 2>{0, 0});
    if (!s.coeffs_from_size || !(s.detail_tolerance > 0)) return detail;
    std::vector<const Plan*> probed;
    for (const Plan& p : plans)
        if (p.partner_of < 0 && !scene[p.surface].options.spatial_coeffs && (p.nu < s.spatial_coeffs || p.nv < s.spatial_coeffs))
            probed.push_back(&p);
    std::atomic<size_t> probe_rays{0};
    parallel_for(probed.size(), 1, s.threads, [&](size_t begin, size_t end) {
        size_t local = 0;
        for (size_t k = begin; k < end; ++k) detail[probed[k]->surface] = coeffs_for_detail(gather, scene, *probed[k], s, local);
        probe_rays += local;
    }, progress.cancel_flag());
    progress.throw_if_cancelled();
    rays += probe_rays;
    return detail;
}

// Schoenberg nodes (12), except that at a knot of multiplicity degree + 1 (a jump) the two
// nodes that fall on it sample the light just before and just after it: the basis function
// ending there takes the left limit, the one starting there the right limit. A jump standing
// for a narrow penumbra (`bands`) has them just outside the band, at most halfway across the
// span beside it: inside it they took the penumbra's middle for both sides.
std::vector<double> nodes_beside_jumps(const KnotVector& k, const std::vector<DiscontinuityLine>& bands) {
    std::vector<double> nodes = k.schoenberg_nodes();
    for (size_t i = 0; i + 1 < nodes.size(); ++i)
        if (nodes[i] == nodes[i + 1] && k.degree() > 0) {
            const double t = nodes[i];
            const auto& knots = k.knots();
            const auto lo = std::lower_bound(knots.begin(), knots.end(), t), hi = std::upper_bound(knots.begin(), knots.end(), t);
            const double left = lo == knots.begin() ? 0 : t - *(lo - 1), right = hi == knots.end() ? 0 : *hi - t;
            double half = 0;
            for (const DiscontinuityLine& b : bands)
                if (std::abs(b.position - t) <= 1e-12) half = 0.5 * b.band;  // (t a knot average: rounded)
            nodes[i] = t - std::min(half + 1e-3 * left, 0.5 * left), nodes[i + 1] = t + std::min(half + 1e-3 * right, 0.5 * right);
        }
    return nodes;
}

// The spline layouts of a set of receivers, one per distinct set of axes: receivers of equal
// knots (the small surfaces of a scene at a few coefficients each) share one layout and its
// knot vectors, whose span tables hold more than such a surface's coefficients (a kilobyte and a
// half at 8 x 8). By the knots' exact values.
class LayoutInterner {
public:
    std::shared_ptr<const SplineLayout> operator()(std::vector<KnotVector> axes) {
        size_t hash = axes.size();
        auto mix = [&](size_t h) { hash ^= h + 0x9e3779b97f4a7c15ull + (hash << 6) + (hash >> 2); };
        for (const KnotVector& a : axes) {
            mix(std::hash<int>()(a.degree()));
            for (double t : a.knots()) mix(std::hash<double>()(t));
        }
        auto same = [&](const SplineLayout& l) {
            const auto& b = *l.axes();
            if (b.size() != axes.size()) return false;
            for (size_t k = 0; k < b.size(); ++k)
                if (b[k].degree() != axes[k].degree() || b[k].is_periodic() != axes[k].is_periodic() || b[k].knots() != axes[k].knots())
                    return false;
            return true;
        };
        auto& bucket = layouts_[hash];
        for (const auto& l : bucket)
            if (same(*l)) return l;
        bucket.push_back(std::make_shared<const SplineLayout>(std::make_shared<const std::vector<KnotVector>>(std::move(axes)), 3));
        return bucket.back();
    }

private:
    std::unordered_map<size_t, std::vector<std::shared_ptr<const SplineLayout>>> layouts_;
};

// `bounces`: the receiver gathers bounces (L, Ltmp) into a float64 Le. A final gather's receiver
// holds its Le only, in float32: the precision of the images it is baked into, at half the
// finals' memory (the bounces' sums and convergence stay in float64); the solution has it in
// float64 again.
Receiver make_receiver(const Scene& scene, const Plan& p, const SpatialKnots& knots, const SolverSettings& s,
                       bool bounces, LayoutInterner& layouts) {
    const KnotVector &ku = knots.u, &kv = knots.v;
    Receiver r;
    r.surface = p.surface;
    r.kind = p.kind;
    r.bsdf = p.bsdf.get();
    r.sides = p.sides;
    r.live = p.live;
    r.map = HemisphereMap::for_max_angle(p.map_delta);
    if (p.partner_of < 0) {  // the textures weigh the surface's own receiver and, through it, its partner
        r.albedo = scene[p.surface].material.albedo_texture.get();
        r.tint = scene[p.surface].material.specular_texture.get();
    }
    r.normals = scene[p.surface].material.normal_texture.get();
    std::vector<KnotVector> axes{ku, kv};
    if (p.kind == Representation::Glossy) {
        const double R = r.map.radius();
        const KnotVector ka = KnotVector::clamped_uniform(p.na, s.angular_degree, -R, R);  // (24)
        axes.push_back(ka);
        axes.push_back(ka);
        const std::vector<double> nodes = ka.schoenberg_nodes();
        for (double alpha : nodes)
            for (double beta : nodes) {
                double xyz[3];
                r.map.to_direction(alpha, beta, xyz);  // (25): nodes outside the disc pulled in
                r.directions.push_back({xyz[0], xyz[1], xyz[2]});
            }
        r.per_node = r.directions.size();
    }
    // A side not solved keeps a single zero coefficient (degree 0), which every lookup reads as 0.
    // The spline sets share their layout, and all unsolved sides one.
    auto unsolved = [](size_t dims) {
        return std::make_shared<const SplineLayout>(
            std::make_shared<const std::vector<KnotVector>>(dims, KnotVector::clamped_uniform(1, 0, 0.0, 1.0)), 3);
    };
    static const std::shared_ptr<const SplineLayout> none_2d = unsolved(2), none_4d = unsolved(4);
    const std::shared_ptr<const SplineLayout> solved = layouts(std::move(axes));
    // The solution's float64 splines, checked before the final gather rather than after.
    if (!bounces) TensorSpline::check_memory_budget(*solved->axes(), 3);
    const auto& none = solved->dims() == 4 ? none_4d : none_2d;
    for (int side = 0; side < r.sides; ++side) {
        const auto& layout = r.live[side] ? solved : none;
        r.Le.emplace_back(layout, bounces ? Precision::Float64 : Precision::Float32);
        if (!bounces) continue;
        r.L.emplace_back(layout);
        r.Ltmp.emplace_back(layout);
    }
    r.axes = solved->axes();
    r.nodes = SpatialNodes(nodes_beside_jumps(ku, knots.bands[0]), nodes_beside_jumps(kv, knots.bands[1]));
    return r;
}

// Moves each node that a solved side sees only as the inside of closed, unlit meshes (under a
// block resting on the surface) to the nearest point of the surface that is seen: the nearest
// seen node in (u, v), then bisection towards it down to 1/64 of the way (the contact line).
// A surface hidden everywhere keeps its nodes.
void move_hidden_nodes(std::vector<Receiver>& receivers, const Scene& scene, const Gatherer& gather,
                       const std::vector<const Receiver*>& receiver_of, const SolverSettings& settings, Progress& progress,
                       size_t& rays) {
    if (!settings.hidden_nodes_to_contact) return;
    std::atomic<size_t> probe_rays{0};
    parallel_for(receivers.size(), 1, settings.threads, [&](size_t begin, size_t end) {
        size_t local = 0;
        for (size_t k = begin; k < end; ++k) {
            Receiver& r = receivers[k];
            const Surface& surface = *scene[r.surface].surface;
            // (A node hidden on one side is sampled a little aside, on the contact line.)
            auto hidden = [&](const SurfacePoint& p) { return gather.hidden(r, p, receiver_of, local); };
            const std::vector<double> us = (*r.axes)[0].schoenberg_nodes(), vs = (*r.axes)[1].schoenberg_nodes();
            std::vector<uint8_t> is_hidden(r.nodes.size());
            size_t count = 0;
            for (size_t j = 0; j < r.nodes.size(); ++j) count += is_hidden[j] = hidden(gather.node_point(r, j));
            if (count == 0 || count == r.nodes.size()) continue;
            const size_t nv = vs.size();
            for (size_t j = 0; j < r.nodes.size(); ++j) {
                if (!is_hidden[j]) continue;
                double u0 = us[j / nv], v0 = vs[j % nv], best = 1e300, u1 = u0, v1 = v0;
                for (size_t i = 0; i < r.nodes.size(); ++i) {
                    const double du = us[i / nv] - u0, dv = vs[i % nv] - v0;
                    if (!is_hidden[i] && du * du + dv * dv < best) best = du * du + dv * dv, u1 = us[i / nv], v1 = vs[i % nv];
                }
                for (int step = 0; step < 6; ++step) {  // (u0, v0) hidden, (u1, v1) seen
                    const double um = 0.5 * (u0 + u1), vm = 0.5 * (v0 + v1);
                    if (hidden(surface.evaluate(um, vm))) u0 = um, v0 = vm;
                    else u1 = um, v1 = vm;
                }
                r.nodes.move(j, {u1, v1});
            }
        }
        probe_rays += local;
    }, progress.cancel_flag());
    progress.throw_if_cancelled();
    rays += probe_rays;
}

// Work items counted receiver by receiver (a gather's nodes, the error estimate's checks): a
// running count, one number a receiver rather than a (receiver, item) pair an item.
class RunningCount {
public:
    template <class Count>
    RunningCount(size_t receivers, Count&& count) : first_(receivers + 1, 0) {
        for (size_t k = 0; k < receivers; ++k) first_[k + 1] = first_[k] + count(k);
    }
    size_t total() const { return first_.back(); }
    // Items before receiver k (k up to the receivers: all).
    size_t first(size_t k) const { return first_[k]; }
    // f(k, i) for items [b, e), item i of receiver k, in order (past receivers of no items).
    template <class F>
    void walk(size_t b, size_t e, F&& f) const {
        size_t k = size_t(std::upper_bound(first_.begin(), first_.end(), b) - first_.begin()) - 1;
        for (size_t w = b; w < e; ++w) {
            while (w >= first_[k + 1]) ++k;
            f(k, w - first_[k]);
        }
    }

private:
    std::vector<size_t> first_;
};

// Whether a glossy spline's angular knots resolve its BSDF's lobe: at least two spans across the
// lobe's width in the disc (as the plan measures it). A narrower lobe (a glass sheet's, a
// near-mirror's: their counts stop at angular_coeffs_max) is sampled too coarsely for a quadratic
// through three samples to say its curvature, and sharpening lifted its peaks far too high (the
// glass sheet's floor, lit through it, 8.9% -> 16.1% at preview).
bool lobe_resolved(const Receiver& r, const KnotVector& angular) {
    return (angular.num_coeffs() - angular.degree()) * lobe_in_disc(*r.bsdf) >= 2 * 2 * r.map.radius();
}

// The nodes whose samples stay as they are when a receiver's fit is sharpened: those the work
// took as means over their support (Receiver::support_means) and the nodes beside them, whose
// corrections would read a mean as a point value. Empty where there is none.
std::vector<uint8_t> kept_unsharpened(const Receiver& r) {
    if (std::find(r.support_means.begin(), r.support_means.end(), 1) == r.support_means.end()) return {};
    const size_t nu = r.nodes.axis(0).size(), nv = r.nodes.axis(1).size();
    std::vector<uint8_t> keep(r.support_means.size(), 0);
    for (size_t i = 0; i < nu; ++i)
        for (size_t j = 0; j < nv; ++j) {
            if (!r.support_means[i * nv + j]) continue;
            for (size_t a = i > 0 ? i - 1 : 0; a <= std::min(i + 1, nu - 1); ++a)
                for (size_t c = j > 0 ? j - 1 : 0; c <= std::min(j + 1, nv - 1); ++c) keep[a * nv + c] = 1;
        }
    return keep;
}

// Runs `work(receiver, node, values)` for every node of receivers [begin, end) on all threads
// and writes the values into the receivers' spline set `target`.
template <typename Work>
size_t gather_all(std::vector<Receiver>& receivers, size_t begin, size_t end, Receiver::Splines target,
                  const SolverSettings& settings, Progress& progress, Work&& work,
                  const std::vector<uint8_t>& skip = {}) {
    const RunningCount nodes(end - begin, [&](size_t k) {
        return skip.empty() || !skip[begin + k] ? receivers[begin + k].nodes.size() : size_t(0);
    });
    std::atomic<size_t> rays{0};
    parallel_for(nodes.total(), 4, settings.threads, [&](size_t b, size_t e) {
        size_t local_rays = 0;
        std::vector<Vec3> values;
        nodes.walk(b, e, [&](size_t k, size_t j) {
            Receiver& r = receivers[begin + k];
            values.assign(r.sides * r.per_node, Vec3{0, 0, 0});
            work(r, j, values.data(), local_rays);
            for (int side = 0; side < r.sides; ++side)
                for (size_t a = 0; a < r.per_node && r.solves(side); ++a)
                    r.set_coefficient(target, side, j, a, values[side * r.per_node + a]);
        });
        rays += local_rays;
        progress.advance(e - b);
    }, progress.cancel_flag());
    progress.throw_if_cancelled();
    if (settings.sharpen_fit) {
        parallel_for(end - begin, 1, settings.threads, [&](size_t b, size_t e) {
            for (size_t k = begin + b; k < begin + e; ++k) {
                if (!skip.empty() && skip[k]) continue;
                Receiver& r = receivers[k];
                r.support_means = kept_unsharpened(r);
                const std::vector<double>* nodes[2] = {&r.nodes.axis(0), &r.nodes.axis(1)};
                for (int side = 0; side < r.sides; ++side) {
                    if (!r.solves(side)) continue;
                    // A Float32 set (a regather's correction) is sharpened in float64, one
                    // spline at a time.
                    TensorSpline& stored = (r.*target)[side];
                    std::optional<TensorSpline> wide;
                    if (stored.precision() == Precision::Float32) wide = stored.with_precision(Precision::Float64);
                    TensorSpline& spline = wide ? *wide : stored;
                    for (int axis = 0; axis < 2; ++axis) sharpen_samples(spline, axis, *nodes[axis], r.support_means);
                    // A glossy spline's angular samples are at its Schoenberg nodes too: of the
                    // radiance extended outward from the disc's rim (the map pulls the nodes
                    // beyond it in), a kink there that the limiter leaves alone.
                    if (spline.dims() == 4 && lobe_resolved(r, spline.axis(2)))
                        for (int axis = 2; axis < 4; ++axis) sharpen_samples(spline, axis, {}, r.support_means);
                    if (wide) {  // in place: a new float32 array a spline would leave the old ones as holes
                        const std::vector<double>& sharp = wide->coeffs();
                        std::transform(sharp.begin(), sharp.end(), stored.coeffs_f32(), [](double x) { return float(x); });
                    }
                }
            }
        });
    }
    for (size_t k = begin; k < end; ++k) std::vector<uint8_t>().swap(receivers[k].support_means);
    return rays;
}

size_t node_count(const std::vector<Receiver>& receivers) {
    size_t n = 0;
    for (const auto& r : receivers) n += r.nodes.size();
    return n;
}

std::vector<Receiver> build_receivers(const Scene& scene, std::vector<Plan>& plans, const Gatherer& gather,
                                      const SolverSettings& settings, Progress& progress, size_t& rays,
                                      bool bounces = true) {
    const double a = settings.epsilon, b = 1 - settings.epsilon;
    std::vector<SpatialKnots> knots;
    for (const Plan& p : plans)
        knots.push_back({KnotVector::clamped_uniform(p.nu, settings.spatial_degree, a, b),
                         KnotVector::clamped_uniform(p.nv, settings.spatial_degree, a, b), {}});
    std::optional<DiscontinuityFinder> finder;
    if (settings.discontinuity_knots || settings.near_contact_knots) {
        std::vector<DistantSource> distant;
        if (settings.discontinuity_knots) {
            distant = bright_world_sources(gather.world_bright());
            for (const DistantLight& light : scene.distant_lights()) distant.push_back({light.direction, light.angle});
        }
        finder.emplace(scene, std::move(distant), &gather.caster(),
                       DiscontinuityKinds{settings.discontinuity_knots, settings.near_contact_knots});
    }
    if (settings.adaptive_knots || finder) {
        std::atomic<size_t> probe_rays{0};
        parallel_for(plans.size(), 1, settings.threads, [&](size_t begin, size_t end) {
            size_t local = 0;
            for (size_t k = begin; k < end; ++k)
                knots[k] = finder ? knots_at_discontinuities(*finder, gather, scene, plans[k], settings, local)
                                  : adaptive_knots(gather, scene, plans[k], settings, local);
            probe_rays += local;
        }, progress.cancel_flag());
        progress.throw_if_cancelled();
        rays += probe_rays;
    }
    std::vector<Receiver> receivers;
    receivers.reserve(plans.size());  // no copies of the nodes while growing
    LayoutInterner layouts;
    for (size_t k = 0; k < plans.size(); ++k) {
        receivers.push_back(make_receiver(scene, plans[k], knots[k], settings, bounces, layouts));
        receivers.back().index = int(k);
    }
    for (size_t k = 0; k < plans.size(); ++k)
        if (plans[k].partner_of >= 0) {
            receivers[k].is_partner = true;
            Receiver& base = receivers[plans[k].partner_of];
            base.partner = &receivers[k];
            // S of a layered coat took the base's share at the BSDF's albedo: a texture's texels show
            // through CoatedBase.
            if (base.albedo) base.coat = scene[base.surface].material.coated_base();
        }
    return receivers;
}

// The receiver that answers for each surface (the diffuse part D of a decomposed one).
std::vector<const Receiver*> index_by_surface(const Scene& scene, const std::vector<Receiver>& receivers) {
    std::vector<const Receiver*> of(scene.size(), nullptr);
    for (const auto& r : receivers)
        if (!r.is_partner) of[r.surface] = &r;
    return of;
}

// When to stop bouncing, and the geometric tail of the bounces not taken, per receiver and
// channel. Judged per receiver, not over the whole scene, so that a part lit a million times
// brighter, or a separate room of another albedo, neither stops the bounces before a dim part
// has converged nor lends it its decay. Increments are taken in pairs of consecutive bounces,
// P_k = I_k + I_(k-1), and their decay over two bounces, rho2 = P_k / P_(k-2): where light only
// goes back and forth between two surfaces (two facing plates) each gets light every other
// bounce, and the single-bounce ratio is meaningless. The bounces still to come then add
// rho2 / (1 - rho2) (L_k + L_(k-1)); its uncertainty is judged from the change of rho2 against
// the value two bounces earlier (an independent pair).
class BounceConvergence {
public:
    // Starts from the direct light, increment 0 (in L).
    explicit BounceConvergence(const std::vector<Receiver>& receivers)
        : state_(receivers.size()), held_(receivers.size(), 0.0), settled_(receivers.size(), 0), shape_(receivers.size()),
          shape_bounce_(receivers.size(), 0) {
        const auto sums = maxima(receivers);
        for (size_t k = 0; k < receivers.size(); ++k)
            for (int c = 0; c < 3; ++c) state_[k][c].increment = state_[k][c].pair[0] = sums[k][c];
    }

    // After a bounce (its increment in L, the cumulative light in Le): the relative radiance
    // still missing (without extrapolation) or the uncertainty of the tail (with it), the
    // largest over receivers and channels; `last_increment` gets the largest relative increment.
    double update(const std::vector<Receiver>& receivers, bool extrapolate, double& last_increment) {
        const auto sums = maxima(receivers);
        ++bounces_;
        brightest_ = {0, 0, 0};
        for (const auto& m : sums)
            for (int c = 0; c < 3; ++c) brightest_[c] = std::max(brightest_[c], m[3 + c]);
        double pairs[3] = {0, 0, 0};
        double error = 0;
        last_increment = 0;
        errors_.assign(receivers.size(), 0.0);
        for (size_t k = 0; k < receivers.size(); ++k)
            for (int c = 0; c < 3; ++c) {
                Channel& s = state_[k][c];
                const double increment = sums[k][c], total = sums[k][3 + c];
                const double pair = increment + s.increment;
                // rho2 of this bounce; 2 (unknown) until two pairs exist.
                const double rho2 = s.pair[1] > 0 ? pair / s.pair[1] : 2.0;
                s.increment = increment;
                s.total = total;
                pairs[c] += pair;
                s.pair[1] = s.pair[0], s.pair[0] = pair;
                s.rho2[2] = s.rho2[1], s.rho2[1] = s.rho2[0], s.rho2[0] = rho2;
                s.tail = 0;
                // Light at the rounding level of the brightest part has no relative accuracy to keep.
                if (!(total > kNegligible * brightest_[c]) || pair == 0) continue;
                last_increment = std::max(last_increment, increment / total);
                double channel_error = 1e300;
                if (rho2 < 1) {
                    s.tail = rho2 / (1 - rho2);
                    channel_error = pair * (extrapolate ? std::abs(rho2 - s.rho2[2]) / ((1 - rho2) * (1 - rho2)) : s.tail) / total;
                }
                error = std::max(error, channel_error);
                errors_[k] = std::max(errors_[k], channel_error);
            }
        for (size_t k = 0; k < receivers.size(); ++k) {
            errors_[k] = std::max(errors_[k], held_[k]);
            error = std::max(error, held_[k]);
        }
        for (int c = 0; c < 3; ++c) {
            scene_rho2_[c] = scene_pairs_[1][c] > 0 ? pairs[c] / scene_pairs_[1][c] : 2.0;
            scene_pairs_[1][c] = scene_pairs_[0][c], scene_pairs_[0][c] = pairs[c];
        }
        if (last_increment == 0) {
            // No receiver got light this bounce, so none will: the series has ended and nothing
            // is missing (a lone floor under a lamp), whatever the decay could not yet be judged from.
            for (auto& channels : state_)
                for (Channel& c : channels) c.tail = 0;
            errors_.assign(errors_.size(), 0.0);
            return 0;
        }
        return error;
    }

    // rho2 / (1 - rho2) per channel of receiver k, to multiply the last two increments by.
    std::array<double, 3> tail(int k) const {
        const auto& s = state_[size_t(k)];
        return {s[0].tail, s[1].tail, s[2].tail};
    }
    // What update() returned, for receiver k alone (0 before the first bounce).
    double error(int k) const { return errors_.empty() ? 0.0 : errors_[size_t(k)]; }

    // Whether receiver r has settled (SolverSettings::settle_factor), given its last increment
    // (in L) and the one before (in Ltmp): from then on each of its increments is decay() times
    // its increment two bounces before, to within `bound` of its light. Once settled, for good.
    // First its largest coefficients: every channel that has light anywhere in the scene must
    // have light here (one still dark may be lit by a later bounce: the faces of books pressed
    // against a shelf, dark after the direct light, "settled" on no light at all and stayed
    // black), its rho2 below 1 for the last three bounces, steady within kSteady and within
    // kSteady of the whole scene's, and its tail's uncertainty below `bound`. Then its shape:
    // the pair of increments, coefficient by coefficient, must be rho2 times the pair two
    // bounces before (kept meanwhile), to within `bound` once summed over the tail (a shape still
    // changing, as light from near and far arrives with different delays, is not a multiple of
    // the one before: on the furnished interior its largest coefficient alone settled receivers
    // ten times off the tolerance).
    bool settles(const Receiver& r, double bound) {
        const size_t k = size_t(r.index);
        if (settled_[k]) return true;
        if (!largest_settled(k, bound)) {
            std::vector<double>().swap(shape_[k]);
            return false;
        }
        const int age = shape_[k].empty() ? 0 : bounces_ - shape_bounce_[k];
        if (age == 1) return false;  // the pair two bounces before is kept: compare next bounce
        std::vector<double> pair;
        for (int side = 0; side < r.sides; ++side) {
            const auto& l = r.L[side].coeffs();
            const auto& before = r.Ltmp[side].coeffs();
            for (size_t c = 0; c < l.size(); ++c) pair.push_back(l[c] + before[c]);
        }
        if (age != 2) {  // none kept, or kept too long ago
            shape_[k] = std::move(pair), shape_bounce_[k] = bounces_;
            return false;
        }
        const auto& s = state_[k];
        double deviation[3] = {0, 0, 0};
        for (size_t c = 0; c < pair.size(); ++c)
            deviation[c % 3] = std::max(deviation[c % 3], std::abs(pair[c] - s[c % 3].rho2[0] * shape_[k][c]));
        double error = 0;
        for (int c = 0; c < 3; ++c)
            if (s[c].total > 0) error = std::max(error, deviation[c] / ((1 - s[c].rho2[0]) * s[c].total));
        if (!(error < bound)) {
            shape_[k] = std::move(pair), shape_bounce_[k] = bounces_;
            return false;
        }
        std::vector<double>().swap(shape_[k]);
        held_[k] = std::max({held_[k], errors_[k], error});
        settled_[k] = 1;
        return true;
    }
    // rho2 per channel of settled receiver k: each of its increments is this times its increment
    // two bounces before. Its error stays what it was when it settled (the extrapolated
    // increments' own rho2 is steady, and would claim none).
    std::array<double, 3> decay(int k) const {
        const auto& s = state_[size_t(k)];
        return {s[0].rho2[0], s[1].rho2[0], s[2].rho2[0]};
    }

private:
    static constexpr double kNegligible = 1e-12;
    static constexpr double kSteady = 0.05;  // of rho2, from one bounce to the next, to settle
    bool largest_settled(size_t k, double bound) const {
        if (errors_.empty() || !(errors_[k] < bound)) return false;
        bool lit = false;
        for (int c = 0; c < 3; ++c) {
            const Channel& s = state_[k][c];
            if (!(brightest_[c] > 0)) continue;
            if (!(s.total > kNegligible * brightest_[c]) || s.pair[0] == 0) return false;
            for (double rho2 : s.rho2)
                if (!(rho2 < 1)) return false;
            if (std::abs(s.rho2[0] - s.rho2[1]) > kSteady * s.rho2[1]) return false;
            if (std::abs(s.rho2[0] - scene_rho2_[c]) > kSteady * scene_rho2_[c]) return false;
            lit = true;
        }
        return lit;
    }
    struct Channel {
        double increment = 0;          // I_(k-1): largest |coefficient| of the last increment
        double total = 0;              // largest |coefficient| of Le
        double pair[2] = {0, 0};       // P_(k-1), P_(k-2)
        double rho2[3] = {2, 2, 2};    // rho2 of the last three bounces, newest first
        double tail = 0;
    };
    // Per receiver: the largest |coefficient| of the increment L, per channel, then of Le.
    static std::vector<std::array<double, 6>> maxima(const std::vector<Receiver>& receivers) {
        std::vector<std::array<double, 6>> sums(receivers.size(), std::array<double, 6>{});
        for (const Receiver& r : receivers) {
            auto& m = sums[size_t(r.index)];
            for (int side = 0; side < r.sides; ++side) {
                const auto& le = r.Le[side].coeffs();
                const auto& l = r.L[side].coeffs();
                for (size_t c = 0; c < le.size(); ++c) {
                    m[c % 3] = std::max(m[c % 3], std::abs(l[c]));
                    m[3 + c % 3] = std::max(m[3 + c % 3], std::abs(le[c]));
                }
            }
        }
        return sums;
    }
    std::vector<std::array<Channel, 3>> state_;
    std::vector<double> errors_;
    std::vector<double> held_;  // a settled receiver's error when it settled
    std::vector<uint8_t> settled_;
    std::vector<std::vector<double>> shape_;  // a receiver's pair of increments, while it may settle
    std::vector<int> shape_bounce_;           // the bounce it was kept at
    int bounces_ = 0;                         // update()s so far
    std::array<double, 3> brightest_{};  // largest |coefficient| of Le over all receivers, per channel
    // rho2 of the whole scene's increments (their pairs summed over receivers), per channel, and
    // the last two sums: late increments everywhere decay as the slowest mode of the transport.
    std::array<double, 3> scene_rho2_{2, 2, 2};
    std::array<std::array<double, 3>, 2> scene_pairs_{};
};

}  // namespace

SolverSettings SolverSettings::preset(const std::string& name) {
    // Each iterates on a coarse representation and refines in the final gather (paper 4.2),
    // preview twice and final four times (each later one reading the latest fine splines), their late bounces
    // with a quarter of the rays (draft's few nodes would be too few); the README lists their
    // measured time and error.
    SolverSettings s;
    s.final_gather = true;
    s.final_spatial_factor = 2;
    s.final_integration_factor = 1;
    s.distant_support_means = true;
    if (name == "draft") {
        s.spatial_coeffs = 8;
        s.angular_resolution = 2.0;
        s.angular_coeffs_max = 12;
        s.angular_albedo_tolerance = 0.03;
        s.hemisphere_nodes_theta = 8;
        s.hemisphere_nodes_phi = 16;
        s.bsdf_samples = 9;
        s.tolerance = 1e-2;
    } else if (name == "preview") {
        s.spatial_coeffs = 12;
        s.final_passes = 2;
        s.late_bounces_after = 1;
        s.angular_resolution = 3.0;
        s.emitter_shadow_depth = 3;
        s.tolerance = 3e-3;
        // Coefficients where the light needs them (issue 16): the furnished interior at 100
        // objects in 0.28x the time (37.3 -> 10.4 s, 4.6x fewer rays a surface) at the same
        // area-weighted error against the final preset's solve (1.85% -> 1.86%; per surface,
        // unweighted, median 4.2% -> 4.8%: a sun edge across a book's face gets fewer knots); the
        // study's scenes against Mitsuba within 0.012 points of the uniform 12 x 12 (Cornell box
        // 1.407% -> 1.419%, within what other knot counts give: 1.403% with size alone, 1.420%
        // at tolerance 0.001). README, "Effort where the light needs it".
        s.coeffs_from_size = true;
        s.detail_tolerance = 0.005;
        s.near_contact_knots = true;
        // Knots clustered at the direct light's detail, a quarter of their density: the study's
        // scenes against Mitsuba 3 at preview (bench/study/compare_preview.py) Bezier patches
        // 3.95% -> 2.13%, glossy spheres 2.92% -> 1.99%, contact shadows 3.77% -> 2.90%, Cornell
        // box 1.54% -> 1.23%, glossy-wall box 1.53% -> 1.20%, for 5-40% more CPU time (half
        // their density, as at final, took the Cornell boxes' knots from the indirect light's
        // detail: 1.84%, 1.70%).
        s.adaptive_knots = true;
        s.knot_detail_share = 0.25;
    } else if (name == "final" || name == "reference") {
        s.spatial_coeffs = 16;
        // Four final gathers: the later two carry the finals' light two bounces further into
        // cavities the coarse bounces lit through blurred openings (the validation's board
        // leaning on a wall: its back 1.014 -> 1.006 of Mitsuba's mean); every validation and
        // study scene measured gained (table_spheres 1.85% -> 1.72%, open_box 3.51% -> 3.40%)
        // for 15-35% more CPU time. Since the coarse correction (below) the third pass buys
        // 0.02-0.03 points at most and the fourth nothing within 0.01 (table_spheres 1.75%,
        // 1.72%, 1.71% with 2, 3, 4 passes; open_box 3.39%, 3.37%, 3.37%; the board's mean
        // 1.0023, 1.0021, 1.0016) for 8-15% of the CPU time each: a candidate for three.
        s.final_passes = 4;
        // The coarse light's error carried over eight coarse bounces before the second pass: the
        // wedge behind leaning_board's board, lit through the bounces' blurred ends, 1.12x
        // Mitsuba's inside after the four passes, 1.00x with it (the board's back 1.09 -> 1.01),
        // for 12-27% more CPU time (the GGX scenes the most); the other validation scenes within
        // 0.03 points of their error.
        s.final_correction_bounces = 8;
        s.late_bounces_after = 2;
        s.adaptive_knots = true;
        // Knots on the shadow edges and contact lines that run along parameter lines: the
        // validation's thin occluder 1.9% -> 1.2% of Mitsuba's; no other validation or study
        // scene changed by more than 0.05 points but the glass sheet's floor (9.5% -> 9.1%).
        // At preview it cost as much as it gained (knots spent on lines finer than its spans).
        s.discontinuity_knots = true;
        s.near_contact_knots = true;
        s.angular_resolution = 4.0;
        // A roughness-1 metal's 8 x 8 angular coefficients left its light 8% off at 75 degrees
        // (Cycles' shadowing); its albedo's fit within 0.5% takes 24 x 24 (tests/core/test_solver_glossy.py).
        s.angular_albedo_tolerance = 0.005;
        s.emitter_shadow_depth = 5;
        s.tolerance = 1e-3;
        // A surface's error of a few percent sits much of it in thin bands beside contact lines
        // and shadow edges, which a set of checks hits or misses by chance: the validation
        // scenes' objects' estimates varied between sets by a standard deviation of log2 of 0.37
        // (median) at 48 checks, 0.25 at 128, which cost 3-11% of the solve's rays (1-4% at 48).
        s.error_checks = 128;
        // Refined to 1% where the estimate says a surface is over it, within five times the
        // first solve's rays (the worst surfaces first; bsgi.refine): against Mitsuba the
        // validation's thin_occluder 1.2% -> 0.5%, leaning_board 2.6% -> 0.7%, open_box 3.4% ->
        // 1.4%, table_spheres 1.7% -> 1.5% (ceiling_light 0.4%: nothing over), for 2.6-5.5x the
        // CPU time (README, refinement). Three times was too little for a second pass of
        // open_box's floor and wall (2.1%, at 0.6x the CPU time): a pass is a whole solve.
        s.refine_to_error = 0.01;
        s.refine_cost = 5;
        if (name == "reference") {
            // Final's bounces, and a final gather that resolves shadow edges and contact lines
            // (four times the coefficients per direction) and the light it integrates there
            // (twice the nodes per axis): the settings that took the validation scenes' diffuse
            // ones under 1% of Mitsuba's, at 5-8 times final's cost.
            s.final_spatial_factor = 4;
            s.final_integration_factor = 2;
            s.refine_to_error = 0;  // one solve, fine everywhere: what refinement is measured against
            s.refine_cost = 0;
        }
    } else {
        throw std::invalid_argument("unknown preset '" + name + "': use draft, preview, final or reference");
    }
    return s;
}

// The rays' scene: the surfaces that block rays, by scene index (null for the others), and
// the window panes among them, which rays cross.
RayCaster ray_caster_of(const Scene& scene) {
    std::vector<const Surface*> occluders(scene.size(), nullptr);
    std::vector<std::optional<ThinGlass>> panes(scene.size());
    for (size_t i = 0; i < scene.size(); ++i) {
        if (scene[i].occluder) occluders[i] = scene[i].surface.get();
        panes[i] = scene[i].material.thin_glass;
    }
    return RayCaster(occluders, panes);
}

namespace {

// The final gather's integration nodes per axis at scene surface i: the settings' factor times
// the surface's own (SurfaceOptions::integration_factor, which refinement raises).
double final_density(const Scene& scene, const SolverSettings& s, int i) {
    return double(s.final_integration_factor) * scene[i].options.integration_factor;
}

// The fields of an error check's record (SolveSteps::State::CheckField).
constexpr int kCheckFields = 11;

// The error estimate's checks of a receiver of this many nodes: error_checks, but no more than a
// quarter of its nodes, in fours (each four has an input check and a doubled-nodes one), and at
// least 16: 48 checks on a book's face of 8 x 8 final nodes cost more than its final gather; 16
// say its relative RMS error to about 1/sqrt(32), 18%, against a factor of two asked of the
// estimate.
size_t error_checks_of(size_t nodes, const SolverSettings& s) {
    constexpr size_t kFewestChecks = 16;
    const size_t quarter = (nodes / 4 + 3) / 4 * 4;
    return std::min(size_t(s.error_checks), std::max(kFewestChecks, quarter));
}

// What a solve holds from its start to its end besides its receivers: the ray caster (a 64-byte
// record and about as much BVH a triangle, and an Embree geometry a surface, about 1 kB: 410 MB
// for the 350,000 quads of the interior of 50,000 objects), and per scene surface the gather's
// copy of it, its plans and its sides (768 bytes: the solve's state less its receivers and ray
// caster, 0.6-0.8 kB a surface on the furnished interior at 300 and 2,000 objects, measured
// with mallinfo2; it was counted as 8 kB a receiver with the receivers' axes copied thrice).
size_t fixed_bytes(const Scene& scene) {
    size_t triangles = 0, occluders = 0, grids = 0;
    for (const auto& s : scene.surfaces())
        if (s.occluder) triangles += s.surface->tessellate_for_rays().triangles.size() / 3, ++occluders;
    // The solve's gatherer and the error estimate's each keep the curved emitters' grids.
    for (const int e : scene.emitters()) grids += 2 * Gatherer::emitter_grid_bytes(*scene[e].surface);
    return triangles * 128 + occluders * 1024 + scene.size() * 768 + grids;
}

// Samples per axis of the coarse light's residual over a node's cell (the coarse correction).
constexpr int kResidualSamples = 4;

// The coarse correction's bounces: at most the solve's (the residual of bounces cut short holds
// the next one, which the correction must not carry further).
int correction_bounces(const SolverSettings& s) {
    return s.final_gather && s.final_passes > 1 ? std::min(s.final_correction_bounces, s.max_bounces) : 0;
}

// The stages of the final gather's coarse correction: its residual's restriction, then its bounces.
int correction_stages(const SolverSettings& s) { return correction_bounces(s) > 0 ? 1 + correction_bounces(s) : 0; }

// The bytes a local solve of these plans (and final plans) allocates after the sides probe, at
// its peak: fixed_bytes, the receivers (three spline sets and the nodes), and then the larger of
// a bounce's packed output with the form-factor rows and the final gather's finer receivers
// (their sets and nodes), which follow the bounces' increments.
size_t estimate_bytes(const Scene& scene, const SolverSettings& settings, const std::vector<Plan>& plans,
                      const std::vector<Plan>& final_plans) {
    size_t coarse = 0, resident = layouts_bytes(plans, settings), rows = 0, fine = 0, fine64 = 0, packed = 0,
           fine_nodes = layouts_bytes(final_plans, settings);
    for (const Plan& p : plans) {
        coarse += set_bytes(p);
        resident += plan_bytes(p);
        // Form-factor rows: at most one term per ray and basis function, 12 bytes each.
        if (settings.form_factors && p.kind == Representation::Diffuse)
            rows += size_t(p.live[0] + p.live[1]) * p.nu * p.nv * settings.hemisphere_nodes_theta * settings.hemisphere_nodes_phi *
                    (settings.spatial_degree + 1) * (settings.spatial_degree + 1) * sizeof(TransportTerm);
    }
    // The finals' Le and a regather's correction are float32 sets (make_receiver).
    for (const Plan& p : final_plans)
        fine += set_bytes(p, Precision::Float32), fine64 += set_bytes(p), packed += p.coefficients() * 3 * sizeof(double),
            fine_nodes += node_bytes(p) + receiver_bytes(p);
    // The local solve gathers each phase from the splines that hold its input (a runner's packed
    // copy of it is not counted). A bounce holds its packed output; with settle_factor, the pairs
    // of increments of receivers that may settle as well (at most a set).
    const size_t bounce = rows + (settings.settle_factor > 0 ? 2 : 1) * coarse;
    // The final gather holds the finals' set, a regather the correction as well, and the first
    // pass's light packed (float64) where a third pass needs it; the bounces' increments (two coarse
    // sets) and rows are freed by then, but the heap keeps what it cannot give back (a small
    // surface's splines are small blocks) and the finals, larger a surface, reuse only part of
    // it: counted as one set freed (measured on the interior at 10 to 100 objects: none freed
    // overestimates 10 objects by 25%, both underestimates 100 by 28%).
    // The coarse correction keeps a copy of the coarse light through the second pass (its
    // bounces' two sets come and go before the regather's correction set is made).
    const size_t final = final_plans.empty() ? 0
                                             : fine + (settings.final_passes > 1 ? fine : 0) +
                                                   (settings.final_passes > 2 ? packed : 0) + fine_nodes +
                                                   (correction_stages(settings) ? coarse : 0);
    const size_t freed = final_plans.empty() ? 0 : coarse;
    // Each thread keeps the scatter tables of its last few view-dependent receivers, at most at
    // the final gather's density. (The error estimate's gatherer at twice that density gathers a
    // check's few directions at a time: its tables are small. Counted as the largest tables at
    // twice the density, the estimate was 1.9 times the peak measured at 10 objects.)
    size_t table = 0;
    for (const Plan& p : plans) {
        if (p.kind == Representation::Diffuse) continue;
        const bool transmits = p.bsdf->transmits();
        const double density = settings.final_gather ? std::max(1.0, final_density(scene, settings, p.surface)) : 1.0;
        const size_t incoming = size_t(transmits ? 2 : 1) * nodes_along(settings.hemisphere_nodes_theta, density) *
                                nodes_along(settings.hemisphere_nodes_phi, density);
        table = std::max(table, ScatterTable::bytes(size_t(transmits ? p.sides : 1) * p.na * p.na, incoming,
                                                    nodes_along(settings.bsdf_samples, density), p.bsdf->gather_branches()));
    }
    const size_t tables = size_t(resolve_threads(settings.threads)) * ScatterTable::kRecent * table;
    resident += tables;
    // The error estimate reads the result (the finals, if any; the correction is freed) and
    // keeps per result receiver its checks' record (a count and kCheckFields doubles a check),
    // and while gathering them the checks' points, then their input errors.
    size_t records = 0;
    for (const Plan& p : final_plans.empty() ? plans : final_plans) {
        const size_t checks = error_checks_of(size_t(p.nu) * p.nv, settings);
        records += (1 + (kCheckFields + 3 + 1) * checks) * sizeof(double) + 48;
    }
    // With a final gather, the input pass's scales too (InputScales, per scene surface).
    const size_t scales = InputScales::values_for(scene.size()) * sizeof(double);
    const size_t estimate = settings.estimate_error ? records + (final_plans.empty() ? 0 : fine + fine_nodes + 2 * scales) : 0;
    // At the end the finals become the solution's splines, in float64, with the coarse receivers
    // freed.
    const size_t output = final_plans.empty() ? 0 : tables + fine64 + fine_nodes;
    return fixed_bytes(scene) + std::max(output, resident + std::max(bounce, std::max(final, estimate) -
                                                                              std::min(freed, std::max(final, estimate))));
}

}  // namespace

std::vector<SurfaceSides> probe_sides(const Scene& scene, const SolverSettings& settings, size_t* bytes) {
    return probe_sides(scene, ray_caster_of(scene), settings, bytes);
}

size_t estimate_solve_bytes(const Scene& scene, const SolverSettings& settings, const std::vector<SurfaceSides>* probed) {
    validate(settings);  // the plan's arithmetic assumes valid settings (UBSan found an int overflow)
    if (probed && probed->size() != scene.size())
        throw std::invalid_argument("estimate_solve_bytes: sides of " + std::to_string(probed->size()) +
                                    " surfaces given for a scene of " + std::to_string(scene.size()));
    // The light's detail is only known after probing it (the finals': after the bounces): every
    // surface as if its light asked for all spatial_coeffs, which detail_density_max limits.
    std::vector<std::array<int, 2>> detail;
    if (settings.coeffs_from_size && settings.detail_tolerance > 0)
        detail.assign(scene.size(), {settings.spatial_coeffs, settings.spatial_coeffs});
    size_t probe = 0;
    const std::vector<SurfaceSides> sides = probed ? *probed : probe_sides(scene, settings, &probe);
    const std::vector<Plan> plans = plan_scene(scene, settings, 1, sides, detail);
    const size_t solve = estimate_bytes(scene, settings, plans,
                                        settings.final_gather ? plan_scene(scene, settings, settings.final_spatial_factor, sides, detail)
                                                              : std::vector<Plan>{});
    // The probe runs beside what the whole solve holds; its memory is freed before the receivers
    // are made.
    return std::max(probe ? probe + fixed_bytes(scene) : 0, solve);
}

namespace {

size_t packed_size(const std::vector<Receiver>& receivers, size_t begin, size_t end, Receiver::Splines which) {
    size_t size = 0;
    for (size_t k = begin; k < end; ++k)
        for (const TensorSpline& side : receivers[k].*which) size += side.num_values();
    return size;
}

// Coefficients of a spline set of receivers [begin, end), flat: receiver after receiver, sides in
// order, appended to `flat` (whose caller reserved room: growing by doubling would hold up to
// three times the set).
void pack_onto(std::vector<double>& flat, const std::vector<Receiver>& receivers, size_t begin, size_t end,
               Receiver::Splines which) {
    for (size_t k = begin; k < end; ++k)
        for (const TensorSpline& side : receivers[k].*which)
            if (side.precision() == Precision::Float32) flat.insert(flat.end(), side.coeffs_f32(), side.coeffs_f32() + side.num_values());
            else flat.insert(flat.end(), side.coeffs().begin(), side.coeffs().end());
}

std::vector<double> pack(const std::vector<Receiver>& receivers, size_t begin, size_t end, Receiver::Splines which) {
    std::vector<double> flat;
    flat.reserve(packed_size(receivers, begin, end, which));
    pack_onto(flat, receivers, begin, end, which);
    return flat;
}

// to += from, coefficient by coefficient, on every side of receivers [begin, end) (a float32 sum
// rounded once a coefficient).
void add_onto(std::vector<Receiver>& receivers, size_t begin, size_t end, Receiver::Splines to, Receiver::Splines from) {
    for (size_t k = begin; k < end; ++k)
        for (int side = 0; side < receivers[k].sides; ++side) {
            TensorSpline& sum = (receivers[k].*to)[side];
            const TensorSpline& term = (receivers[k].*from)[side];
            const size_t n = sum.num_values();
            const float* t32 = term.precision() == Precision::Float32 ? term.coeffs_f32() : nullptr;
            const double* t64 = t32 ? nullptr : term.coeffs().data();
            auto at = [&](size_t c) { return t32 ? double(t32[c]) : t64[c]; };
            if (sum.precision() == Precision::Float32) {
                float* c32 = sum.coeffs_f32();
                for (size_t c = 0; c < n; ++c) c32[c] = float(double(c32[c]) + at(c));
            } else {
                double* c64 = sum.coeffs().data();
                for (size_t c = 0; c < n; ++c) c64[c] += at(c);
            }
        }
}

// The inverse of pack; receivers with `skip` set keep their coefficients.
void unpack(const double* flat, size_t count, std::vector<Receiver>& receivers, size_t begin, size_t end, Receiver::Splines which,
            const std::vector<uint8_t>& skip = {}) {
    const size_t size = packed_size(receivers, begin, end, which);
    if (count != size)
        throw std::invalid_argument("solve step: " + std::to_string(count) + " coefficients given for receivers " +
                                    std::to_string(begin) + " to " + std::to_string(end) + ", which have " + std::to_string(size));
    const double* from = flat;
    for (size_t k = begin; k < end; ++k)
        for (TensorSpline& side : receivers[k].*which) {
            const size_t n = side.num_values();
            if (skip.empty() || !skip[k]) {
                if (side.precision() == Precision::Float32)
                    std::transform(from, from + n, side.coeffs_f32(), [](double x) { return float(x); });
                else
                    std::copy(from, from + n, side.coeffs().begin());
            }
            from += n;
        }
}

void unpack(const std::vector<double>& flat, std::vector<Receiver>& receivers, size_t begin, size_t end, Receiver::Splines which,
            const std::vector<uint8_t>& skip = {}) {
    unpack(flat.data(), flat.size(), receivers, begin, end, which, skip);
}

std::vector<size_t> nodes_of(const std::vector<Receiver>& receivers) {
    std::vector<size_t> n;
    for (const auto& r : receivers) n.push_back(r.nodes.size());
    return n;
}

// Checks the inputs and begins the first of the solve's stages: their count.
int begin_solve(const Scene& scene, const SolverSettings& settings, Progress& progress) {
    validate(settings);
    bool any_emitter = false;
    for (const auto& s : scene.surfaces()) any_emitter |= s.material.emits();
    if (!any_emitter && !scene.has_world() && scene.distant_lights().empty())
        throw std::invalid_argument("scene has no emitter: add a light, an emissive material or world light");
    // Form factors carry one scalar weight per coefficient: not the colour of albedo textures.
    const int ff_stage = settings.form_factors && !scene.has_coloured_transport() && settings.max_bounces > 0 ? 1 : 0;
    const int stages = 2 + ff_stage + settings.max_bounces + (settings.final_gather ? settings.final_passes : 0) +
                       correction_stages(settings) + (settings.estimate_error ? 1 : 0);
    progress.begin_stage("building ray scene", 0, stages, 1);
    return stages;
}

// The error estimate's check points: a low-discrepancy (R2) sequence over the parameter square,
// whose points fall between the Schoenberg nodes of any knots, and per point kCheckDirections
// cosine-distributed outgoing directions (stratified in cos^2 theta, turned from point to point),
// which fall between a glossy receiver's angular nodes.
constexpr int kCheckDirections = 8;

std::array<double, 2> check_point(size_t i) {
    return {std::fmod(0.5 + i * 0.7548776662466927, 1.0), std::fmod(0.5 + i * 0.5698402909980532, 1.0)};
}

// A check point and its weight: the inverse of its density against uniform points.
struct CheckPoint {
    double u, v, weight;
};

// n check points of receiver r where its splines' error is likely: a spline's error grows with
// h^2 |f''| (h its knot spacing), and its second differences over h show where (shadow edges and
// contact lines, whose error a few uniform points would miss on a large surface). The light of
// the lights at infinity (`distant`: at (u, v) on a side, exact, one shadow ray a sample) is
// taken out of the spline first: where the spline follows a sun's edge the difference is smooth,
// where it blurs one (an oblique edge that no knot follows) the difference keeps the edge, which
// the spline's own differences hardly show (the sunlit room's floor, its final spline 40% off in
// the block's shadow, was estimated at 4% of its error). Chosen among
// 16 n candidates of the R2 sequence with density 1/2 + 1/2 of that indicator's share
// (defensive: smooth parts keep half the points), by systematic sampling; each weighted by the
// inverse of its density, so that weighted means are those over uniform points. Candidates
// `hidden` (inside a closed object: the floor under a box) are left out, and the means are those
// over the visible part of the surface. The candidates are the sequence's from `seed` times a
// stride longer than any receiver's candidates (SolverSettings::error_checks_seed).
template <typename Hidden, typename Distant>
std::vector<CheckPoint> check_points(const Receiver& r, size_t n, size_t seed, Hidden&& hidden, Distant&& distant) {
    const size_t m = kCandidatesPerCheck * n, first = seed * kCandidatesPerCheck * kMaxErrorChecks;
    auto candidate = [first](size_t i) { return check_point(first + i); };
    const Vec3 normal{0, 0, r.solves(0) || !r.solves(1) ? 1.0 : -1.0};
    const int side = normal.z > 0 ? 0 : 1;
    // Taken out only where they reach a candidate (most of a furnished room lies in shade): a
    // shadow ray a candidate until one is lit.
    bool lit = false;
    for (size_t i = 0; i < m && !lit; ++i) {
        const auto [u, v] = candidate(i);
        lit = distant(u, v, side) > 0;
    }
    auto f = [&](double u, double v) {
        u = std::clamp(u, 0.0, 1.0), v = std::clamp(v, 0.0, 1.0);
        const Vec3 L = r.radiance(&Receiver::Le, u, v, normal);
        return L.x + L.y + L.z - (lit ? distant(u, v, side) : 0.0);
    };
    // The local knot spacing (adaptive knots cluster at shadow edges).
    const TensorSpline& spline = r.Le[r.solves(0) || !r.solves(1) ? 0 : 1];
    auto spacing = [&](int axis, double x) {
        const KnotVector& k = spline.axis(axis);
        return 1.0 / k.span_inverse_width(k.find_span(std::clamp(x, k.domain_begin(), k.domain_end())));
    };
    std::vector<double> score(m, -1.0);  // -1: hidden
    double mean = 0;
    size_t visible = 0;
    for (size_t i = 0; i < m; ++i) {
        const auto [u, v] = candidate(i);
        if (hidden(u, v)) continue;
        const double c = f(u, v), hu = spacing(0, u), hv = spacing(1, v);
        const double d2 = std::abs(f(u - hu, v) - 2 * c + f(u + hu, v)) + std::abs(f(u, v - hv) - 2 * c + f(u, v + hv));
        mean += score[i] = d2;
        ++visible;
    }
    std::vector<CheckPoint> out;
    if (!visible) return out;
    mean /= visible;
    for (double& x : score)
        if (x >= 0) x = mean > 0 ? 0.5 + 0.5 * x / mean : 1.0;  // density against uniform, mean 1
    double cumulative = 0;
    size_t next = 0;
    for (size_t i = 0; i < m && next < n; ++i) {
        if (score[i] < 0) continue;
        cumulative += score[i] / visible;
        for (; next < n && cumulative * n > next + 0.5; ++next) {
            const auto [u, v] = candidate(i);
            out.push_back({u, v, 1.0 / score[i]});
        }
    }
    return out;
}

std::vector<Vec3> check_directions(size_t i) {
    std::vector<Vec3> d;
    for (int a = 0; a < kCheckDirections; ++a) {
        const double w = (a + 0.5) / kCheckDirections;
        const double phi = 2 * 3.14159265358979323846 * std::fmod(a * 0.6180339887498949 + i * 0.7548776662466927, 1.0);
        const double cos_t = std::sqrt(w), sin_t = std::sqrt(1 - w);
        d.push_back({sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t});
    }
    return d;
}

// The directions a check compares values at, for viewers along `views`: a bumped receiver's
// radiance is its map's normal's whatever the view (the values all at that normal: one gather's
// rays, a BSDF evaluation each).
std::vector<Vec3> value_directions(const Receiver& r, const std::vector<Vec3>& views, double u, double v) {
    if (!r.normals) return views;
    return std::vector<Vec3>(views.size(), bumped_normal(*r.normals, u, v));
}

// A receiver of r's material and sides whose one node is the check point (u, v) and whose angular
// nodes are `directions` (if glossy): gathering at it is the phase's gather where no node sits.
Receiver probe_of(const Receiver& r, double u, double v, const std::vector<Vec3>& directions) {
    Receiver q;
    q.surface = r.surface;
    q.index = r.index;
    q.kind = r.kind;
    q.bsdf = r.bsdf;
    q.albedo = r.albedo;
    q.coat = r.coat;
    q.tint = r.tint;
    q.normals = r.normals;
    q.sides = r.sides;
    q.live = r.live;
    q.map = r.map;
    q.nodes = SpatialNodes({u}, {v});
    if (r.kind != Representation::Diffuse) q.directions = directions, q.per_node = directions.size();
    return q;
}

// The sides a viewer sees of a receiver: both of a transmitting one, else the front if it was
// solved, else the back.
std::array<bool, 2> sides_seen(const Receiver& r) {
    if (r.bsdf->transmits()) return {r.solves(0), r.solves(1)};
    return {r.solves(0), !r.solves(0) && r.solves(1)};
}

// The settings of the error estimate's second gather: twice the integration nodes per direction
// (hemisphere nodes, BSDF samples as a density of 2 would give them, emitter cells half as wide,
// twice the world's bright directions).
SolverSettings doubled_integration(SolverSettings s) {
    s.hemisphere_nodes_theta *= 2;
    s.hemisphere_nodes_phi *= 2;
    s.bsdf_samples *= 2;
    s.emitter_cell_ratio *= 0.5;
    s.emitter_max_depth = std::min(s.emitter_max_depth + 1, 20);
    s.world_bright_samples *= 2;
    return s;
}

}  // namespace

struct SolveSteps::State {
    const Scene& scene;
    const SolverSettings settings;
    const int stages;
    int ff_stage = 0;
    const RayCaster caster;
    std::vector<SurfaceSides> sides;
    std::vector<Plan> plans, final_plans;
    // Per scene surface, the coefficients its direct light asked for (detail_tolerance).
    std::vector<std::array<int, 2>> direct_detail;
    size_t bytes = 0;
    Scene lit_scene;
    std::optional<Gatherer> gather;
    const SolverSettings fine_settings;  // of the error estimate's doubled gather
    std::optional<Gatherer> fine_gather;
    size_t knot_rays = 0;  // of placing the knots, counted once by the solve however many steps place them
    std::vector<Receiver> receivers, finals;
    bool finals_built = false;
    // Whether the receivers hold the converged coarse light Le that the finals are planned from.
    bool coarse_light = false;
    std::vector<const Receiver*> receiver_of, final_of;
    std::optional<RunningCount> checks_;  // see checks()
    // With form factors, Lambertian receivers keep their rows of the transport operator. A row's
    // weights are scalars: they cannot carry the colour of a textured surface its rays hit.
    bool rows_possible = false;
    std::vector<std::vector<std::vector<TransportTerm>>> rows;
    std::vector<char> rows_done;

    bool solved = false;

    State(const Scene& scene_, const SolverSettings& settings_, Progress& progress, const std::vector<SurfaceSides>* probed)
        : scene(scene_), settings(settings_), stages(begin_solve(scene_, settings_, progress)), caster(ray_caster_of(scene_)),
          fine_settings(doubled_integration(settings_)) {
        rows_possible = settings.form_factors && !scene.has_coloured_transport();
        ff_stage = rows_possible && settings.max_bounces > 0 ? 1 : 0;
        if (probed && probed->size() != scene.size())
            throw std::invalid_argument("solve steps: sides of " + std::to_string(probed->size()) + " surfaces given for a scene of " +
                                        std::to_string(scene.size()));
        sides = probed ? *probed : probe_sides(scene, caster, settings);
        // The scene as the gathering sees it: emitters whose back side encloses its light emit
        // from their front only. Built before the plans: the probe of the direct light's detail
        // (detail_tolerance) gathers.
        lit_scene = scene;
        for (size_t i = 0; i < scene.size(); ++i)
            if (sides[i].encloses_emission) lit_scene.set_two_sided_emission(i, false);
        gather.emplace(lit_scene, settings, caster);
        plans = plan_scene(scene, settings, 1, sides);
        direct_detail = detail_of_scene(*gather, scene, plans, settings, progress, knot_rays);
        if (std::any_of(direct_detail.begin(), direct_detail.end(), [](const std::array<int, 2>& d) { return d[0] || d[1]; }))
            plans = plan_scene(scene, settings, 1, sides, direct_detail);
        if (settings.final_gather) final_plans = plan_scene(scene, settings, settings.final_spatial_factor, sides, direct_detail);
        bytes = estimate_bytes(scene, settings, plans, final_plans);
        check_budget(plans);
        for (const Plan& p : plans)
            if (p.kind != Representation::Diffuse && p.bsdf->lobe_width() <= 0)
                throw std::invalid_argument("surface '" + scene[p.surface].surface->name() +
                                            "': a perfectly smooth (mirror or glass) BSDF has no spline representation; "
                                            "give it a roughness");

        progress.begin_stage("placing knots", 0, stages, 1);
        receivers = build_receivers(scene, plans, *gather, settings, progress, knot_rays);
        receiver_of = index_by_surface(scene, receivers);
        move_hidden_nodes(receivers, scene, *gather, receiver_of, settings, progress, knot_rays);
        rows.resize(receivers.size());
        rows_done.assign(receivers.size(), 0);
    }

    // Refuses, naming the largest surface of `of`, a solve whose estimate is over the budget.
    void check_budget(const std::vector<Plan>& of) const {
        if (bytes <= settings.memory_budget_mb * 1024 * 1024) return;
        const Plan* largest = nullptr;
        for (const Plan& p : of)
            if (!largest || plan_bytes(p) > plan_bytes(*largest)) largest = &p;
        std::ostringstream msg;
        msg << "solve needs about " << bytes / (1024 * 1024) << " MB, over the budget of " << settings.memory_budget_mb << " MB";
        if (largest)
            msg << "; the largest is surface '" << scene[largest->surface].surface->name() << "' with "
                << largest->coefficients() << " RGB coefficients (" << plan_bytes(*largest) / (1024 * 1024) << " MB: "
                << largest->reason << ")";
        throw std::runtime_error(msg.str());
    }

    bool uses_rows(const Receiver& r) const {
        return rows_possible && r.kind == Representation::Diffuse && !r.bsdf->transmits();
    }

    // The finals, built by the first phase that needs them on these steps (`what` names it):
    // planned from the coarse light with a detail tolerance, which the phase's input holds
    // packed, ending `after` values before the input's end.
    void finals_from_input(const SolveSteps::Input& input, size_t after, const std::string& what, Progress& progress) {
        if (settings.final_gather && !finals_built && plans_from_detail()) {
            const size_t size = packed_size(receivers, 0, receivers.size(), &Receiver::Le);
            if (input.size < size + after)
                throw std::invalid_argument("solve step: " + what + " reads the coarse Le (" + std::to_string(size) +
                                            " coefficients) and " + std::to_string(after) + " values after it, given " +
                                            std::to_string(input.size));
            unpack(input.data + input.size - after - size, size, receivers, 0, receivers.size(), &Receiver::Le);
            coarse_light = true;
        }
        build_finals(progress);
    }

    // The final gather's finer receivers, with their own knots. With detail_tolerance a diffuse
    // or glossy surface's finals get the coefficients its converged coarse light asks for where its direct
    // light asked for fewer (coeffs_for_coarse_light): their count is known only once the
    // bounces are done, on every worker from the coarse light its phase reads.
    void build_finals(Progress& progress) {
        if (finals_built || !settings.final_gather) return;
        if (plans_from_detail()) {
            if (!coarse_light) throw std::logic_error("solve steps: the finals are planned from the coarse light, not yet given");
            std::vector<std::array<int, 2>> detail = direct_detail;
            parallel_for(receivers.size(), 16, settings.threads, [&](size_t begin, size_t end) {
                for (size_t k = begin; k < end; ++k) {
                    const Receiver& r = receivers[k];
                    if (r.is_partner || r.kind == Representation::Decomposed || scene[r.surface].options.spatial_coeffs) continue;
                    const std::array<int, 2> d = coeffs_for_coarse_light(r, settings);
                    detail[r.surface] = {std::max(detail[r.surface][0], d[0]), std::max(detail[r.surface][1], d[1])};
                }
            });
            std::vector<Plan> planned = plan_scene(scene, settings, settings.final_spatial_factor, sides, detail);
            for (size_t k = 0; k < planned.size(); ++k)
                if (planned[k].nu != final_plans[k].nu || planned[k].nv != final_plans[k].nv)
                    planned[k].reason += "; its light after the bounces asked for more than its direct light's " +
                                         std::to_string(final_plans[k].nu) + " x " + std::to_string(final_plans[k].nv);
            final_plans = std::move(planned);
            bytes = estimate_bytes(scene, settings, plans, final_plans);
            check_budget(final_plans);
        }
        finals = build_receivers(scene, final_plans, *gather, settings, progress, knot_rays, false);
        move_hidden_nodes(finals, scene, *gather, receiver_of, settings, progress, knot_rays);
        final_of = index_by_surface(scene, finals);
        finals_built = true;
    }

    // The per-surface error estimate (SurfaceReport::estimated_error) of the last phase's
    // splines Le (estimated(): the finals, or the receivers without a final gather), indexed
    // like them (NaN for partners, which count with their surface): at each check point, the
    // light gathered as the last phase would gather it (direct light, and the others'
    // cumulative radiance Le with the world's along the same rays: without a final gather, the
    // bounces' sum Le is the fixed point of that gather) against the spline, relative RMS over
    // the visible checks; at every other check the error of the input the gather read (the
    // others' splines, from their coarse and final ones), at every fourth the gather at doubled
    // integration nodes; and the bounces' radiance still missing (the tail).
    //
    // It runs in two passes over receivers, each a phase a solve's runner can split over
    // workers: estimate_checks (the spline against the gathers) and, with a final gather,
    // estimate_inputs (the input's error, weighted by every surface's input_scales from the
    // first pass's records); estimate_errors adds the parts up.
    std::vector<Receiver>& estimated() { return settings.final_gather ? finals : receivers; }
    bool plans_from_detail() const { return settings.coeffs_from_size && settings.detail_tolerance > 0; }
    // A receiver's record of the first pass: the count of its checks, then per check these
    // fields (weighted sums over its visible values, and where it lies), as many as checks_of
    // gives it (a book's face 16 where the floor has 48: records of error_checks each held
    // 3.5 kB a surface, most of the estimate's memory on a large interior).
    enum CheckField { Fit, CoarseFit, Integration, Radiance, Values, U, V, Weight, Visible, FineFit, PhaseFit, kFields };
    static_assert(kFields == kCheckFields);
    // The estimated receivers' checks (checks_of each) as a running count, made once the result
    // is: receiver k's record starts at k + kCheckFields * first(k) of all receivers' records,
    // its input errors at first(k).
    const RunningCount& checks() {
        if (!checks_) {
            const std::vector<Receiver>& result = estimated();
            checks_.emplace(result.size(), [&](size_t k) { return checks_of(result[k]); });
        }
        return *checks_;
    }
    size_t record_at(size_t k) { return k + size_t(kCheckFields) * checks().first(k); }
    size_t checks_in(size_t k) { return checks().first(k + 1) - checks().first(k); }
    // Every other check measures the input's error, every fourth also gathers at doubled
    // integration nodes (four times the rays): spread over the surface as all of them are.
    static bool input_check(size_t i) { return i % 2 == 0; }
    static bool fine_check(size_t i) { return i % 4 == 0; }
    size_t checks_of(const Receiver& r) const { return error_checks_of(r.nodes.size(), settings); }
    std::vector<size_t> checks_of_all() {
        std::vector<size_t> n;
        for (size_t k = 0; k < estimated().size(); ++k) n.push_back(checks_in(k));
        return n;
    }
    // The integration nodes per axis of the gather that made a receiver's result.
    double density_at(const Receiver& q) const { return settings.final_gather ? final_density(scene, settings, q.surface) : 1.0; }

    // Behind the back of an opaque surface (not a pane) that no light reaches (its back side
    // not solved): inside a closed object, seen by no viewer. A lit back (a plane leaning on
    // a wall, two-sided) is seen: the wedge under it was left out of the checks, where its
    // splines err most (the validation's open box: the left wall estimated at 0.29 of its error).
    bool behind(const Vec3& p, const Vec3& normal, const Vec3& d, size_t& counted) const {
        const SurfaceHit hit = caster.closest_hit(caster.spawn(p, normal, d), d);
        ++counted;
        if (hit.surface < 0 || dot(hit.frame.z, d) <= 0) return false;
        const Material& m = scene[hit.surface].material;
        if (m.thin_glass || (m.bsdf && m.bsdf->transmits())) return false;
        const Receiver* h = receiver_of[hit.surface];
        return !(h && h->solves(1));
    }
    // Which (side, direction) values of a check count, bit side * kCheckDirections + a: only
    // what a viewer can see. A value along a direction whose ray meets the back of an opaque
    // surface (the floor under a box, the ceiling behind a lamp) lies inside a closed object.
    uint16_t visible_values(const Receiver& r, const SurfacePoint& p, const std::vector<Vec3>& dirs, size_t& counted) const {
        static_assert(2 * kCheckDirections <= 16, "a check's values are bits of a uint16_t");
        const std::array<bool, 2> seen = sides_seen(r);
        uint16_t bits = 0;
        for (int side = 0; side < 2; ++side)
            for (size_t a = 0; a < dirs.size() && seen[side]; ++a) {
                const Vec3 d = p.frame.to_world(side == 0 ? dirs[a] : Vec3{dirs[a].x, dirs[a].y, -dirs[a].z});
                if (!behind(p.p, p.frame.z, d, counted)) bits |= uint16_t(1u << (side * dirs.size() + a));
            }
        return bits;
    }
    // The weight in the surface's means of value x of a check of weight `weight` (0 where not
    // seen), and its index among the nd values per side that values_of gives: a diffuse value
    // counts by its share of visible directions.
    static double value_weight(const Receiver& r, double weight, uint16_t visible, size_t x) {
        if (!(visible >> x & 1u)) return 0.0;
        const bool diffuse = r.kind == Representation::Diffuse && !r.partner;
        return weight * (diffuse ? 1.0 / kCheckDirections : 1.0);
    }
    static size_t value_index(size_t x, size_t nd) { return (x / kCheckDirections) * nd + (nd == 1 ? 0 : x % kCheckDirections); }
    // The surface's light is the sum of its parts (D and S of (38), a tint's pair), compared
    // at (side, direction) values; a diffuse part has one per side. `gathered(q, part, out)`
    // adds a part's light at the probe q into `out` (side-major, then direction).
    template <class Gathered>
    static std::vector<Vec3> values_of(const Receiver& r, double u, double v, const std::vector<Vec3>& dirs, Gathered&& gathered) {
        const size_t nd = r.kind == Representation::Diffuse && !r.partner ? 1 : dirs.size();
        std::vector<Vec3> values(2 * nd, Vec3{0, 0, 0}), out;
        const std::array<bool, 2> seen = sides_seen(r);
        for (const Receiver* part = &r; part; part = part == &r ? part->partner : nullptr) {
            const Receiver q = probe_of(*part, u, v, dirs);
            out.assign(q.sides * q.per_node, {0, 0, 0});
            gathered(q, *part, out);
            for (int side = 0; side < q.sides; ++side)
                for (size_t a = 0; a < nd && seen[side]; ++a) values[side * nd + a] += out[side * q.per_node + (q.per_node == 1 ? 0 : a)];
        }
        return values;
    }
    static double squared(const Vec3& e) { return dot(e, e) / 3; }

    // body(k, i, receiver, rays) for check i of each receiver begin + k of estimated() but the
    // partners, on all threads: it adds the rays it casts to `rays`, as this adds all to `rays`.
    template <class Body>
    void for_each_check(size_t begin, size_t end, Progress& progress, size_t& rays, Body&& body) {
        const std::vector<Receiver>& result = estimated();
        const RunningCount& count = checks();
        const size_t first = count.first(begin);
        std::atomic<size_t> counted{0};
        parallel_for(count.first(end) - first, 1, settings.threads, [&](size_t b, size_t e) {
            size_t local = 0;
            count.walk(first + b, first + e, [&](size_t k, size_t i) {
                if (!result[k].is_partner) body(k - begin, i, result[k], local);
            });
            counted += local;
            progress.advance(e - b);
        }, progress.cancel_flag());
        progress.throw_if_cancelled();
        rays += counted;
    }

    // The first pass for receivers [begin, end) of estimated(): their records (each
    // 1 + kCheckFields * checks_of). At each check the spline (and the coarse one) against the last phase's gather, and
    // the gather at doubled nodes against the phase's.
    std::vector<double> estimate_checks(size_t begin, size_t end, Progress& progress, size_t& rays) {
        if (!fine_gather) fine_gather.emplace(lit_scene, fine_settings, caster);
        const std::vector<Receiver>& result = estimated();
        // Receiver begin + k's record in these receivers' records (checks() made here, before
        // the threads read it).
        const size_t first = record_at(begin);
        auto at = [&](size_t k) { return record_at(begin + k) - first; };
        // The others' splines a gather read err (the contact shadows blurred over a coarse grid),
        // and that error enters each surface's light through its gather, where its own splines
        // cannot show it: it is measured from the others' coarse and final splines (estimate_inputs).
        const std::vector<const Receiver*> result_of = index_by_surface(scene, result);
        // A regather read the previous final splines, close to the result's: its gather is
        // checked from the result's.
        const bool regathered = settings.final_gather && settings.final_passes > 1;
        const std::vector<const Receiver*>& last_of = regathered ? result_of : receiver_of;
        std::vector<double> records(at(end - begin), 0.0);
        std::vector<std::vector<CheckPoint>> points(end - begin);
        std::atomic<size_t> candidate_rays{0};
        parallel_for(end - begin, 1, settings.threads, [&](size_t b, size_t e) {
            size_t local = 0;
            for (size_t k = b; k < e; ++k) {
                const Receiver& r = result[begin + k];
                if (r.is_partner) continue;
                const Surface& surface = *scene[r.surface].surface;
                const double side = r.solves(0) || !r.solves(1) ? 1.0 : -1.0;
                points[k] = check_points(r, checks_of(r), size_t(settings.error_checks_seed), [&](double u, double v) {
                    const SurfacePoint p = surface.evaluate(u, v);
                    return behind(p.p, p.frame.z, p.frame.z * side, local);
                }, [&](double u, double v, int s) { return gather->distant_light_at(r, u, v, s, local); });
                records[at(k)] = double(points[k].size());
            }
            candidate_rays += local;
        }, progress.cancel_flag());
        progress.throw_if_cancelled();
        rays += candidate_rays;
        auto gather_from = [&](const Gatherer& by, const std::vector<const Receiver*>& from, size_t& counted) {
            return [this, &by, &from, &counted](const Receiver& q, const Receiver&, std::vector<Vec3>& out) {
                std::vector<Vec3> direct(out.size());
                by.direct(q, 0, direct.data(), counted);
                by.indirect(q, 0, from, &Receiver::Le, density_at(q), true, out.data(), counted);
                for (size_t k = 0; k < out.size(); ++k) out[k] += direct[k];
            };
        };
        // The splines `which_of` (the finals, or the coarse ones) at the check: a part's own splines.
        auto spline_at = [&](const std::vector<const Receiver*>& which_of, double u, double v) {
            return [&which_of, u, v](const Receiver& q, const Receiver& part, std::vector<Vec3>& out) {
                const Receiver* whole = which_of[part.surface];
                const Receiver* own = part.is_partner ? (whole ? whole->partner : nullptr) : whole;
                if (!own) return;
                for (int side = 0; side < q.sides; ++side)
                    for (size_t b = 0; b < q.per_node; ++b) out[side * q.per_node + b] += own->own_radiance(&Receiver::Le, u, v, q.outgoing(side, b));
            };
        };
        for_each_check(begin, end, progress, rays, [&](size_t k, size_t i, const Receiver& r, size_t& local) {
            if (i >= points[k].size()) return;
            const auto [u, v, weight] = points[k][i];
            const SurfacePoint p = scene[r.surface].surface->evaluate(u, v);
            const std::vector<Vec3> views = check_directions(i), dirs = value_directions(r, views, u, v);
            const std::vector<Vec3> G = values_of(r, u, v, dirs, gather_from(*gather, last_of, local));
            const std::vector<Vec3> S = values_of(r, u, v, dirs, spline_at(result_of, u, v));
            std::vector<Vec3> C, F, I;
            if (settings.final_gather) C = values_of(r, u, v, dirs, spline_at(receiver_of, u, v));
            if (fine_check(i)) {
                F = values_of(r, u, v, dirs, gather_from(*fine_gather, result_of, local));
                // The doubled nodes' baseline: the gather at the phase's nodes of the same splines.
                I = regathered || !settings.final_gather ? G : values_of(r, u, v, dirs, gather_from(*gather, result_of, local));
            }
            const uint16_t visible = visible_values(r, p, views, local);
            double* c = &records[at(k) + 1 + i * kCheckFields];
            c[U] = u, c[V] = v, c[Weight] = weight, c[Visible] = visible;
            for (size_t x = 0; x < 2 * dirs.size(); ++x) {
                const double share = value_weight(r, weight, visible, x);
                if (share == 0) continue;
                const size_t j = value_index(x, S.size() / 2);
                c[Fit] += share * squared(S[j] - G[j]);
                if (!C.empty()) c[CoarseFit] += share * squared(C[j] - G[j]);
                if (fine_check(i)) {
                    c[Integration] += share * squared(F[j] - I[j]);
                    c[FineFit] += share * squared(S[j] - F[j]);
                    c[PhaseFit] += share * squared(S[j] - I[j]);
                }
                c[Radiance] += share * (G[j].x + G[j].y + G[j].z) / 3;
                c[Values] += share;
            }
        });
        return records;
    }

    // Per scene surface, how its finals' difference from its coarse splines scales to the
    // error of what a gather read from it, over its parameter square (InputScales::kCells per axis,
    // bilinear between the cells' centres; InputScales), from the first pass's records of all
    // receivers. A fraction r of the coarse error remains (measured at its checks, against the
    // gather), so what the coarse splines err is the difference between the two over 1 - r,
    // what the finals err that over 1/r - 1 (Richardson, with the order measured rather than
    // assumed). r is taken as at most 1/2 (first order, as at a contact shadow): nearer 1 the
    // difference is noise. r is local, a Gaussian-weighted ratio over the checks around each
    // cell: where a discontinuity's knots follow a contact line the finals are close to exact
    // and their difference from the blurred coarse splines is large, while far from it both err
    // alike (leaning_board's box, beside the floor's contact lines, was estimated at 5 times
    // its error with one r per surface).
    std::vector<double> input_scales(const std::vector<double>& records) {
        const std::vector<Receiver>& result = estimated();
        const bool regathered = settings.final_gather && settings.final_passes > 1;
        constexpr size_t cells = InputScales::values_for(1);
        constexpr double sigma = 1.0 / InputScales::kCells;
        std::vector<double> scale(InputScales::values_for(scene.size()), 1.0);
        for (size_t k = 0; k < result.size(); ++k) {
            if (result[k].is_partner) continue;
            for (size_t cell = 0; cell < cells; ++cell) {
                const double cu = (cell % InputScales::kCells + 0.5) / InputScales::kCells;
                const double cv = (cell / InputScales::kCells + 0.5) / InputScales::kCells;
                double fine = 0, coarse = 0;
                for (size_t i = 0; i < checks_in(k); ++i) {
                    const double* c = &records[record_at(k) + 1 + i * kCheckFields];
                    const double du = c[U] - cu, dv = c[V] - cv;
                    const double w = std::exp(-(du * du + dv * dv) / (2 * sigma * sigma));
                    fine += w * c[Fit], coarse += w * c[CoarseFit];
                }
                const double r = coarse > 0 ? std::min(std::sqrt(fine / coarse), 0.5) : 0.5;
                scale[result[k].surface * cells + cell] = regathered ? r / (1 - r) : 1 / (1 - r);
            }
        }
        return scale;
    }

    // The second pass (with a final gather) for receivers [begin, end) of estimated(): per
    // check (checks_of each, 0 where none), the input's error: the others' finals less their coarse
    // splines, gathered, each surface's weighted by `scale` (input_scales). `records`: the first
    // pass's of all receivers, which say where the checks lie and what they see.
    std::vector<double> estimate_inputs(size_t begin, size_t end, const double* scale, const double* records,
                                        Progress& progress, size_t& rays) {
        const std::vector<Receiver>& result = estimated();
        const std::vector<const Receiver*> result_of = index_by_surface(scene, result);
        const InputScales input_scale(scale, scene.size());
        const RunningCount& count = checks();
        std::vector<double> inputs(count.first(end) - count.first(begin), 0.0);
        for_each_check(begin, end, progress, rays, [&](size_t k, size_t i, const Receiver& r, size_t& local) {
            const size_t record = record_at(begin + k);
            const double* c = &records[record + 1 + i * kCheckFields];
            if (i >= size_t(records[record]) || !input_check(i)) return;
            const std::vector<Vec3> dirs = value_directions(r, check_directions(i), c[U], c[V]);
            const std::vector<Vec3> E = values_of(r, c[U], c[V], dirs, [&](const Receiver& q, const Receiver&, std::vector<Vec3>& out) {
                gather->indirect_change(q, 0, result_of, receiver_of, density_at(q), 0, out.data(), local, &input_scale);
            });
            for (size_t x = 0; x < 2 * dirs.size(); ++x)
                inputs[count.first(begin + k) - count.first(begin) + i] += value_weight(r, c[Weight], uint16_t(c[Visible]), x) * squared(E[value_index(x, E.size() / 2)]);
        });
        return inputs;
    }

    // Each receiver's estimate from the first pass's records and the second's input errors
    // (empty without a final gather) of all receivers, and `tail`, per receiver, the bounces'
    // radiance still missing. `parts`: per receiver, the four parts added in quadrature
    // (SurfaceReport::error_parts).
    std::vector<double> estimate_errors(const std::vector<double>& records, const std::vector<double>& inputs,
                                        const std::vector<double>& tail, std::vector<std::array<double, 4>>& parts) {
        const std::vector<Receiver>& result = estimated();
        std::vector<double> errors(result.size(), std::nan(""));
        for (size_t k = 0; k < result.size(); ++k) {
            if (result[k].is_partner) continue;
            // Sums over the checks: all of them, the input's, the doubled nodes'.
            double fit = 0, radiance = 0, values = 0, input = 0, input_values = 0, integration = 0, fine_values = 0;
            double fine_fit = 0, phase_fit = 0;
            for (size_t i = 0; i < checks_in(k); ++i) {
                const double* c = &records[record_at(k) + 1 + i * kCheckFields];
                fit += c[Fit], radiance += c[Radiance], values += c[Values];
                if (input_check(i)) input += inputs.empty() ? 0.0 : inputs[checks().first(k) + i], input_values += c[Values];
                if (fine_check(i)) integration += c[Integration], fine_values += c[Values], fine_fit += c[FineFit], phase_fit += c[PhaseFit];
            }
            // Emission leaves the front side (and the back where two-sided) on top of the spline.
            const Material& m = scene[result[k].surface].material;
            // Seen by no viewer (every check's directions meet the back of an opaque surface: a
            // face pressed against another): no estimate, rather than a 0 that would pass for an
            // exact one and lower its object's.
            if (!(values > 0)) continue;
            const double mean = radiance / values + (m.emission.x + m.emission.y + m.emission.z) / 3;
            if (!(mean > 0)) {
                errors[k] = 0;  // seen, and no light: nothing to be wrong about
                continue;
            }
            auto rms = [&](double sum, double weight) { return weight > 0 ? std::sqrt(sum / weight) / mean : 0.0; };
            // The spline's own error. Against the phase's gather at every check it counts that
            // gather's integration error too, which the spline, fitted to many such gathers, has
            // smoothed in part; against the doubled nodes' gather it does not, but there are a
            // quarter as many of those checks. So: the first, scaled by how the two differ where
            // both are known (their ratio at the same checks varies less than either). Adding
            // the integration error to the first counted it twice where it is noise-like: the
            // Cornell boxes' ceilings and walls were estimated at 1.3-1.5 times their error as
            // measured against Mitsuba with 1,536 checks, 0.9-1.1 this way.
            const double own = rms(fit, values) * (phase_fit > 0 ? std::sqrt(fine_fit / phase_fit) : 1.0);
            // Of which the integration, at most a gather's (the doubled integration nodes'
            // difference taken as the error itself: the rules converge faster where smooth), the
            // rest the fit.
            const double e_int = std::min(rms(integration, fine_values), own);
            const double e_fit = std::sqrt(std::max(own * own - e_int * e_int, 0.0));
            const double e_input = rms(input, input_values);
            const double e_tail = std::min(tail[k], 1.0);  // not converged: as large as the radiance
            errors[k] = std::sqrt(own * own + e_input * e_input + e_tail * e_tail);
            parts[k] = {e_fit, e_input, e_int, e_tail};
        }
        return errors;
    }

    // A pass of the estimate for receivers [begin, end) of estimated() on a worker: `input`
    // holds the estimated splines' Le, then with a final gather the coarse Le, then for the
    // second pass each scene surface's input scale and the first pass's records of all receivers.
    std::vector<double> estimate_step(SolveSteps::Phase phase, size_t begin, size_t end, const SolveSteps::Input& input,
                                      const std::vector<size_t>& settled, Progress& progress, size_t& rays, bool unpacked) {
        if (!settings.estimate_error) throw std::invalid_argument("solve step: the settings estimate no error");
        if (phase == SolveSteps::Phase::EstimateInput && !settings.final_gather)
            throw std::invalid_argument("solve step: without a final gather the error estimate has no input pass");
        if (!settled.empty()) throw std::invalid_argument("solve step: only a bounce's receivers settle");
        const size_t coarse_size = settings.final_gather ? packed_size(receivers, 0, receivers.size(), &Receiver::Le) : 0;
        // The input pass's input ends with the checks pass's records of all receivers and their
        // count (the records' length follows from the finals, which may be planned from the
        // coarse Le before them).
        size_t extra = 0, records = 0;
        const size_t scales = InputScales::values_for(scene.size());
        if (phase == SolveSteps::Phase::EstimateInput) {
            const double count = input.size ? input.data[input.size - 1] : -1.0;
            if (!(count >= 0 && count + 1 + double(scales) <= double(input.size) && count == std::floor(count)))
                throw std::invalid_argument("solve step: the error estimate's input pass ends with the count of its records, given " +
                                            std::to_string(count));
            records = size_t(count);
            extra = scales + records + 1;
        }
        finals_from_input(input, extra, "the error estimate's pass", progress);
        std::vector<Receiver>& result = estimated();
        if (begin > end || end > result.size())
            throw std::invalid_argument("solve step: receivers " + std::to_string(begin) + " to " + std::to_string(end) +
                                        " out of " + std::to_string(result.size()));
        const size_t result_size = packed_size(result, 0, result.size(), &Receiver::Le);
        if (phase == SolveSteps::Phase::EstimateInput && records != record_at(result.size()))
            throw std::invalid_argument("solve step: the error estimate's checks have " + std::to_string(record_at(result.size())) +
                                        " record values, given " + std::to_string(records));
        if (input.size != result_size + coarse_size + extra)
            throw std::invalid_argument("solve step: the error estimate's pass reads " + std::to_string(result_size + coarse_size + extra) +
                                        " values, given " + std::to_string(input.size));
        if (!unpacked) {
            unpack(input.data, result_size, result, 0, result.size(), &Receiver::Le);
            if (settings.final_gather) unpack(input.data + result_size, coarse_size, receivers, 0, receivers.size(), &Receiver::Le);
        }
        if (phase == SolveSteps::Phase::EstimateChecks) return estimate_checks(begin, end, progress, rays);
        const double* scale = input.data + result_size + coarse_size;
        return estimate_inputs(begin, end, scale, scale + scales, progress, rays);
    }

    // The rows of the transport operator of receivers [begin, end) that use them, cast once.
    void build_rows(size_t begin, size_t end, Progress& progress, size_t& rays) {
        std::vector<std::pair<int, int>> items;
        for (size_t k = begin; k < end; ++k) {
            if (!uses_rows(receivers[k]) || rows_done[k]) continue;
            // Row side * nodes + j: node j of a side.
            const size_t nodes = receivers[k].nodes.size();
            rows[k].assign(receivers[k].sides * nodes, {});
            for (int side = 0; side < receivers[k].sides; ++side)
                for (size_t j = 0; j < nodes && receivers[k].solves(side); ++j) items.emplace_back(int(k), int(side * nodes + j));
        }
        std::atomic<size_t> row_rays{0};
        parallel_for(items.size(), 4, settings.threads, [&](size_t b, size_t e) {
            size_t local = 0;
            for (size_t w = b; w < e; ++w) {
                const auto [k, row] = items[w];
                const size_t nodes = receivers[k].nodes.size();
                gather->transport_row(receivers[k], int(row / nodes), row % nodes, receiver_of, rows[k][row], local);
            }
            row_rays += local;
            progress.advance(e - b);
        }, progress.cancel_flag());
        progress.throw_if_cancelled();
        rays += row_rays;
        for (size_t k = begin; k < end; ++k) rows_done[k] = 1;
    }
};

SolveSteps::SolveSteps(const Scene& scene, const SolverSettings& settings, Progress& progress,
                       const std::vector<SurfaceSides>* sides)
    : state_(std::make_unique<State>(scene, settings, progress, sides)) {}

SolveSteps::~SolveSteps() = default;

const std::vector<SurfaceSides>& SolveSteps::sides() const { return state_->sides; }

namespace {
// A late bounce's integration nodes per axis, against a bounce's (SolverSettings::late_bounces_after).
constexpr double kLateBounceDensity = 0.5;
// A regather's integration nodes per axis, against the final gather's: it gathers a correction,
// at full density where it meets a lobe narrower than GGX alpha 0.3's (Bsdf::lobe_width).
constexpr double kRegatherDensity = 0.5, kSharpLobe = 2 * 0.3;
// The final gather and a regather gather into the finer receivers, the others into the coarse ones.
bool on_finals(SolveSteps::Phase phase) {
    return phase == SolveSteps::Phase::Final || phase == SolveSteps::Phase::Regather;
}
// The error estimate's two passes check the estimated splines (the finals, or the coarse ones).
bool on_estimate(SolveSteps::Phase phase) {
    return phase == SolveSteps::Phase::EstimateChecks || phase == SolveSteps::Phase::EstimateInput;
}
}  // namespace

std::vector<size_t> SolveSteps::nodes(Phase phase, Progress& progress) {
    if (on_estimate(phase)) {
        state_->build_finals(progress);
        return state_->checks_of_all();
    }
    if (!on_finals(phase)) return nodes_of(state_->receivers);
    state_->build_finals(progress);
    return nodes_of(state_->finals);
}

std::vector<double> SolveSteps::gather(Phase phase, size_t begin, size_t end, Input input, Progress& progress, size_t& rays,
                                       const std::vector<size_t>& settled, bool unpacked) {
    return gather_from(phase, begin, end, &input, progress, rays, settled, unpacked);
}

std::vector<double> SolveSteps::gather_from(Phase phase, size_t begin, size_t end, const Input* input, Progress& progress,
                                            size_t& rays, const std::vector<size_t>& settled, bool unpacked) {
    State& s = *state_;
    if (on_estimate(phase)) return s.estimate_step(phase, begin, end, *input, settled, progress, rays, unpacked);
    const bool fine = on_finals(phase);
    if (fine && !s.settings.final_gather) throw std::invalid_argument("solve step: the settings have no final gather");
    if (phase == Phase::Regather && s.settings.final_passes < 2)
        throw std::invalid_argument("solve step: the settings have one final pass, no regather");
    if (fine && input) s.finals_from_input(*input, 0, phase == Phase::Final ? "a final gather" : "a regather", progress);  // both read the coarse Le last
    if (fine) s.build_finals(progress);
    std::vector<Receiver>& targets = fine ? s.finals : s.receivers;
    if (begin > end || end > targets.size())
        throw std::invalid_argument("solve step: receivers " + std::to_string(begin) + " to " + std::to_string(end) +
                                    " out of " + std::to_string(targets.size()));
    const Gatherer& gather = *s.gather;
    const Scene& scene = s.scene;
    const SolverSettings& settings = s.settings;
    const bool bounce = phase == Phase::Bounce || phase == Phase::LateBounce;
    if (!settled.empty() && !bounce) throw std::invalid_argument("solve step: only a bounce's receivers settle");
    std::vector<uint8_t> skip(settled.empty() ? 0 : targets.size(), 0);
    for (size_t k : settled) {
        if (k < begin || k >= end)
            throw std::invalid_argument("solve step: settled receiver " + std::to_string(k) + " is not among receivers " +
                                        std::to_string(begin) + " to " + std::to_string(end));
        skip[k] = 1;
    }
    if (phase == Phase::Direct) {
        // Gather from every emitter (and the world) into L.
        // (Receivers a final gather will read carry a sun's light as means over their nodes'
        // supports where its edges cross them, marked for gather_all's sharpening; without one
        // they are the result, seen, and keep point samples.)
        const bool means = settings.final_gather && settings.distant_support_means;
        if (means)
            for (size_t k = begin; k < end; ++k) targets[k].support_means.assign(targets[k].nodes.size(), 0);
        rays += gather_all(targets, begin, end, &Receiver::L, settings, progress, [&](const Receiver& r, size_t j, Vec3* out, size_t& n) {
            if (means) gather.direct_over_support(r, j, s.receiver_of, out, n);
            else gather.direct(r, j, out, n);
            if (!scene.has_world()) return;
            std::vector<Vec3> world(r.sides * r.per_node);
            gather.world(r, j, world.data(), n);
            for (size_t k = 0; k < world.size(); ++k) out[k] += world[k];
        });
        return pack(targets, begin, end, &Receiver::L);
    }
    if (bounce) {
        // Gather the incremental radiance L of all surfaces into Ltmp (but settled receivers').
        const double density = phase == Phase::LateBounce ? kLateBounceDensity : 1.0;
        if (input && !unpacked) unpack(input->data, input->size, s.receivers, 0, s.receivers.size(), &Receiver::L);
        s.build_rows(begin, end, progress, rays);
        rays += gather_all(targets, begin, end, &Receiver::Ltmp, settings, progress, [&](const Receiver& r, size_t j, Vec3* out, size_t& n) {
            const size_t k = size_t(r.index);
            if (!s.uses_rows(r)) {
                gather.indirect(r, j, s.receiver_of, &Receiver::L, density, false, out, n);
                return;
            }
            for (int side = 0; side < r.sides; ++side) {
                if (!r.solves(side)) continue;
                Vec3 sum{0, 0, 0};
                for (const TransportTerm& t : s.rows[k][side * r.nodes.size() + j]) {
                    const double* c = &s.receivers[t.receiver].L[t.side].coeffs()[3 * size_t(t.index)];
                    sum += Vec3{c[0], c[1], c[2]} * double(t.weight);
                }
                out[side] = r.bsdf->eval({0, 0, 1}, {0, 0, 1}) * sum;
            }
        }, skip);
        return pack(targets, begin, end, &Receiver::Ltmp);
    }
    // Final gather: finer receivers gather direct light from the emitters, and indirect light
    // from the cumulative radiance Le of the others (emitters count as non-emissive there) with
    // the world's light along the same rays: the coarse receivers' Le.
    if (phase == Phase::Final) {
        if (input && !unpacked) unpack(input->data, input->size, s.receivers, 0, s.receivers.size(), &Receiver::Le);
        rays += gather_all(targets, begin, end, &Receiver::Le, settings, progress, [&](const Receiver& r, size_t j, Vec3* out, size_t& n) {
            std::vector<Vec3> direct(r.sides * r.per_node);
            gather.direct(r, j, direct.data(), n);
            gather.indirect(r, j, s.receiver_of, &Receiver::Le, final_density(scene, settings, r.surface), true, out, n);
            for (size_t k = 0; k < direct.size(); ++k) out[k] += direct[k];
        });
        // The local solve reads the light where it is (no packed copy of the finals beside it).
        return input ? pack(targets, begin, end, &Receiver::Le) : std::vector<double>();
    }
    // The regather: the final gather read the coarse splines; what reading the finer ones adds
    // is the gathered change between them (fine less coarse: a narrow shadow the coarse grid
    // blurred), a small part of the light, gathered into L (held only meanwhile: the others read
    // Le) and added to the final gather's Le, with kRegatherDensity of the nodes per axis; at
    // full density at a node whose rays meet a surface glossier than GGX alpha 0.3 (the lobe
    // kSharpLobe): its reflections' change is sharp (at half density the diffuse walls before
    // a near-mirror wall lost 0.5 points of accuracy).
    if (input && !unpacked) {
        const size_t fine_size = packed_size(s.finals, 0, s.finals.size(), &Receiver::Le);
        const size_t coarse_size = packed_size(s.receivers, 0, s.receivers.size(), &Receiver::Le);
        if (input->size != fine_size + coarse_size)
            throw std::invalid_argument("solve step: a regather reads the finals' Le (" + std::to_string(fine_size) +
                                        " coefficients) and the coarse Le (" + std::to_string(coarse_size) + "), given " +
                                        std::to_string(input->size));
        unpack(input->data, fine_size, s.finals, 0, s.finals.size(), &Receiver::Le);
        unpack(input->data + fine_size, coarse_size, s.receivers, 0, s.receivers.size(), &Receiver::Le);
    }
    // The correction in float32: rounding it costs 6e-8 of a small part of the light, and it is
    // the largest set while it is held (at 1,000 objects 115 MB in float64, beside the finals).
    for (size_t k = begin; k < end; ++k) {
        Receiver& r = targets[k];
        r.L.clear();
        for (const TensorSpline& le : r.Le) r.L.emplace_back(le.layout(), Precision::Float32);
    }
    rays += gather_all(targets, begin, end, &Receiver::L, settings, progress, [&](const Receiver& r, size_t j, Vec3* out, size_t& n) {
        const double full = final_density(scene, settings, r.surface);
        if (gather.indirect_change(r, j, s.final_of, s.receiver_of, kRegatherDensity * full, kSharpLobe, out, n))
            gather.indirect_change(r, j, s.final_of, s.receiver_of, full, kSharpLobe, out, n);
    });
    // The correction alone: the solve adds it to the first final gather's Le (the local solve
    // from L, where it is: no packed copy of the finals beside the three sets it holds).
    if (!input) return {};
    std::vector<double> out = pack(targets, begin, end, &Receiver::L);
    for (size_t k = begin; k < end; ++k) std::vector<TensorSpline>().swap(targets[k].L);
    return out;
}

Solution solve(const Scene& scene, const SolverSettings& settings, Progress& progress, const std::vector<SurfaceSides>* sides) {
    return SolveSteps(scene, settings, progress, sides).solve(progress);
}

Solution SolveSteps::solve(Progress& progress, const Runner& run) {
    State& st = *state_;
    if (st.solved) throw std::logic_error("solve steps: solve() runs once (the solution takes the splines)");
    st.solved = true;
    const Scene& scene = st.scene;
    const SolverSettings& settings = st.settings;
    const int stages = st.stages;
    std::vector<Receiver>& receivers = st.receivers;
    const size_t all = receivers.size();
    Solution solution;
    solution.stats.bytes = st.bytes;
    size_t rays = 0;
    // One phase's gather for all receivers: here, from the splines that hold its input, or
    // wherever `run` sends its groups, with `input()` packed. `settled`: a bounce's receivers that
    // do not gather (0 nodes for `run`).
    auto phase = [&](Phase p, const auto& input, const std::vector<size_t>& settled = {}) {
        std::vector<size_t> n = nodes(p, progress);
        const size_t before = rays;
        std::vector<double> out;
        if (!run) {
            out = gather_from(p, 0, n.size(), nullptr, progress, rays, settled);
        } else {
            for (size_t k : settled) n[k] = 0;
            out = run(p, input(), n, rays);
            progress.throw_if_cancelled();
        }
        if (p == Phase::Final || p == Phase::Regather) solution.stats.final_rays += rays - before;
        return out;
    };

    // Direct lighting phase: gather from every emitter (and the world) into S.L; S.Le <- S.L.
    const auto t0 = std::chrono::steady_clock::now();
    progress.begin_stage("direct light", 1, stages, node_count(receivers));
    unpack(phase(Phase::Direct, [] { return std::vector<double>(); }), receivers, 0, all, &Receiver::L);
    for (auto& r : receivers)
        for (int side = 0; side < r.sides; ++side) r.Le[side].coeffs() = r.L[side].coeffs();
    solution.stats.seconds_direct = seconds_since(t0);

    // Indirect phase: gather the incremental radiance L of all surfaces into Ltmp, then
    // Le += Ltmp, L <- Ltmp, until what is still missing is small.
    const auto t1 = std::chrono::steady_clock::now();
    BounceConvergence convergence(receivers);
    bool converged = false;
    if (st.ff_stage && !run) {
        // Here the rows are cast in a stage of their own; a runner's steps cast them with their group's first bounce.
        progress.begin_stage("form factors", 2, stages, node_count(receivers));
        st.build_rows(0, all, progress, rays);
        for (const auto& per_receiver : st.rows)
            for (const auto& row : per_receiver) solution.stats.transport_terms += row.size();
    }
    std::vector<uint8_t> skip(all, 0);
    for (int bounce = 0; bounce < settings.max_bounces; ++bounce) {
        // Settled receivers (SolverSettings::settle_factor) do not gather: their increment is
        // rho2 times the one two bounces before, which Ltmp still holds (L holds the last).
        std::vector<size_t> settled;
        size_t gathering = 0;
        for (size_t k = 0; k < all; ++k) {
            skip[k] = settings.settle_factor > 0 && convergence.settles(receivers[k], settings.settle_factor * settings.tolerance);
            if (skip[k]) settled.push_back(k), solution.stats.settled_nodes += receivers[k].nodes.size();
            else gathering += receivers[k].nodes.size();
        }
        progress.begin_stage("indirect bounce " + std::to_string(bounce + 1), 2 + st.ff_stage + bounce, stages, gathering);
        const bool late = settings.late_bounces_after > 0 && bounce >= settings.late_bounces_after;
        unpack(phase(late ? Phase::LateBounce : Phase::Bounce, [&] { return pack(receivers, 0, all, &Receiver::L); }, settled),
               receivers, 0, all, &Receiver::Ltmp, skip);
        for (size_t k : settled) {
            const std::array<double, 3> rho2 = convergence.decay(int(k));
            for (int side = 0; side < receivers[k].sides; ++side) {
                auto& c = receivers[k].Ltmp[side].coeffs();
                for (size_t i = 0; i < c.size(); ++i) c[i] *= rho2[i % 3];
            }
        }
        add_onto(receivers, 0, all, &Receiver::Le, &Receiver::Ltmp);
        for (auto& r : receivers)
            for (int side = 0; side < r.sides; ++side) std::swap(r.L[side], r.Ltmp[side]);  // receiver_of points at the receivers: still valid
        solution.stats.bounces = bounce + 1;
        const double error = convergence.update(receivers, settings.extrapolate, solution.stats.last_increment);
        solution.stats.estimated_error = error;
        if (error < settings.tolerance || solution.stats.last_increment == 0) {
            converged = true;
            break;
        }
    }
    if (settings.extrapolate && converged) {
        // The geometric tail over the bounces not taken, from the last two increments (L, and
        // the one before it, now in Ltmp).
        for (auto& r : receivers) {
            const std::array<double, 3> tail = convergence.tail(r.index);
            for (int side = 0; side < r.sides; ++side) {
                auto& le = r.Le[side].coeffs();
                const auto& l = r.L[side].coeffs();
                const auto& before = r.Ltmp[side].coeffs();
                for (size_t c = 0; c < le.size(); ++c) le[c] += tail[c % 3] * (l[c] + before[c]);
            }
        }
        solution.stats.extrapolated = true;
    }
    if (settings.final_gather) {
        // The final gather reads the coarse Le alone: the increments and the rows are done with.
        for (Receiver& r : receivers) std::vector<TensorSpline>().swap(r.L), std::vector<TensorSpline>().swap(r.Ltmp);
        std::vector<std::vector<std::vector<TransportTerm>>>().swap(st.rows);
    }
    solution.stats.seconds_indirect = seconds_since(t1);

    // Final gather (Algorithm 1's last phase), from the cumulative radiance Le.
    if (settings.final_gather) {
        const auto t2 = std::chrono::steady_clock::now();
        st.coarse_light = true;  // the bounces are done: the receivers hold it
        st.build_finals(progress);
        solution.stats.bytes = st.bytes;  // with the finals as planned from it
        const int corrections = correction_stages(settings);
        const int first_final = stages - settings.final_passes - corrections - (settings.estimate_error ? 1 : 0);
        progress.begin_stage("final gather", first_final, stages, node_count(st.finals));
        // The first final gather's light F_1: in the finals' Le here, packed from a runner. Each
        // regather adds its correction to F_1, which is kept packed only where a later one
        // needs it (more than two passes, or a runner); with two passes Le holds it meanwhile.
        std::vector<double> first = phase(Phase::Final, [&] { return pack(receivers, 0, all, &Receiver::Le); });
        // The coarse correction (SolverSettings::final_correction_bounces) from stage `stage` on:
        // the residual F_1 - C over the coarse nodes' cells into L, its bounces over the coarse
        // receivers (a late bounce's gather, here or by the runner) taken off their Le, which
        // then holds C - E. Returns C.
        auto lower_coarse_light = [&](int stage) {
            std::vector<std::vector<double>> kept;
            for (Receiver& r : receivers) {
                r.L.clear(), r.Ltmp.clear();
                for (const TensorSpline& le : r.Le) r.L.emplace_back(le.layout()), r.Ltmp.emplace_back(le.layout());
                for (const TensorSpline& le : r.Le) kept.push_back(le.coeffs());
            }
            progress.begin_stage("final gather 2: the coarse light's residual", stage, stages, node_count(receivers));
            gather_all(receivers, 0, all, &Receiver::L, settings, progress, [&](const Receiver& r, size_t j, Vec3* out, size_t&) {
                const Receiver* fine = st.final_of[r.surface];
                if (fine && r.is_partner) fine = fine->partner;
                if (!fine) return;
                // The residual's mean over the node's cell (halfway to its neighbours), not its
                // value at the node: it is sharp where the finals resolve what C blurs (a shadow's
                // edge), and the bounces carry its integral. A node moved off the grid (hidden)
                // takes its value there.
                const std::vector<double>&us = r.nodes.axis(0), &vs = r.nodes.axis(1);
                const size_t i = j / vs.size(), k = j % vs.size();
                const SpatialNode x = r.nodes[j];
                const bool moved = x.u != us[i] || x.v != vs[k];
                auto cell = [](const std::vector<double>& t, size_t i, double& lo, double& hi) {
                    lo = i > 0 ? 0.5 * (t[i - 1] + t[i]) : t[i], hi = i + 1 < t.size() ? 0.5 * (t[i] + t[i + 1]) : t[i];
                };
                double u0, u1, v0, v1;
                cell(us, i, u0, u1), cell(vs, k, v0, v1);
                const int m = moved ? 1 : kResidualSamples;
                for (int side = 0; side < r.sides; ++side)
                    for (size_t a = 0; a < r.per_node && r.solves(side); ++a) {
                        const Vec3 d = r.outgoing(side, a);
                        Vec3 sum{0, 0, 0};
                        for (int p = 0; p < m; ++p)
                            for (int q = 0; q < m; ++q) {
                                const double u = moved ? x.u : u0 + (u1 - u0) * (p + 0.5) / m;
                                const double v = moved ? x.v : v0 + (v1 - v0) * (q + 0.5) / m;
                                sum += fine->own_radiance(&Receiver::Le, u, v, d) - r.own_radiance(&Receiver::Le, u, v, d);
                            }
                        out[side * r.per_node + a] = sum / double(m * m);
                    }
            });
            for (int bounce = 1; bounce <= correction_bounces(settings); ++bounce) {
                progress.begin_stage("final gather 2: the coarse light's error, bounce " + std::to_string(bounce), stage + bounce,
                                     stages, node_count(receivers));
                unpack(phase(Phase::LateBounce, [&] { return pack(receivers, 0, all, &Receiver::L); }), receivers, 0, all,
                       &Receiver::Ltmp);
                for (Receiver& r : receivers)
                    for (int side = 0; side < r.sides; ++side) {
                        auto& le = r.Le[side].coeffs();
                        const auto& e = r.Ltmp[side].coeffs();
                        for (size_t c = 0; c < le.size(); ++c) le[c] -= e[c];
                        std::swap(r.L[side], r.Ltmp[side]);
                    }
            }
            for (Receiver& r : receivers) std::vector<TensorSpline>().swap(r.L), std::vector<TensorSpline>().swap(r.Ltmp);
            return kept;
        };
        if (run) unpack(first, st.finals, 0, st.finals.size(), &Receiver::Le);
        else if (settings.final_passes > 2) first = pack(st.finals, 0, st.finals.size(), &Receiver::Le);
        // Each regather: the first final gather's light plus the change that reading the
        // latest finals instead of the coarse splines makes, F_k+1 = F_1 + G(F_k - C): a fixed
        // point iteration whose later passes carry the finer light a bounce further (into a
        // wedge lit through a narrow opening, which the coarse bounces blurred).
        for (int pass = 2; pass <= settings.final_passes; ++pass) {
            // C, kept while the coarse receivers hold C - E for the regather to read.
            std::vector<std::vector<double>> coarse_light;
            if (pass == 2 && corrections) coarse_light = lower_coarse_light(first_final + 1);
            progress.begin_stage("final gather " + std::to_string(pass), first_final - 1 + pass + corrections, stages,
                                 node_count(st.finals));
            std::vector<double> next = phase(Phase::Regather, [&] {
                std::vector<double> input;
                input.reserve(packed_size(st.finals, 0, st.finals.size(), &Receiver::Le) + packed_size(receivers, 0, all, &Receiver::Le));
                pack_onto(input, st.finals, 0, st.finals.size(), &Receiver::Le);
                pack_onto(input, receivers, 0, all, &Receiver::Le);
                return input;
            });
            if (!coarse_light.empty()) {
                size_t i = 0;
                for (Receiver& r : receivers)
                    for (TensorSpline& le : r.Le) le.coeffs() = std::move(coarse_light[i++]);
            }
            if (run) {
                for (size_t i = 0; i < next.size(); ++i) next[i] += first[i];
                unpack(next, st.finals, 0, st.finals.size(), &Receiver::Le);
                continue;
            }
            if (!first.empty()) unpack(first, st.finals, 0, st.finals.size(), &Receiver::Le);
            add_onto(st.finals, 0, st.finals.size(), &Receiver::Le, &Receiver::L);
            for (Receiver& r : st.finals) std::vector<TensorSpline>().swap(r.L);
        }
        solution.stats.seconds_final = seconds_since(t2);
    }
    std::vector<Receiver>& result = settings.final_gather ? st.finals : receivers;
    solution.stats.rays = rays + st.knot_rays;
    std::vector<double> errors(result.size(), std::nan(""));
    std::vector<std::array<double, 4>> error_parts(result.size(), SurfaceReport().error_parts);
    if (settings.estimate_error) {
        const auto t3 = std::chrono::steady_clock::now();
        const std::vector<size_t> checks = st.checks_of_all();
        const size_t all_checks = std::accumulate(checks.begin(), checks.end(), size_t(0));
        progress.begin_stage("error estimate", stages - 1, stages, (settings.final_gather ? 2 : 1) * all_checks);
        // Each pass here, or wherever `run` sends its groups, given the estimated splines (and the
        // coarse ones they were gathered from); the second pass also each surface's input scale
        // and the first pass's records.
        auto pass = [&](Phase p, const std::vector<double>& scale, const std::vector<double>& records) {
            size_t& counted = solution.stats.estimate_rays;
            if (!run)
                return p == Phase::EstimateChecks ? st.estimate_checks(0, result.size(), progress, counted)
                                                  : st.estimate_inputs(0, result.size(), scale.data(), records.data(), progress, counted);
            std::vector<double> input;
            input.reserve(packed_size(result, 0, result.size(), &Receiver::Le) +
                          (settings.final_gather ? packed_size(receivers, 0, all, &Receiver::Le) : 0) + scale.size() + records.size() + 1);
            pack_onto(input, result, 0, result.size(), &Receiver::Le);
            if (settings.final_gather) pack_onto(input, receivers, 0, all, &Receiver::Le);
            input.insert(input.end(), scale.begin(), scale.end());
            input.insert(input.end(), records.begin(), records.end());
            if (p == Phase::EstimateInput) input.push_back(double(records.size()));  // see estimate_step
            std::vector<double> out = run(p, input, checks, counted);
            progress.throw_if_cancelled();
            return out;
        };
        const std::vector<double> records = pass(Phase::EstimateChecks, {}, {});
        std::vector<double> inputs;
        if (settings.final_gather) inputs = pass(Phase::EstimateInput, st.input_scales(records), records);
        std::vector<double> tail(result.size(), 0.0);
        for (size_t k = 0; k < result.size(); ++k)
            if (const Receiver* coarse = st.receiver_of[result[k].surface]) tail[k] = convergence.error(coarse->index);
        errors = st.estimate_errors(records, inputs, tail, error_parts);
        solution.stats.seconds_estimate = seconds_since(t3);
    }
    const std::vector<Plan>& plans = st.plans;
    const std::vector<Plan>& final_plans = st.final_plans;

    // Outgoing radiance = emission (front side, and back side where two-sided; the same in every
    // direction: constants are reproduced exactly by the partition of unity) + the cumulative
    // reflected radiance.
    solution.radiance.resize(scene.size());
    // The coarse receivers are done with once the finals are the result: room for the finals in
    // float64, one receiver at a time.
    if (settings.final_gather) std::vector<Receiver>().swap(receivers);
    for (size_t k = 0; k < result.size(); ++k) {
        Receiver& r = result[k];
        if (r.is_partner) continue;  // consumed with its diffuse part
        auto to_float64 = [](Receiver& part) {
            for (TensorSpline& side : part.Le)
                if (side.precision() == Precision::Float32) side = side.with_precision(Precision::Float64);
        };
        to_float64(r);
        if (r.partner) to_float64(result[r.partner->index]);
        for (const Receiver* part = &r; part; part = part->is_partner ? nullptr : part->partner)
            for (int side = 0; side < part->sides; ++side)
                if (part->solves(side)) solution.stats.coefficients += part->Le[side].num_values() / 3;
        const Material& m = scene[r.surface].material;
        std::shared_ptr<const Texture> emission = m.emission_texture;
        if (!emission && (m.albedo_texture || m.specular_texture) && m.emits())  // kept out of the textured spline: one texel
            emission = std::make_shared<Texture>(1, 1, std::vector<float>{float(m.emission.x), float(m.emission.y), float(m.emission.z)},
                                                 "emission", false);
        for (int side = 0; side < r.sides && !emission; ++side) {
            if (!r.solves(side) || (side == 1 && !m.two_sided_emission)) continue;
            auto& c = r.Le[side].coeffs();
            for (size_t i = 0; i < c.size(); i += 3) c[i] += m.emission.x, c[i + 1] += m.emission.y, c[i + 2] += m.emission.z;
        }
        // The front spline of a surface lit only from behind is zero (the output always has one);
        // the back spline exists only where the back side was solved.
        auto front = [](Receiver& part) { return part.live[0] ? std::move(part.Le[0]) : TensorSpline(part.axes, 3); };
        auto back = [](Receiver& part) {
            return part.solves(1) ? std::optional<TensorSpline>(std::move(part.Le[1])) : std::nullopt;
        };
        std::optional<SurfaceRadiance> out;
        std::string kind;
        if (r.tint) {
            Receiver& black = result[r.partner->index];
            out = SurfaceRadiance{r.kind, r.map, front(r), back(r), std::nullopt, std::nullopt};
            out->tint_zero = front(black);
            out->lower_tint_zero = back(black);
            out->specular = m.specular_texture;
            kind = "glossy 4D";
        } else if (r.partner) {
            Receiver& s = result[r.partner->index];
            out = SurfaceRadiance{Representation::Decomposed, s.map, front(s), back(s), front(r), back(r)};
            kind = "decomposed 2D + 4D (38)";
        } else {
            out = SurfaceRadiance{r.kind, r.map, front(r), back(r), std::nullopt, std::nullopt};
            kind = r.kind == Representation::Diffuse ? "diffuse 2D"
                   : r.normals                       ? "bumped 4D"
                   : (r.sides == 2 && r.bsdf->transmits() ? "glossy 4D + transmission" : "glossy 4D");
        }
        out->albedo = m.albedo_texture;
        out->normals = m.normal_texture;
        out->coat = r.coat;
        out->emission = emission;
        out->two_sided_emission = m.two_sided_emission;
        if (!r.bsdf->transmits() && settings.two_sided)
            kind += r.live[0] ? (r.live[1] ? ", both sides" : "") : (r.live[1] ? ", back side" : ", no side lit");
        const Plan& p = (settings.final_gather ? final_plans : plans)[k];
        std::vector<int> shape;
        for (size_t n : out->upper.shape()) shape.push_back(int(n));
        shape.pop_back();
        solution.reports.push_back({scene[r.surface].surface->name(), kind, shape, p.reason, errors[k], error_parts[k]});
        solution.radiance[r.surface] = std::move(out);
    }
    for (size_t i = 0; i < scene.size(); ++i) {
        if (const auto& glass = scene[i].material.thin_glass) {
            std::ostringstream why;
            why << "window pane (thin glass, index " << glass->eta << (glass->one_interface ? ", one face of a slab" : "")
                << "): light passes straight through it with the Fresnel transmittance, no spline";
            solution.reports.push_back({scene[i].surface->name(), "thin glass", {}, why.str()});
        } else if (!scene[i].receiver) {
            solution.reports.push_back({scene[i].surface->name(), "emitter", {}, "light object: emits only, no spline"});
        }
    }
    for (const DistantLight& l : scene.distant_lights())
        solution.reports.push_back({l.name, "distant light", {}, "a light at infinity (sun): emits only, no spline"});
    if (const EnvironmentMap* map = scene.world_map())
        solution.reports.push_back({"world", "world light", {},
                                    "an environment map of " + std::to_string(map->width()) + " x " +
                                        std::to_string(map->height()) + " pixels from every unblocked direction"});
    else if (scene.has_world())
        solution.reports.push_back({"world", "world light", {}, "constant radiance from every unblocked direction"});
    progress.finish();
    return solution;
}

}  // namespace bsgi
