#include "bsgi/solver.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <sstream>

#include "bsgi/parallel.h"
#include "bsgi/quadrature.h"
#include "bsgi/ray_scene.h"

namespace bsgi {

namespace {

constexpr double kPi = 3.14159265358979323846;

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A receiving surface: its radiance splines (Figure 4) and its Schoenberg nodes.
struct Receiver {
    int surface;
    TensorSpline Le, L, Ltmp;  // cumulative, incremental, temporary reflected radiance
    std::vector<SurfacePoint> nodes;  // at (u*_i, v*_j), i slowest, matching the coefficient layout
};

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

// B-spline quadrature (11) on [0, 1] with n coefficients: of the quadratic quasi-interpolant
// for degree 2 (with 3 coefficients this is Simpson's rule), of Schoenberg's approximation otherwise.
QuadratureRule emitter_quadrature(int n, int degree) {
    const KnotVector k = KnotVector::clamped_uniform(n, degree, 0.0, 1.0);
    return k.degree() == 2 ? quasi_interpolant_quadrature(k) : schoenberg_quadrature(k);
}

class GatherContext {
public:
    GatherContext(const Scene& scene, const SolverSettings& settings) : scene_(scene), settings_(settings) {
        Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
        for (size_t i = 0; i < scene.size(); ++i) {
            const Tessellation t = scene[i].surface->tessellate();
            for (size_t k = 0; k < t.positions.size(); k += 3) {
                lo = {std::min(lo.x, double(t.positions[k])), std::min(lo.y, double(t.positions[k + 1])),
                      std::min(lo.z, double(t.positions[k + 2]))};
                hi = {std::max(hi.x, double(t.positions[k])), std::max(hi.y, double(t.positions[k + 1])),
                      std::max(hi.z, double(t.positions[k + 2]))};
            }
            if (scene[i].occluder) rays_.add(int(i), t);
        }
        rays_.commit();
        // Ray offsets scale with the scene: its extent and its distance from the origin, since
        // Embree stores positions in float.
        const double magnitude = std::max({length(hi - lo), std::abs(lo.x), std::abs(lo.y), std::abs(lo.z),
                                           std::abs(hi.x), std::abs(hi.y), std::abs(hi.z)});
        offset_ = 2e-5 * magnitude;
        for (size_t i = 0; i < scene.size(); ++i) {
            if (!scene[i].material.emits()) continue;
            emitters_.push_back({int(i)});
        }
        cell_rule_ = emitter_quadrature(settings.emitter_coeffs, settings.emitter_degree);
    }

    // Direct light at a receiver point: the surface integral (8)/(35) over every emitter but the
    // receiver itself, returned as reflected radiance for a Lambertian albedo.
    Vec3 direct(int receiver, const SurfacePoint& r, const Vec3& albedo, size_t& rays) const {
        Vec3 irradiance{0, 0, 0};
        const Vec3 origin = r.p + r.frame.z * offset_;
        for (const Emitter& e : emitters_) {
            if (e.surface == receiver) continue;
            const SceneSurface& es = scene_[e.surface];
            irradiance += es.material.emission * emitter_cell(r, origin, *es.surface, 0, 1, 0, 1, 0, rays);
        }
        return albedo * irradiance / kPi;
    }

