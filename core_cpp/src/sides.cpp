#include "bsgi/sides.h"

#include <algorithm>
#include <cmath>

#include "bsgi/parallel.h"

namespace bsgi {

namespace {

constexpr double kPi = 3.14159265358979323846;
// The probe: a 6 x 6 grid of cells per side of a surface, a point at each cell's centre casting
// 6 x 12 cosine-weighted directions, and 3 x 3 points of each emitter; enough to tell which
// parts of which sides face which, not to integrate.
constexpr int kPoints = 6, kCells = kPoints * kPoints, kTheta = 6, kPhi = 12, kEmitterPoints = 3;
// Rays of one point that must reach lit cells for the point to count as lit by them: one ray
// alone may have slipped through a crack between two patches (a box's edge).
constexpr int kRaysToCarry = 2;

constexpr int kNotChecked = -1, kLitDirectly = -2;

// A probe ray's end on a receiver: the cell it lands in, numbered (surface * 2 + side) * kCells
// + cell, and where. 24 bytes: a large scene's probe holds millions.
struct Hit {
    double u, v;
    int cell;
    // Checked when needed: whether the point itself sees light directly (kLitDirectly), else
    // the cells its own probe rays reach (an index into the probe's `sees`).
    int checked = kNotChecked;
};

// What the centre of one cell of one side sees: light (an emitter, a distant light, the world)
// and the receivers its rays reach.
struct CellView {
    std::string light;  // what lights it directly, empty if nothing
    std::vector<Hit> hits;
    bool escaped = false;  // some rays reach no surface
    bool others = false;   // some rays reach another surface than the one probed
};

int cell_of(double u, double v) {
    const int a = std::clamp(int(u * kPoints), 0, kPoints - 1), b = std::clamp(int(v * kPoints), 0, kPoints - 1);
    return a * kPoints + b;
}

// Direction k of the probe's cosine-weighted set on the side of normal n = +-frame.z, turned
// about the normal by `turn` (a fraction of the azimuth step): each cell turns its set by its
// own amount, so that the cells' rays do not line up with the edges of boxes made of patches,
// where a ray may slip between two patches that meet.
Vec3 probe_direction(const SurfacePoint& p, int side, int k, double turn) {
    const double w = (k / kPhi + 0.5) / kTheta, phi = 2 * kPi * (k % kPhi + turn) / kPhi;
    const double cos_t = std::sqrt(w), sin_t = std::sqrt(1 - w);
    return p.frame.to_world({sin_t * std::cos(phi), sin_t * std::sin(phi), side ? -cos_t : cos_t});
}

// The first surface a probe ray meets that is not a window pane: light passes panes, so the
// probe looks through them (escaped past kMaxPanes panes, as the gathering gives up there).
SurfaceHit opaque_hit(const RayCaster& caster, Vec3 origin, const Vec3& dir) {
    for (int k = 0; k <= RayCaster::kMaxPanes; ++k) {
        const SurfaceHit hit = caster.closest_hit(origin, dir);
        if (hit.surface < 0 || !caster.pane(hit.surface)) return hit;
        origin = caster.spawn(hit.p, hit.frame.z, dir);
    }
    return {};
}

// True if point p (normal n of the side probed) sees a point of the emitter's emitting side.
bool sees_emitter(const RayCaster& caster, const SurfacePoint& p, const Vec3& n, const SceneSurface& e) {
    for (int a = 0; a < kEmitterPoints; ++a)
        for (int b = 0; b < kEmitterPoints; ++b) {
            const double s = (a + 0.5) / kEmitterPoints, t = (b + 0.5) / kEmitterPoints;
            if (!e.surface->in_domain(s, t)) continue;
            const SurfacePoint ep = e.surface->evaluate(s, t);
            const Vec3 d = ep.p - p.p;
            const double len = length(d);
            // Emitters radiate from their front (and their back if two-sided).
            const double facing = -dot(d, ep.frame.z);
            if (!(len > 0) || dot(d, n) <= 0 || facing == 0 || (facing < 0 && !e.material.two_sided_emission)) continue;
            if (e.material.cone && e.material.cone->factor(-d / len) <= 0) continue;
            const Vec3 origin = caster.spawn(p.p, p.frame.z, d);
            const Vec3 segment = ep.p + ep.frame.z * (facing > 0 ? caster.offset() : -caster.offset()) - origin;
            const double stop = 1.0 - 2 * caster.offset() / length(segment);
            if (stop > 0 && caster.transmittance(origin, segment, 0.0, stop) > 0) return true;
        }
    return false;
}

// What lights point p of surface i on a side directly (emitters and distant lights; the world
// only if `world`, which the caller may find with its own rays): a description, empty if none.
std::string direct_light(const Scene& scene, const RayCaster& caster, int i, const SurfacePoint& p, int side, bool world) {
    const Vec3 n = side ? -p.frame.z : p.frame.z;
    for (size_t e = 0; e < scene.size(); ++e)
        if (int(e) != i && scene[e].material.emits() && sees_emitter(caster, p, n, scene[e]))
            return "light from '" + scene[e].surface->name() + "'";
    for (const DistantLight& l : scene.distant_lights())
        if (dot(l.direction, n) > 0 && caster.transmittance(caster.spawn(p.p, p.frame.z, l.direction), l.direction) > 0)
            return "light from '" + l.name + "'";
    if (world && scene.has_world())
        for (int k = 0; k < kTheta * kPhi; ++k) {
            const Vec3 dir = probe_direction(p, side, k, 0.5);
            if (opaque_hit(caster, caster.spawn(p.p, p.frame.z, dir), dir).surface < 0) return "world light";
        }
    return "";
}

std::vector<CellView> probe_side(const Scene& scene, const RayCaster& caster, int i, int side) {
    std::vector<CellView> cells(kCells);
    const Surface& surface = *scene[i].surface;
    for (int a = 0; a < kPoints; ++a)
        for (int b = 0; b < kPoints; ++b) {
            CellView& view = cells[a * kPoints + b];
            const double u = (a + 0.5) / kPoints, v = (b + 0.5) / kPoints;
            if (!surface.in_domain(u, v)) continue;
            const SurfacePoint p = surface.evaluate(u, v);
            view.light = direct_light(scene, caster, i, p, side, false);
            const double turn = std::fmod((2 * (i * kCells + a * kPoints + b) + side + 1) * 0.6180339887498949, 1.0);
            for (int k = 0; k < kTheta * kPhi; ++k) {
                const Vec3 dir = probe_direction(p, side, k, turn);
                const SurfaceHit hit = opaque_hit(caster, caster.spawn(p.p, p.frame.z, dir), dir);
                if (hit.surface < 0) {
                    view.escaped = true;
                    if (scene.has_world() && view.light.empty()) view.light = "world light";
                    continue;
                }
                view.others |= hit.surface != i;
                if (!scene[hit.surface].receiver) continue;
                const int hit_side = dot(dir, hit.frame.z) < 0 ? 0 : 1;
                view.hits.push_back({hit.u, hit.v, (2 * hit.surface + hit_side) * kCells + cell_of(hit.u, hit.v)});
            }
            // Only a cell not lit directly asks its hits whether they carry light: the others'
            // would hold most of a large scene's probe memory for nothing.
            if (!view.light.empty()) view.hits = {};
            view.hits.shrink_to_fit();
        }
    return cells;
}

// What the probe holds at its end, its peak: the cells' views with their hits (and the cells
// their ends see), and each cell's reason. A heap block costs its capacity and about 16 bytes.
size_t held_bytes(const std::vector<std::array<std::vector<CellView>, 2>>& views, const std::vector<std::string>& why,
                  const std::vector<std::vector<int>>& sees) {
    constexpr size_t kBlock = 16;
    auto string_bytes = [](const std::string& s) { return sizeof(std::string) + (s.capacity() > 15 ? s.capacity() + 1 + kBlock : 0); };
    size_t bytes = views.size() * sizeof(views[0]) + why.size() * sizeof(char);  // and `lit`, a char a cell
    for (const std::string& w : why) bytes += string_bytes(w);
    bytes += sees.capacity() * sizeof(sees[0]);
    for (const std::vector<int>& cells : sees) bytes += cells.capacity() * sizeof(int) + (cells.empty() ? 0 : kBlock);
    for (const auto& surface : views)
        for (const std::vector<CellView>& cells : surface) {
            bytes += cells.capacity() * sizeof(CellView) + (cells.empty() ? 0 : kBlock);
            for (const CellView& c : cells) {
                bytes += string_bytes(c.light) - sizeof(std::string) + c.hits.capacity() * sizeof(Hit) + (c.hits.empty() ? 0 : kBlock);
            }
        }
    return bytes;
}

}  // namespace

std::vector<SurfaceSides> probe_sides(const Scene& scene, const RayCaster& caster, const SolverSettings& settings, size_t* bytes) {
    const size_t n = scene.size();
    std::vector<SurfaceSides> out(n);
    std::vector<int> probed;  // both sides of every opaque receiver
    for (size_t i = 0; i < n; ++i) {
        const SceneSurface& s = scene[i];
        if (s.material.bsdf && s.material.bsdf->transmits()) {
            out[i].live = {true, true};
            out[i].why = {"transmits", "transmits"};
        } else if (!settings.two_sided) {
            out[i].why = {"one-sided solve", "one-sided solve (two_sided off)"};
        } else if (s.receiver) {
            probed.push_back(int(i));
        }
    }
    if (probed.empty()) return out;
    std::vector<std::array<std::vector<CellView>, 2>> views(n);
    parallel_for(probed.size(), 1, settings.threads, [&](size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k)
            for (int side = 0; side < 2; ++side) views[probed[k]][side] = probe_side(scene, caster, probed[k], side);
    });
    // Cells lit directly (or emitting), then cells that see a lit cell, to a fixed point; `why`
    // keeps what lit each first. Light is carried per cell rather than per side, so that only
    // where a side is lit lights others: the floor under a box standing on it (its rays end on
    // the box's inside) lights no one. A ray landing in a lit cell counts only if its own end
    // sees light or a lit cell too: the box's inside, whose rays meet the floor where the box's
    // bottom lies on it, stays dark although the floor cell at the box's edge is lit.
    // Two-sided emitters whose back sees only themselves keep their light inside.
    for (int i : probed) {
        if (!scene[i].material.two_sided_emission) continue;
        bool inside = true;
        for (const CellView& v : views[i][1]) inside &= !v.escaped && !v.others;
        out[i].encloses_emission = inside;
    }
    std::vector<char> lit(2 * n * kCells, 0);
    std::vector<std::string> why(2 * n * kCells);
    for (int i : probed)
        for (int side = 0; side < 2; ++side)
            for (int c = 0; c < kCells; ++c) {
                const size_t id = (2 * size_t(i) + side) * kCells + c;
                const CellView& v = views[i][side][c];
                const bool emits = (side == 0 || (scene[i].material.two_sided_emission && !out[i].encloses_emission)) &&
                                   scene[i].material.emits();
                lit[id] = emits || !v.light.empty();
                why[id] = emits ? "emits" : v.light.empty() ? "" : "receives " + v.light;
            }
    // A ray's end carries light if its cell is lit and the point itself sees light directly or
    // sees a lit cell (a cell lit at its centre may be dark where the ray ends).
    std::vector<std::vector<int>> sees;
    auto carries_light = [&](Hit& h) {
        if (!lit[h.cell]) return false;
        const int surface = h.cell / (2 * kCells), side = (h.cell / kCells) % 2;
        if (h.checked == kNotChecked) {
            const SurfacePoint p = scene[surface].surface->evaluate(h.u, h.v);
            if (!direct_light(scene, caster, surface, p, side, true).empty()) {
                h.checked = kLitDirectly;
            } else {
                h.checked = int(sees.size());
                std::vector<int>& cells = sees.emplace_back();
                for (int k = 0; k < kTheta * kPhi; ++k) {
                    const Vec3 dir = probe_direction(p, side, k, 0.5);
                    const SurfaceHit hit = opaque_hit(caster, caster.spawn(p.p, p.frame.z, dir), dir);
                    if (hit.surface >= 0 && scene[hit.surface].receiver)
                        cells.push_back((2 * hit.surface + (dot(dir, hit.frame.z) < 0 ? 0 : 1)) * kCells + cell_of(hit.u, hit.v));
                }
                cells.shrink_to_fit();
            }
        }
        if (h.checked == kLitDirectly) return true;
        int seen = 0;
        for (int c : sees[h.checked]) seen += lit[c];
        return seen >= kRaysToCarry;
    };
    for (bool changed = true; changed;) {
        changed = false;
        for (int i : probed)
            for (int side = 0; side < 2; ++side)
                for (int c = 0; c < kCells; ++c) {
                    const size_t id = (2 * size_t(i) + side) * kCells + c;
                    if (lit[id]) continue;
                    int carrying = 0;
                    for (Hit& h : views[i][side][c].hits)
                        if (carries_light(h) && ++carrying == kRaysToCarry) {
                            lit[id] = changed = true;
                            why[id] = "receives light reflected by '" + scene[h.cell / (2 * kCells)].surface->name() + "'";
                            break;
                        }
                }
    }
    for (int i : probed)
        for (int side = 0; side < 2; ++side) {
            // The reason of a cell lit directly if there is one, else of the first lit cell.
            bool escaped = false;
            out[i].live[side] = false;
            out[i].why[side].clear();
            for (int c = 0; c < kCells; ++c) {
                const size_t id = (2 * size_t(i) + side) * kCells + c;
                escaped |= views[i][side][c].escaped;
                if (!lit[id]) continue;
                const bool direct = why[id].rfind("receives light reflected", 0) != 0;
                if (!out[i].live[side] || (direct && out[i].why[side].rfind("receives light reflected", 0) == 0))
                    out[i].why[side] = why[id];
                out[i].live[side] = true;
            }
            if (!out[i].live[side])
                out[i].why[side] = side == 1 && out[i].encloses_emission
                                       ? "emits, but only into itself (the inside of a closed mesh)"
                                       : escaped ? "sees no light" : "sees no light (the inside of a closed mesh?)";
        }
    if (bytes) *bytes = held_bytes(views, why, sees);
    return out;
}

}  // namespace bsgi
