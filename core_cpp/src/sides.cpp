#include "bsgi/sides.h"

#include <algorithm>
#include <cmath>

#include "bsgi/parallel.h"

namespace bsgi {

namespace {

constexpr double kPi = 3.14159265358979323846;
// The probe: a 4 x 4 grid of points per surface, 6 x 12 cosine-weighted directions from each,
// and 3 x 3 points of each emitter; enough to tell which sides face which, not to integrate.
constexpr int kPoints = 4, kTheta = 6, kPhi = 12, kEmitterPoints = 3;

// What one side of a surface sees directly: light (an emitter, a distant light, the world), and
// the sides of other receivers (surface * 2 + side).
struct SideView {
    std::string light;  // what lights it directly, empty if nothing
    std::vector<int> sides_seen;
};

// True if point p (normal n of the side probed) sees a point of the emitter's emitting side.
bool sees_emitter(const RayCaster& caster, const SurfacePoint& p, const Vec3& n, const SceneSurface& e) {
    for (int a = 0; a < kEmitterPoints; ++a)
        for (int b = 0; b < kEmitterPoints; ++b) {
            const double s = (a + 0.5) / kEmitterPoints, t = (b + 0.5) / kEmitterPoints;
            if (!e.surface->in_domain(s, t)) continue;
            const SurfacePoint ep = e.surface->evaluate(s, t);
            const Vec3 d = ep.p - p.p;
            const double len = length(d);
            if (!(len > 0) || dot(d, n) <= 0 || dot(d, ep.frame.z) >= 0) continue;  // emitters radiate from their front
            if (e.material.cone && e.material.cone->factor(-d / len) <= 0) continue;
            const Vec3 origin = caster.spawn(p.p, p.frame.z, d);
            const Vec3 segment = ep.p + ep.frame.z * caster.offset() - origin;
            const double stop = 1.0 - 2 * caster.offset() / length(segment);
            if (stop > 0 && !caster.occluded(origin, segment, 0.0, stop)) return true;
        }
    return false;
}

SideView probe_side(const Scene& scene, const RayCaster& caster, int i, int side) {
    SideView view;
    const Surface& surface = *scene[i].surface;
    std::vector<int> seen;
    for (int a = 0; a < kPoints; ++a)
        for (int b = 0; b < kPoints; ++b) {
            const double u = (a + 0.5) / kPoints, v = (b + 0.5) / kPoints;
            if (!surface.in_domain(u, v)) continue;
            const SurfacePoint p = surface.evaluate(u, v);
            const Vec3 n = side ? -p.frame.z : p.frame.z;
            for (size_t e = 0; e < scene.size() && view.light.empty(); ++e)
                if (int(e) != i && scene[e].material.emits() && sees_emitter(caster, p, n, scene[e]))
                    view.light = "light from '" + scene[e].surface->name() + "'";
            for (const DistantLight& l : scene.distant_lights())
                if (view.light.empty() && dot(l.direction, n) > 0 &&
                    !caster.occluded(caster.spawn(p.p, p.frame.z, l.direction), l.direction))
                    view.light = "light from '" + l.name + "'";
            for (int k = 0; k < kTheta; ++k)
                for (int m = 0; m < kPhi; ++m) {
                    const double w = (k + 0.5) / kTheta, phi = 2 * kPi * (m + 0.5) / kPhi;
                    const double cos_t = std::sqrt(w), sin_t = std::sqrt(1 - w);
                    const Vec3 local{sin_t * std::cos(phi), sin_t * std::sin(phi), side ? -cos_t : cos_t};
                    const Vec3 dir = p.frame.to_world(local);
                    const SurfaceHit hit = caster.closest_hit(caster.spawn(p.p, p.frame.z, dir), dir);
                    if (hit.surface < 0) {
                        if (scene.has_world() && view.light.empty()) view.light = "world light";
                        continue;
                    }
                    if (scene[hit.surface].receiver) seen.push_back(2 * hit.surface + (dot(dir, hit.frame.z) < 0 ? 0 : 1));
                }
        }
    std::sort(seen.begin(), seen.end());
    seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
    view.sides_seen = std::move(seen);
    return view;
}

}  // namespace

std::vector<SurfaceSides> probe_sides(const Scene& scene, const RayCaster& caster, const SolverSettings& settings) {
    const size_t n = scene.size();
    std::vector<SurfaceSides> out(n);
    for (size_t i = 0; i < n; ++i) {
        const SceneSurface& s = scene[i];
        const bool transmits = s.material.bsdf && s.material.bsdf->transmits();
        if (transmits) {
            out[i].live = {true, true};
            out[i].why = {"transmits", "transmits"};
        } else if (!settings.two_sided) {
            out[i].why = {"one-sided solve", "one-sided solve (two_sided off)"};
        }
    }
    if (!settings.two_sided) return out;
    // Which sides to probe: both sides of every opaque receiver.
    std::vector<int> probed;
    for (size_t i = 0; i < n; ++i)
        if (scene[i].receiver && out[i].why[0].empty()) probed.push_back(int(i));
    std::vector<std::array<SideView, 2>> views(n);
    parallel_for(probed.size(), 1, settings.threads, [&](size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k)
            for (int side = 0; side < 2; ++side) views[probed[k]][side] = probe_side(scene, caster, probed[k], side);
    });
    for (int i : probed) {
        for (int side = 0; side < 2; ++side) {
            const SideView& v = views[i][side];
            const bool emits = side == 0 && scene[i].material.emits();
            out[i].live[side] = emits || !v.light.empty();
            out[i].why[side] = emits ? "emits" : v.light.empty() ? "" : "receives " + v.light;
        }
    }
    // Light reflected on: a side that sees a live side of a receiver is live, to a fixed point.
    for (bool changed = true; changed;) {
        changed = false;
        for (int i : probed)
            for (int side = 0; side < 2; ++side) {
                if (out[i].live[side]) continue;
                for (int seen : views[i][side].sides_seen)
                    if (out[seen / 2].live[seen % 2]) {
                        out[i].live[side] = changed = true;
                        out[i].why[side] = "receives light reflected by '" + scene[seen / 2].surface->name() + "'";
                        break;
                    }
            }
    }
    for (int i : probed)
        for (int side = 0; side < 2; ++side)
            if (!out[i].live[side]) out[i].why[side] = "sees no light (the inside of a closed mesh?)";
    return out;
}

}  // namespace bsgi