    // The geometric part of (8) over the parameter cell [s0, s1] x [t0, t1] of an emitter: the
    // cell's B-spline quadrature rule where the cell is small seen from the receiver, else the sum
    // over its four quarters. The kernel 1/r^4 peaks where the receiver is close (contact edges,
    // a lamp just above a surface): cells shrink geometrically towards it.
    double emitter_cell(const SurfacePoint& r, const Vec3& origin, const Surface& emitter, double s0, double s1,
                        double t0, double t1, int depth, size_t& rays) const {
        const Vec3 c = emitter.evaluate(0.5 * (s0 + s1), 0.5 * (t0 + t1)).p;
        double radius = 0;
        for (double s : {s0, s1})
            for (double t : {t0, t1}) radius = std::max(radius, length(emitter.evaluate(s, t).p - c));
        const double dist = length(c - r.p) - radius;
        if (depth < settings_.emitter_max_depth && 2 * radius > settings_.emitter_cell_ratio * dist) {
            const double sm = 0.5 * (s0 + s1), tm = 0.5 * (t0 + t1);
            return emitter_cell(r, origin, emitter, s0, sm, t0, tm, depth + 1, rays) +
                   emitter_cell(r, origin, emitter, sm, s1, t0, tm, depth + 1, rays) +
                   emitter_cell(r, origin, emitter, s0, sm, tm, t1, depth + 1, rays) +
                   emitter_cell(r, origin, emitter, sm, s1, tm, t1, depth + 1, rays);
        }
        const double ds = s1 - s0, dt = t1 - t0;
        double sum = 0;
        for (size_t p = 0; p < cell_rule_.nodes.size(); ++p)
            for (size_t k = 0; k < cell_rule_.nodes.size(); ++k) {
                const SurfacePoint ep = emitter.evaluate(s0 + ds * cell_rule_.nodes[p], t0 + dt * cell_rule_.nodes[k]);
                const Vec3 d = ep.p - r.p;
                const double cos_r = dot(d, r.frame.z), cos_e = -dot(d, ep.frame.z);
                if (cos_r <= 0 || cos_e <= 0) continue;  // emitters radiate from their front
                const double d2 = dot(d, d);
                ++rays;
                // Both ends lifted off their surfaces, and the segment stopped short of the emitter,
                // so neither surface, nor one meeting the emitter along its edge, shadows it.
                const Vec3 segment = ep.p + ep.frame.z * offset_ - origin;
                const double stop = 1.0 - 2 * offset_ / length(segment);
                if (stop > 0 && rays_.occluded(origin, segment, 0.0, stop)) continue;
                sum += cell_rule_.weights[p] * cell_rule_.weights[k] * cos_r * cos_e / (d2 * d2) * ep.jacobian;
            }
        return sum * ds * dt;
    }

