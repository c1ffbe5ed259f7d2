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

TensorSpline make_spatial_spline(const SolverSettings& s) {
    const KnotVector k = KnotVector::clamped_uniform(s.spatial_coeffs, s.spatial_degree, s.epsilon, 1 - s.epsilon);
    return TensorSpline({k, k}, 3);
}

// B-spline quadrature (11) on [0, 1] with n coefficients: of the quadratic quasi-interpolant
// (order h^3) for degree 2, of Schoenberg's approximation otherwise.
QuadratureRule emitter_quadrature(int n, int degree) {
    const KnotVector k = KnotVector::clamped_uniform(n, std::min(degree, n - 1), 0.0, 1.0);
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
            Emitter e;
            e.surface = int(i);
            const Tessellation t = scene[i].surface->tessellate();
            Vec3 c{0, 0, 0};
            const size_t nv = t.positions.size() / 3;
            for (size_t k = 0; k < nv; ++k) c += Vec3(t.positions[3 * k], t.positions[3 * k + 1], t.positions[3 * k + 2]);
            e.center = c / double(nv);
            e.radius = 0;
            for (size_t k = 0; k < nv; ++k)
                e.radius = std::max(e.radius, length(Vec3(t.positions[3 * k], t.positions[3 * k + 1], t.positions[3 * k + 2]) - e.center));
            emitters_.push_back(e);
        }
        for (int n = settings.emitter_nodes; n <= settings.emitter_nodes_max; n *= 2) rules_.push_back(emitter_quadrature(n, settings.emitter_degree));
        if (rules_.empty()) rules_.push_back(emitter_quadrature(std::max(1, settings.emitter_nodes), settings.emitter_degree));
    }

    // Irradiance-weighted direct light at a receiver point: the surface integral (8)/(35) over
    // every emitter but the receiver itself, returned as reflected radiance for a Lambertian albedo.
    Vec3 direct(int receiver, const SurfacePoint& r, const Vec3& albedo, size_t& rays) const {
        Vec3 irradiance{0, 0, 0};
        const Vec3 origin = r.p + r.frame.z * offset_;
        for (const Emitter& e : emitters_) {
            if (e.surface == receiver) continue;
            const SceneSurface& es = scene_[e.surface];
            // Closer than a few emitter sizes: the integrand peaks, use a finer rule.
            const double dist = std::max(length(e.center - r.p) - e.radius, 1e-12);
            size_t level = 0;
            while (level + 1 < rules_.size() && 2 * e.radius / rules_[level].nodes.size() > 0.5 * dist) ++level;
            const QuadratureRule& q = rules_[level];
            Vec3 sum{0, 0, 0};
            for (size_t p = 0; p < q.nodes.size(); ++p)
                for (size_t k = 0; k < q.nodes.size(); ++k) {
                    const SurfacePoint ep = es.surface->evaluate(q.nodes[p], q.nodes[k]);
                    const Vec3 d = ep.p - r.p;
                    const double cos_r = dot(d, r.frame.z), cos_e = -dot(d, ep.frame.z);
                    if (cos_r <= 0 || cos_e <= 0) continue;  // emitters radiate from their front
                    const double d2 = dot(d, d);
                    const double len = std::sqrt(d2);
                    ++rays;
                    if (rays_.occluded(origin, d, 0.0, std::max(0.0, 1.0 - 2 * offset_ / len))) continue;
                    sum += es.material.emission * (q.weights[p] * q.weights[k] * cos_r * cos_e / (d2 * d2) * ep.jacobian);
                }
            irradiance += sum;
        }
        return albedo * irradiance / kPi;
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
        Vec3 center;
        double radius;
    };
    const Scene& scene_;
    const SolverSettings& settings_;
    RayScene rays_;
    double offset_ = 0;
    std::vector<Emitter> emitters_;
    std::vector<QuadratureRule> rules_;  // emitter rules, finer and finer
};

void validate(const SolverSettings& s) {
    auto need = [](bool ok, const char* what) {
        if (!ok) throw std::invalid_argument(std::string("solver settings: ") + what);
    };
    need(s.spatial_degree >= 0 && s.spatial_degree <= kMaxDegree, "spatial_degree must be in 0..5");
    need(s.spatial_coeffs >= s.spatial_degree + 1, "spatial_coeffs must be at least spatial_degree + 1");
    need(s.epsilon >= 0 && s.epsilon < 0.5, "epsilon must be in [0, 0.5)");
    need(s.emitter_nodes >= 1 && s.emitter_nodes_max >= s.emitter_nodes, "emitter_nodes must be >= 1 and <= emitter_nodes_max");
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
    const KnotVector knots = KnotVector::clamped_uniform(settings.spatial_coeffs, settings.spatial_degree, settings.epsilon,
                                                         1 - settings.epsilon);
    const std::vector<double> nodes = knots.schoenberg_nodes();
    for (size_t i = 0; i < scene.size(); ++i) {
        if (!scene[i].receiver) continue;
        receiver_of[i] = int(receivers.size());
        Receiver r{int(i), make_spatial_spline(settings), make_spatial_spline(settings), make_spatial_spline(settings), {}};
        for (double u : nodes)
            for (double v : nodes) r.nodes.push_back(scene[i].surface->evaluate(u, v));
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
        double max_increment = 0, max_total = 0;
        for (auto& r : receivers) {
            for (size_t c = 0; c < r.Le.coeffs().size(); ++c) {
                r.Le.coeffs()[c] += r.Ltmp.coeffs()[c];
                max_increment = std::max(max_increment, std::abs(r.Ltmp.coeffs()[c]));
                max_total = std::max(max_total, std::abs(r.Le.coeffs()[c]));
            }
            std::swap(r.L, r.Ltmp);
        }
        // incident[] points at the L members, which swap() exchanged in place: still valid.
        solution.stats.bounces = bounce + 1;
        solution.stats.last_increment = max_total > 0 ? max_increment / max_total : 0;
        if (solution.stats.last_increment < settings.tolerance) break;
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