    // Hemispherical integral (26)-(32) of the incremental radiance of the other surfaces, with
    // the cosine-weighted product rule in (cos^2 theta, phi): degree-0 B-spline quadrature on
    // uniform knots, where cos(theta) d(omega) = d(cos^2 theta) d(phi) / 2.
    Vec3 gather(const SurfacePoint& r, const Vec3& albedo, const std::vector<const TensorSpline*>& incident,
                size_t& rays) const {
        const int nt = settings_.hemisphere_nodes_theta, np = settings_.hemisphere_nodes_phi;
        const Vec3 origin = r.p + r.frame.z * offset_;
        Vec3 sum{0, 0, 0};
        for (int i = 0; i < nt; ++i) {
            const double w = (i + 0.5) / nt;
            const double cos_t = std::sqrt(w), sin_t = std::sqrt(1 - w);
            for (int j = 0; j < np; ++j) {
                const double phi = 2 * kPi * (j + 0.5 * (1 + (i & 1))) / np;  // rows staggered
                const Vec3 dir = r.frame.to_world({sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t});
                ++rays;
                const RayHit hit = rays_.closest_hit(origin, dir, 0.0, 1e300);
                if (hit.surface < 0 || !incident[hit.surface]) continue;
                double u = hit.u, v = hit.v;
                const Surface& hs = *scene_[hit.surface].surface;
                hs.refine_parameters(origin + dir * hit.t, u, v);
                if (dot(hs.evaluate(u, v).frame.z, dir) >= 0) continue;  // back side: no radiance there
                double L[3];
                const double uv[2] = {u, v};
                incident[hit.surface]->evaluate(uv, L);
                sum += Vec3(L[0], L[1], L[2]);
            }
        }
        return albedo * sum / double(nt * np);  // (albedo / pi) * pi * mean
    }

private:
    struct Emitter {
        int surface;
    };
    const Scene& scene_;
    const SolverSettings& settings_;
    RayScene rays_;
    double offset_ = 0;
    std::vector<Emitter> emitters_;
    QuadratureRule cell_rule_;  // on [0, 1], for one emitter cell
};

// Knots where detail is (paper 3.1: "if there is extra detail in one part of the surface the
// knots can be clustered there"): the direct light is probed on a grid twice as fine as the
// coefficients, and knots in u (v) are equidistributed by the square root of the light's second
// differences along u (v), which is the knot density that balances the error of a spline at
// shadow edges and contact lines. Half of the density stays uniform, and no span gets narrower
// than a quarter of the uniform one, so smooth light keeps its uniform knots.
std::pair<KnotVector, KnotVector> adaptive_knots(const GatherContext& ctx, int surface, const SceneSurface& s,
                                                 const SolverSettings& settings, size_t& rays) {
    const int n = settings.spatial_coeffs, d = settings.spatial_degree;
    const double a = settings.epsilon, b = 1 - settings.epsilon;
    const int probes = 2 * n + 1;
    std::vector<double> f(size_t(probes) * probes);
    double fmax = 0;
    for (int i = 0; i < probes; ++i)
        for (int j = 0; j < probes; ++j) {
            const SurfacePoint p = s.surface->evaluate(a + (b - a) * i / (probes - 1), a + (b - a) * j / (probes - 1));
            const Vec3 L = ctx.direct(surface, p, {1, 1, 1}, rays);
            f[size_t(i) * probes + j] = L.x + L.y + L.z;
            fmax = std::max(fmax, f[size_t(i) * probes + j]);
        }
    const KnotVector uniform = KnotVector::clamped_uniform(n, d, a, b);
    if (!(fmax > 0) || n <= d + 1) return {uniform, uniform};
    auto density_along = [&](bool along_u) {
        std::vector<double> second(probes, 0.0);
        for (int i = 1; i + 1 < probes; ++i)
            for (int j = 0; j < probes; ++j) {
                auto at = [&](int k) { return along_u ? f[size_t(k) * probes + j] : f[size_t(j) * probes + k]; };
                second[i] += std::abs(at(i - 1) - 2 * at(i) + at(i + 1)) / (probes * fmax);
            }
        // Per probe cell, from its two end probes; then half uniform, capped at 4x the mean.
        std::vector<double> density(probes - 1);
        double mean = 0;
        for (int k = 0; k + 1 < probes; ++k) mean += density[k] = std::sqrt(0.5 * (second[k] + second[k + 1]));
        mean /= probes - 1;
        if (!(mean > 1e-6)) return std::vector<double>(probes - 1, 1.0);
        for (double& x : density) x = std::min(0.25 + 0.75 * x / mean, 8.0);
        return density;
    };
    return {equidistributed_knots(density_along(true), n, d, a, b), equidistributed_knots(density_along(false), n, d, a, b)};
}

void validate(const SolverSettings& s) {
    auto need = [](bool ok, const char* what) {
        if (!ok) throw std::invalid_argument(std::string("solver settings: ") + what);
    };
    need(s.spatial_degree >= 0 && s.spatial_degree <= kMaxDegree, "spatial_degree must be in 0..15");
    need(s.spatial_coeffs >= s.spatial_degree + 1, "spatial_coeffs must be at least spatial_degree + 1");
    need(s.epsilon >= 0 && s.epsilon < 0.5, "epsilon must be in [0, 0.5)");
    need(s.emitter_coeffs >= s.emitter_degree + 1, "emitter_coeffs must be at least emitter_degree + 1");
    need(s.emitter_max_depth >= 0 && s.emitter_max_depth <= 20, "emitter_max_depth must be in 0..20");
    need(s.emitter_cell_ratio > 0, "emitter_cell_ratio must be > 0");
    need(s.emitter_degree >= 0 && s.emitter_degree <= 3, "emitter_degree must be in 0..3");
    need(s.hemisphere_nodes_theta >= 1 && s.hemisphere_nodes_phi >= 1, "hemisphere nodes must be >= 1");
    need(s.max_bounces >= 0, "max_bounces must be >= 0");
    need(s.tolerance >= 0, "tolerance must be >= 0");
    need(s.memory_budget_mb > 0, "memory_budget_mb must be > 0");
}

}  // namespace

size_t estimate_solve_bytes(const Scene& scene, const SolverSettings& settings) {
    const size_t n = size_t(settings.spatial_coeffs) * settings.spatial_coeffs;
    const size_t per_receiver = 3 * n * 3 * sizeof(double) + n * sizeof(SurfacePoint) + sizeof(Receiver);
    size_t receivers = 0, triangles = 0;
    for (const auto& s : scene.surfaces()) {
        receivers += s.receiver;
        if (s.occluder) triangles += s.surface->tessellate().triangles.size() / 3;
    }
    return receivers * per_receiver + triangles * 64;  // Embree BVH: about 64 bytes a triangle
}

Solution solve(const Scene& scene, const SolverSettings& settings, Progress& progress) {
    validate(settings);
    bool any_emitter = false;
    for (const auto& s : scene.surfaces()) any_emitter |= s.material.emits();
    if (!any_emitter) throw std::invalid_argument("scene has no emitter: add a light or an emissive material");
    const size_t bytes = estimate_solve_bytes(scene, settings);
    if (bytes > settings.memory_budget_mb * 1024 * 1024) {
        std::ostringstream msg;
        msg << "solve needs about " << bytes / (1024 * 1024) << " MB (" << settings.spatial_coeffs << "^2 coefficients x 3 splines x "
            << scene.size() << " surfaces), over the budget of " << settings.memory_budget_mb << " MB";
        throw std::runtime_error(msg.str());
    }

    const int stages = 1 + settings.max_bounces;
    progress.begin_stage("building ray scene", 0, stages, 1);
    GatherContext ctx(scene, settings);

    std::vector<Receiver> receivers;
    std::vector<int> receiver_of(scene.size(), -1);
    std::vector<int> receiving;
    for (size_t i = 0; i < scene.size(); ++i)
        if (scene[i].receiver) receiving.push_back(int(i));
    const KnotVector uniform = KnotVector::clamped_uniform(settings.spatial_coeffs, settings.spatial_degree, settings.epsilon,
                                                           1 - settings.epsilon);
    std::vector<std::pair<KnotVector, KnotVector>> knots(receiving.size(), {uniform, uniform});
    if (settings.adaptive_knots) {
        progress.begin_stage("placing knots", 0, stages, receiving.size());
        parallel_for(receiving.size(), 1, settings.threads, [&](size_t begin, size_t end) {
            for (size_t k = begin; k < end; ++k) {
                size_t local_rays = 0;
                knots[k] = adaptive_knots(ctx, receiving[k], scene[receiving[k]], settings, local_rays);
                progress.advance(1);
            }
        }, progress.cancel_flag());
        progress.throw_if_cancelled();
    }
    for (size_t k = 0; k < receiving.size(); ++k) {
        const int i = receiving[k];
        receiver_of[i] = int(receivers.size());
        const KnotVector& ku = knots[k].first;
        const KnotVector& kv = knots[k].second;
        Receiver r{i, TensorSpline({ku, kv}, 3), TensorSpline({ku, kv}, 3), TensorSpline({ku, kv}, 3), {}};
        for (double u : ku.schoenberg_nodes())
            for (double v : kv.schoenberg_nodes()) r.nodes.push_back(scene[i].surface->evaluate(u, v));
        receivers.push_back(std::move(r));
    }
    // Work items: one per (receiver, node).
    std::vector<std::pair<int, int>> items;
    for (size_t k = 0; k < receivers.size(); ++k)
        for (size_t j = 0; j < receivers[k].nodes.size(); ++j) items.emplace_back(int(k), int(j));

    Solution solution;
    std::atomic<size_t> rays{0};
    const auto t0 = std::chrono::steady_clock::now();

    // Direct lighting phase: gather from every emitter into S.L; S.Le <- S.L.
    progress.begin_stage("direct light", 0, stages, items.size());
    parallel_for(items.size(), 16, settings.threads, [&](size_t begin, size_t end) {
        size_t local_rays = 0;
        for (size_t w = begin; w < end; ++w) {
            Receiver& r = receivers[items[w].first];
            const int j = items[w].second;
            const Vec3 L = ctx.direct(r.surface, r.nodes[j], scene[r.surface].material.albedo, local_rays);
            double* a = &r.L.coeffs()[3 * j];
            a[0] = L.x, a[1] = L.y, a[2] = L.z;
        }
        rays += local_rays;
        progress.advance(end - begin);
    }, progress.cancel_flag());
    progress.throw_if_cancelled();
    for (auto& r : receivers) r.Le.coeffs() = r.L.coeffs();
    solution.stats.seconds_direct = seconds_since(t0);

    // Indirect phase: gather the incremental radiance L of all surfaces into Ltmp, then
    // Le += Ltmp, L <- Ltmp, until the increment is small.
    const auto t1 = std::chrono::steady_clock::now();
    std::vector<const TensorSpline*> incident(scene.size(), nullptr);
    for (size_t i = 0; i < scene.size(); ++i)
        if (receiver_of[i] >= 0) incident[i] = &receivers[receiver_of[i]].L;
    double previous[3] = {0, 0, 0}, previous_rho[3] = {2, 2, 2}, tail[3] = {0, 0, 0};
    bool converged = false;
    for (int bounce = 0; bounce < settings.max_bounces; ++bounce) {
        progress.begin_stage("indirect bounce " + std::to_string(bounce + 1), 1 + bounce, stages, items.size());
        parallel_for(items.size(), 16, settings.threads, [&](size_t begin, size_t end) {
            size_t local_rays = 0;
            for (size_t w = begin; w < end; ++w) {
                Receiver& r = receivers[items[w].first];
                const int j = items[w].second;
                const Vec3 L = ctx.gather(r.nodes[j], scene[r.surface].material.albedo, incident, local_rays);
                double* a = &r.Ltmp.coeffs()[3 * j];
                a[0] = L.x, a[1] = L.y, a[2] = L.z;
            }
            rays += local_rays;
            progress.advance(end - begin);
        }, progress.cancel_flag());
        progress.throw_if_cancelled();
        // Per channel: the largest increment and cumulative coefficient.
        double increment[3] = {0, 0, 0}, total[3] = {0, 0, 0};
        for (auto& r : receivers) {
            for (size_t c = 0; c < r.Le.coeffs().size(); ++c) {
                r.Le.coeffs()[c] += r.Ltmp.coeffs()[c];
                increment[c % 3] = std::max(increment[c % 3], std::abs(r.Ltmp.coeffs()[c]));
                total[c % 3] = std::max(total[c % 3], std::abs(r.Le.coeffs()[c]));
            }
            std::swap(r.L, r.Ltmp);
        }
        // incident[] points at the L members, which swap() exchanged in place: still valid.
        solution.stats.bounces = bounce + 1;
        // Increments shrink geometrically, by the ratio rho of the transport's dominant mode, so
        // what the remaining bounces add is about increment * rho / (1 - rho). Without
        // extrapolation, stop when that tail is below tolerance; with it, add the tail and stop
        // when its uncertainty (from the change of rho between bounces) is below tolerance.
        double error = 0;
        for (int c = 0; c < 3; ++c) {
            if (total[c] == 0) continue;
            const double rho = previous[c] > 0 ? increment[c] / previous[c] : 1.0;
            double channel_error = 1e300;
            if (rho < 1) {
                tail[c] = rho / (1 - rho);
                channel_error = increment[c] * (settings.extrapolate
                                                    ? std::abs(rho - previous_rho[c]) / ((1 - rho) * (1 - rho))
                                                    : tail[c]) / total[c];
            }
            previous_rho[c] = rho;
            previous[c] = increment[c];
            error = std::max(error, channel_error);
        }
        solution.stats.last_increment = std::max({increment[0] / std::max(total[0], 1e-300),
                                                  increment[1] / std::max(total[1], 1e-300),
                                                  increment[2] / std::max(total[2], 1e-300)});
        solution.stats.estimated_error = error;
        if (error < settings.tolerance || solution.stats.last_increment == 0) {
            converged = true;
            break;
        }
    }
    if (settings.extrapolate && converged) {
        // The geometric tail of the last increment (now in L) over the bounces not taken.
        for (auto& r : receivers)
            for (size_t c = 0; c < r.Le.coeffs().size(); ++c) r.Le.coeffs()[c] += tail[c % 3] * r.L.coeffs()[c];
        solution.stats.extrapolated = true;
    }
    solution.stats.seconds_indirect = seconds_since(t1);
    solution.stats.rays = rays;

    // Outgoing radiance = emission + cumulative reflected radiance (constants are reproduced
    // exactly by the partition of unity).
    solution.radiance.resize(scene.size());
    for (auto& r : receivers) {
        const Vec3 e = scene[r.surface].material.emission;
        auto& c = r.Le.coeffs();
        for (size_t k = 0; k < c.size(); k += 3) c[k] += e.x, c[k + 1] += e.y, c[k + 2] += e.z;
        solution.stats.coefficients += c.size() / 3;
        solution.radiance[r.surface] = std::move(r.Le);
    }
    progress.finish();
    return solution;
}

}  // namespace bsgi
