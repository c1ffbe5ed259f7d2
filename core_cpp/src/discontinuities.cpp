#include "bsgi/discontinuities.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <sstream>

namespace bsgi {

// A polygonal surface as its feature edges: boundary edges and creases of its tessellation,
// collinear runs merged, so a quad is its four sides whatever its triangles.
struct DiscontinuityFinder::Polygonal {
    std::vector<Vec3> vertices;                  // the corners: ends of the merged edges
    std::vector<std::array<int, 2>> edges;       // into vertices
    std::vector<std::vector<Vec3>> edge_faces;   // unit normals of the faces along each edge
    std::vector<std::vector<int>> edges_at;      // per vertex, its edges
    Vec3 normal{0, 0, 0};                        // of a planar one (zero if not planar)
    bool planar = false;
};

namespace {

using Poly = DiscontinuityFinder::Polygonal;

// The box (lo, hi) of the points, widened by `pad` on every side.
std::array<Vec3, 2> box_of(const std::vector<Vec3>& points, double pad = 0) {
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (const Vec3& p : points) {
        lo = Vec3{std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = Vec3{std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    }
    return {lo - Vec3{pad, pad, pad}, hi + Vec3{pad, pad, pad}};
}

bool parallel(const Vec3& a, const Vec3& b) {
    return length(cross(a, b)) <= 1e-6 * length(a) * length(b);
}

// The feature edges of a surface's tessellation, or none if it is curved or has too many.
Poly polygonal_of(const Surface& surface) {
    Poly poly;
    const Tessellation t = surface.tessellate();
    const size_t nv = t.positions.size() / 3;
    if (nv < 3 || t.triangles.empty()) return poly;
    // Vertices are unified by position: tessellations may repeat them along seams.
    const double q = 1e-9 * std::max(surface.size(), 1e-300);
    std::map<std::array<long long, 3>, int> ids;
    std::vector<int> id(nv);
    std::vector<Vec3> pos;
    for (size_t i = 0; i < nv; ++i) {
        const Vec3 p{t.positions[3 * i], t.positions[3 * i + 1], t.positions[3 * i + 2]};
        const std::array<long long, 3> key{std::llround(p.x / q), std::llround(p.y / q), std::llround(p.z / q)};
        auto [it, fresh] = ids.emplace(key, int(pos.size()));
        if (fresh) pos.push_back(p);
        id[i] = it->second;
    }
    // A curved (non-polygonal) surface: its tessellation only approximates it.
    Vec3 plane_n{0, 0, 0};
    std::map<std::pair<int, int>, std::vector<Vec3>> faces;
    for (size_t k = 0; k + 2 < t.triangles.size(); k += 3) {
        const int a = id[t.triangles[k]], b = id[t.triangles[k + 1]], c = id[t.triangles[k + 2]];
        const Vec3 n = cross(pos[b] - pos[a], pos[c] - pos[a]);
        if (!(length(n) > 0)) continue;
        const Vec3 un = normalize(n);
        plane_n = plane_n + n;
        for (auto [x, y] : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}}) faces[{std::min(x, y), std::max(x, y)}].push_back(un);
    }
    if (!(length(plane_n) > 0)) return poly;
    plane_n = normalize(plane_n);
    poly.planar = true;
    for (const Vec3& p : pos) poly.planar = poly.planar && std::abs(dot(p - pos[0], plane_n)) <= 1e-9 * surface.size();
    if (!poly.planar && !surface.tessellation_is_exact()) return poly;
    // Feature edges: on the boundary, or between faces that are not coplanar.
    std::vector<std::pair<int, int>> kept;
    std::vector<std::vector<Vec3>> kept_faces;
    for (const auto& [e, normals] : faces) {
        bool feature = normals.size() == 1;
        for (const Vec3& n : normals) feature = feature || dot(n, normals[0]) < 1 - 1e-9;
        if (feature) kept.push_back(e), kept_faces.push_back(normals);
    }
    // Merge collinear runs through vertices that join exactly two edges.
    std::vector<std::vector<int>> at(pos.size());
    for (size_t e = 0; e < kept.size(); ++e) at[kept[e].first].push_back(int(e)), at[kept[e].second].push_back(int(e));
    std::vector<char> used(kept.size(), 0);
    auto other = [&](int e, int v) { return kept[e].first == v ? kept[e].second : kept[e].first; };
    auto passes = [&](int v, int e) {  // the run goes on through v past edge e
        if (at[v].size() != 2) return -1;
        const int f = at[v][0] == e ? at[v][1] : at[v][0];
        return parallel(pos[other(e, v)] - pos[v], pos[other(f, v)] - pos[v]) && !used[f] ? f : -1;
    };
    std::map<int, int> corner;
    auto corner_of = [&](int v) {
        auto [it, fresh] = corner.emplace(v, int(poly.vertices.size()));
        if (fresh) poly.vertices.push_back(pos[v]), poly.edges_at.emplace_back();
        return it->second;
    };
    for (size_t e0 = 0; e0 < kept.size(); ++e0) {
        if (used[e0]) continue;
        used[e0] = 1;
        std::vector<Vec3> normals = kept_faces[e0];
        int ends[2] = {kept[e0].first, kept[e0].second};
        for (int side = 0; side < 2; ++side) {
            int e = int(e0), v = ends[side];
            for (int f; (f = passes(v, e)) >= 0 && f != int(e0);) {
                used[f] = 1;
                v = other(f, v), e = f;
            }
            ends[side] = v;
        }
        if (ends[0] == ends[1]) continue;  // a closed collinear loop cannot be
        const int a = corner_of(ends[0]), b = corner_of(ends[1]);
        poly.edges_at[a].push_back(int(poly.edges.size()));
        poly.edges_at[b].push_back(int(poly.edges.size()));
        poly.edges.push_back({a, b});
        poly.edge_faces.push_back(normals);
        if (poly.edges.size() > size_t(DiscontinuityFinder::kMaxEdges)) return Poly{};
    }
    poly.normal = poly.planar ? plane_n : Vec3{0, 0, 0};
    return poly;
}

// The receiver as a plane with an affine parametrization s(u, v) = o + u du + v dv.
struct Affine {
    Vec3 o, du, dv, n;
    double gram_inv[2][2];
    std::array<double, 2> uv(const Vec3& p) const {
        const Vec3 d = p - o;
        const double a = dot(d, du), b = dot(d, dv);
        return {gram_inv[0][0] * a + gram_inv[0][1] * b, gram_inv[1][0] * a + gram_inv[1][1] * b};
    }
};

bool affine_of(const Surface& s, Affine& A) {
    A.o = s.evaluate(0, 0).p;
    A.du = s.evaluate(1, 0).p - A.o;
    A.dv = s.evaluate(0, 1).p - A.o;
    const Vec3 n = cross(A.du, A.dv);
    if (!(length(n) > 1e-12 * s.size() * s.size())) return false;
    A.n = normalize(n);
    for (int i = 0; i <= 4; ++i)
        for (int j = 0; j <= 4; ++j) {
            const double u = i / 4.0, v = j / 4.0;
            if (length(s.evaluate(u, v).p - (A.o + u * A.du + v * A.dv)) > 1e-9 * s.size()) return false;
        }
    const double g00 = dot(A.du, A.du), g01 = dot(A.du, A.dv), g11 = dot(A.dv, A.dv), det = g00 * g11 - g01 * g01;
    A.gram_inv[0][0] = g11 / det, A.gram_inv[0][1] = -g01 / det, A.gram_inv[1][0] = -g01 / det, A.gram_inv[1][1] = g00 / det;
    return true;
}

// Clips the segment a-b in (u, v) to the unit square (Liang-Barsky); false if it misses it.
bool clip_unit(std::array<double, 2>& a, std::array<double, 2>& b) {
    double t0 = 0, t1 = 1;
    for (int k = 0; k < 2; ++k) {
        const double d = b[k] - a[k];
        for (double bound : {0.0, 1.0}) {
            const double p = bound == 0.0 ? -d : d, r = bound == 0.0 ? a[k] : 1 - a[k];
            if (p == 0) {
                if (r < 0) return false;
                continue;
            }
            const double t = r / p;
            if (p < 0) t0 = std::max(t0, t);
            else t1 = std::min(t1, t);
        }
    }
    if (t0 > t1) return false;
    const std::array<double, 2> a0 = a;
    for (int k = 0; k < 2; ++k) a[k] = a0[k] + t0 * (b[k] - a0[k]), b[k] = a0[k] + t1 * (b[k] - a0[k]);
    return true;
}

}  // namespace

// A light at infinity and the occluders whose shadows it casts, by cells of the plane across its
// direction (each occluder in the cells its box covers there): a receiver asks only for those
// over its own box, not for every occluder of an interior of thousands.
struct DiscontinuityFinder::Distant {
    DistantSource source;
    Vec3 axis[2];        // of the plane across the direction
    double lo[2]{0, 0}, step[2]{1, 1};
    int cells[2]{0, 0};
    std::vector<std::vector<int>> occluders;  // per cell, scene indices
    double depth = 0;    // the occluders' extent along the direction (a penumbra's widening)

    std::array<double, 2> across(const Vec3& p) const { return {dot(p, axis[0]), dot(p, axis[1])}; }
    // The occluders over the box [lo, hi] of the plane (with repeats).
    std::vector<int> over(std::array<double, 2> a, std::array<double, 2> b) const {
        std::vector<int> out;
        int first[2], last[2];
        for (int k = 0; k < 2; ++k) {
            first[k] = std::clamp(int(std::floor((a[k] - lo[k]) / step[k])), 0, cells[k] - 1);
            last[k] = std::clamp(int(std::floor((b[k] - lo[k]) / step[k])), 0, cells[k] - 1);
            if (b[k] < lo[k] || a[k] > lo[k] + cells[k] * step[k]) return out;
        }
        for (int i = first[0]; i <= last[0]; ++i)
            for (int j = first[1]; j <= last[1]; ++j) {
                const auto& c = occluders[size_t(i) * cells[1] + j];
                out.insert(out.end(), c.begin(), c.end());
            }
        return out;
    }
};

// The occluders by cells of a grid over their boxes (each in the cells its box covers, about one
// occluder a cell): a receiver asks for those near its plane, or between it and an emitter, not
// for every occluder of an interior of thousands (the contact lines' loop over all of them was
// O(receivers x occluders)).
struct DiscontinuityFinder::Grid {
    Vec3 lo{0, 0, 0}, step{1, 1, 1};
    int cells[3]{1, 1, 1};
    std::vector<std::vector<int>> occluders;      // per cell, scene indices
    std::vector<std::array<Vec3, 2>> boxes;       // per scene index (of the occluders only)

    Grid(const Scene& scene, const std::vector<Polygonal>& polys) : boxes(scene.size()) {
        std::vector<int> kept;
        std::vector<Vec3> corners;  // of the occluders' boxes
        for (size_t o = 0; o < scene.size(); ++o) {
            if (!scene[o].occluder || polys[o].edges.empty()) continue;
            boxes[o] = box_of(polys[o].vertices);
            corners.insert(corners.end(), boxes[o].begin(), boxes[o].end());
            kept.push_back(int(o));
        }
        if (kept.empty()) return;
        const auto [all_lo, all_hi] = box_of(corners);
        const double extent[3] = {all_hi.x - all_lo.x, all_hi.y - all_lo.y, all_hi.z - all_lo.z};
        const double largest = std::max({extent[0], extent[1], extent[2], 1e-300});
        double volume = 1;
        for (double e : extent) volume *= std::max(e, 1e-3 * largest);
        const double side = std::cbrt(volume / double(kept.size()));
        double steps[3];
        for (int k = 0; k < 3; ++k) {
            cells[k] = std::clamp(int(std::ceil(extent[k] / side)), 1, 64);
            steps[k] = std::max(extent[k], 1e-3 * largest) / cells[k];
        }
        lo = all_lo, step = Vec3{steps[0], steps[1], steps[2]};
        occluders.resize(size_t(cells[0]) * cells[1] * cells[2]);
        for (const int o : kept) {
            int first[3], last[3];
            range(boxes[o][0], boxes[o][1], first, last);
            for (int i = first[0]; i <= last[0]; ++i)
                for (int j = first[1]; j <= last[1]; ++j)
                    for (int k = first[2]; k <= last[2]; ++k) occluders[(size_t(i) * cells[1] + j) * cells[2] + k].push_back(o);
        }
    }
    void range(const Vec3& a, const Vec3& b, int first[3], int last[3]) const {
        for (int k = 0; k < 3; ++k) {
            first[k] = std::clamp(int(std::floor((a[k] - lo[k]) / step[k])), 0, cells[k] - 1);
            last[k] = std::clamp(int(std::floor((b[k] - lo[k]) / step[k])), 0, cells[k] - 1);
        }
    }
    // The occluders whose boxes meet the box [a, b], by scene index.
    std::vector<int> within(const Vec3& a, const Vec3& b) const {
        std::vector<int> out;
        if (occluders.empty()) return out;
        int first[3], last[3];
        range(a, b, first, last);
        for (int i = first[0]; i <= last[0]; ++i)
            for (int j = first[1]; j <= last[1]; ++j)
                for (int k = first[2]; k <= last[2]; ++k)
                    for (const int o : occluders[(size_t(i) * cells[1] + j) * cells[2] + k]) {
                        const auto& [p, q] = boxes[o];
                        if (p.x <= b.x && q.x >= a.x && p.y <= b.y && q.y >= a.y && p.z <= b.z && q.z >= a.z) out.push_back(o);
                    }
        std::sort(out.begin(), out.end());
        out.erase(std::unique(out.begin(), out.end()), out.end());
        return out;
    }
};

std::vector<DistantSource> bright_world_sources(const std::vector<std::pair<Vec3, double>>& bright) {
    std::vector<size_t> order(bright.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return bright[x].second > bright[y].second; });
    double total = 0;
    for (const auto& b : bright) total += b.second;
    std::vector<char> taken(bright.size(), 0);
    std::vector<DistantSource> out;
    for (size_t i : order) {
        if (taken[i]) continue;
        const Vec3 centre = bright[i].first;
        double share = 0, spread = 0;
        for (size_t j : order) {
            const double cos_angle = std::clamp(dot(bright[j].first, centre), -1.0, 1.0);
            if (taken[j] || std::acos(cos_angle) > DiscontinuityFinder::kClusterAngle) continue;
            taken[j] = 1;
            share += bright[j].second;
            spread = std::max(spread, std::acos(cos_angle));
        }
        if (share >= DiscontinuityFinder::kMinShare * total)
            out.push_back({centre, 2 * spread});
    }
    return out;
}

DiscontinuityFinder::DiscontinuityFinder(const Scene& scene, std::vector<DistantSource> distant, const RayCaster* caster,
                                         DiscontinuityKinds kinds)
    : emitters_(scene.emitters()), scene_(&scene), caster_(caster), kinds_(kinds) {
    if (!kinds.events) distant.clear(), emitters_.clear();
    polys_.resize(scene.size());
    for (size_t i = 0; i < scene.size(); ++i)
        if (scene[i].occluder || scene[i].material.emits()) polys_[i] = polygonal_of(*scene[i].surface);
    grid_ = std::make_unique<Grid>(scene, polys_);
    for (DistantSource& source : distant) {
        Distant D;
        const Frame f = Frame::from_normal(source.direction);
        D.axis[0] = f.x, D.axis[1] = f.y;
        D.source = std::move(source);
        std::vector<std::pair<int, std::array<double, 4>>> boxes;  // occluder, box across
        double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300}, near = 1e300, far = -1e300;
        for (size_t o = 0; o < scene.size(); ++o) {
            if (!scene[o].occluder || polys_[o].edges.empty()) continue;
            std::array<double, 4> box{1e300, 1e300, -1e300, -1e300};
            for (const Vec3& v : polys_[o].vertices) {
                const auto c = D.across(v);
                for (int k = 0; k < 2; ++k) box[k] = std::min(box[k], c[k]), box[2 + k] = std::max(box[2 + k], c[k]);
                near = std::min(near, dot(v, D.source.direction)), far = std::max(far, dot(v, D.source.direction));
            }
            for (int k = 0; k < 2; ++k) lo[k] = std::min(lo[k], box[k]), hi[k] = std::max(hi[k], box[2 + k]);
            boxes.emplace_back(int(o), box);
        }
        if (boxes.empty()) continue;
        D.depth = far - near;
        // About one occluder a cell, at most 512 cells a side.
        const double extent[2] = {std::max(hi[0] - lo[0], 1e-12), std::max(hi[1] - lo[1], 1e-12)};
        const double side = std::sqrt(extent[0] * extent[1] / double(boxes.size()));
        for (int k = 0; k < 2; ++k) {
            D.lo[k] = lo[k];
            D.cells[k] = std::clamp(int(std::ceil(extent[k] / std::max(side, 1e-12))), 1, 512);
            D.step[k] = extent[k] / D.cells[k];
        }
        D.occluders.resize(size_t(D.cells[0]) * D.cells[1]);
        for (const auto& [o, box] : boxes) {
            const int i0 = std::clamp(int((box[0] - D.lo[0]) / D.step[0]), 0, D.cells[0] - 1);
            const int i1 = std::clamp(int((box[2] - D.lo[0]) / D.step[0]), 0, D.cells[0] - 1);
            const int j0 = std::clamp(int((box[1] - D.lo[1]) / D.step[1]), 0, D.cells[1] - 1);
            const int j1 = std::clamp(int((box[3] - D.lo[1]) / D.step[1]), 0, D.cells[1] - 1);
            for (int i = i0; i <= i1; ++i)
                for (int j = j0; j <= j1; ++j) D.occluders[size_t(i) * D.cells[1] + j].push_back(o);
        }
        distant_.push_back(std::move(D));
    }
}

DiscontinuityFinder::~DiscontinuityFinder() = default;
DiscontinuityFinder::DiscontinuityFinder(DiscontinuityFinder&&) noexcept = default;

ReceiverDiscontinuities DiscontinuityFinder::find(int surface, std::array<bool, 2> live, std::array<double, 2> tolerance,
                                                  size_t& rays) const {
    const Scene& scene = *scene_;
    ReceiverDiscontinuities out;
    Affine A;
    if (!affine_of(*scene[surface].surface, A)) {
        out.note = "not a plane with affine (u, v): discontinuities left to the probe";
        return out;
    }
    out.planar = true;
    const double size = scene[surface].surface->size(), flat = 1e-7 * size;
    auto height = [&](const Vec3& p) { return dot(p - A.o, A.n); };
    auto on_live_side = [&](double h) { return (h > flat && live[0]) || (h < -flat && live[1]); };
    // The segment p-q of (u, v) clipped to the surface: k -1 if it misses it (or is a point), 0 or
    // 1 if it is a parameter line u or v = `position` over `length` of the other parameter, 2 if
    // it is oblique.
    struct Segment {
        int k = -1;
        double position = 0, length = 0;
    };
    auto line_of_uv = [&](std::array<double, 2> p, std::array<double, 2> q) {
        Segment out;
        if (!clip_unit(p, q)) return out;
        if (std::abs(p[0] - q[0]) + std::abs(p[1] - q[1]) < 1e-9) return out;  // a point
        out.k = 2, out.length = std::hypot(p[0] - q[0], p[1] - q[1]);
        for (int k = 0; k < 2; ++k)
            if (std::abs(p[k] - q[k]) <= tolerance[k] && std::abs(p[1 - k] - q[1 - k]) > tolerance[1 - k])
                return Segment{k, 0.5 * (p[k] + q[k]), std::abs(p[1 - k] - q[1 - k])};
        return out;
    };
    auto line_of = [&](const Vec3& a, const Vec3& b) { return line_of_uv(A.uv(a), A.uv(b)); };
    // Records what line_of found as a line of the given order, if it is one.
    auto record = [&](const Segment& x, int order, double band = 0, double grade = 0) {
        if (x.k == 0 || x.k == 1) out.lines[x.k].push_back({x.position, order, band, x.length, grade});
        out.oblique += x.k == 2;
    };
    // The rays leave the receiver lifted off it (RayCaster::spawn): a node closer to a jump than
    // `lifts` times that lift gathers the other side's light. The band in each parameter that
    // keeps the nodes four times as far (none without a caster).
    auto lift_band = [&](double lifts) -> std::array<double, 2> {
        if (!caster_) return {0, 0};
        const double half = 4 * caster_->offset() * lifts;
        return {2 * half / length(A.du), 2 * half / length(A.dv)};
    };
    // The part of the line a-b (in (u, v), clipped) along which it bounds the light arriving
    // along `dir` from within `reach`: where one of the two points `offset` to either side is lit
    // and the other is not. Without a ray caster, all of it.
    auto bounds_light = [&](std::array<double, 2> a, std::array<double, 2> b, const Vec3& dir, double offset,
                            double reach = std::numeric_limits<double>::infinity()) {
        if (!caster_) return 1.0;
        const double du = b[0] - a[0], dv = b[1] - a[1], len = std::hypot(du, dv);
        const std::array<double, 2> across{-dv / len, du / len};
        const double half_span = 5 * std::min(tolerance[0], tolerance[1]);
        const int samples = std::clamp(int(std::ceil(len / half_span)) + 1, 3, 32);
        int bounding = 0;
        for (int i = 0; i < samples; ++i) {
            const double t = (i + 0.5) / samples;
            int lit = 0, seen = 0;
            for (const double side : {-1.0, 1.0}) {
                const double u = a[0] + t * du + side * offset * across[0], v = a[1] + t * dv + side * offset * across[1];
                if (u < 0 || u > 1 || v < 0 || v > 1) break;
                const Vec3 x = A.o + A.du * u + A.dv * v;
                ++rays, ++seen;
                lit += max_component(caster_->transmittance(caster_->spawn(x, A.n, dir), dir, 0, reach)) > 0;
            }
            bounding += seen == 2 && lit == 1;
        }
        return double(bounding) / samples;
    };
    // Contact lines: an occluder's feature edge on the receiver's plane with a face leaving it.
    // A node beside one is lift / tan(wedge angle) from the leaving face: closer, its lifted
    // point lies beyond the face, on the other side's light (a board leaning at 60 degrees on a
    // floor: the node beside its foot at 1/1000 of a span, 0.01 mm at 64 coefficients, saw the
    // lit room from inside the wedge). The line is a jump with a lift band.
    // Near contacts: the edges of an occluder's face parallel to the receiver a little off it, on
    // a side solved (a painting hung 1 cm off a wall, a rug over a floor). Under it the receiver
    // sees the room only through the gap, so across the face's outline its light falls from the
    // room's to the gap's within a few gap heights h (a half-plane at height h hides
    // (1 - x / sqrt(x^2 + h^2)) / 2 of the cosine-weighted hemisphere at x: 50% at the edge,
    // 15% at h, 5% at 2h; as much more inside): smoothed by spans wider than that, it darkened a
    // band around the outline (the textured interior's wall 26% dark two pixels from its
    // painting). The fall is continuous: each edge is a graded line, knots a gap height apart
    // across it (a jump there, its nodes a gap off the edge, read the fall's foot as the edge's
    // light: 1.3x at the edge). Only gaps up to a span: a wider fall the spline follows.
    const double span = std::min(length(A.du) * 10 * tolerance[0], length(A.dv) * 10 * tolerance[1]);
    // (The boxes asked of the grid are widened by the flat tolerance too.)
    const std::vector<Vec3> corners{A.o, A.o + A.du, A.o + A.dv, A.o + A.du + A.dv};
    const auto [near_lo, near_hi] = box_of(corners, kNearContactSpans * span + flat);
    for (const int o : grid_->within(near_lo, near_hi)) {
        const Poly& P = polys_[o];
        if (o == surface) continue;
        for (size_t e = 0; e < P.edges.size(); ++e) {
            const Vec3 &a = P.vertices[P.edges[e][0]], &b = P.vertices[P.edges[e][1]];
            const double ha = height(a), hb = height(b), gap = std::max(std::abs(ha), std::abs(hb));
            if (gap <= flat) {
                if (!kinds_.events) continue;
                bool leaves = false;
                double cot = 0;  // of the narrower wedge between a leaving face and the receiver
                for (const Vec3& n : P.edge_faces[e]) {
                    const double c = std::abs(dot(n, A.n));
                    if (c >= 1 - 1e-9) continue;
                    leaves = true;
                    cot = std::max(cot, c / std::sqrt(1 - c * c));
                }
                if (!leaves) continue;
                const Segment line = line_of(a, b);
                record(line, 0, line.k == 0 || line.k == 1 ? lift_band(std::max(1.0, std::min(cot, kMaxContactCot)))[line.k] : 0);
                continue;
            }
            if (!kinds_.near_contacts || std::min(std::abs(ha), std::abs(hb)) <= flat || (ha > 0) != (hb > 0) ||
                !on_live_side(ha) || gap > kNearContactSpans * span)
                continue;
            bool covers = false;  // a face along the edge lies parallel to the receiver
            for (const Vec3& n : P.edge_faces[e]) covers = covers || std::abs(dot(n, A.n)) >= kNearContactCos;
            if (!covers) continue;
            // Only where the face's outline bounds what covers the receiver: not between two books
            // side by side, whose backs cover the wall on both sides of the edge they share.
            std::array<double, 2> pa = A.uv(a), pb = A.uv(b);
            if (!clip_unit(pa, pb)) continue;
            Segment line = line_of_uv(pa, pb);
            if (line.k == 0 || line.k == 1) {
                const double fall = std::max(gap, caster_ ? 4 * caster_->offset() : 0.0);  // the rays' lift blurs a narrower one
                const double grade = fall / length(line.k == 0 ? A.du : A.dv);
                line.length *= bounds_light(pa, pb, ha > 0 ? A.n : -A.n, 2 * grade, 3 * fall);
                if (line.length > 0) record(line, 0, 0, grade);
            } else
                record(line, 0);
        }
    }
    // Occluders that can stand between the receiver and an emitter, nearest first.
    size_t pairs = 0;
    int skipped = 0;
    for (const int em : emitters_) {
        const Poly& E = polys_[em];
        if (em == surface) continue;
        if (E.edges.empty()) {
            if (out.note.empty()) out.note = "emitter '" + scene[em].surface->name() + "' is curved: its shadows left to the probe";
            continue;
        }
        double reach = 0;  // the emitter's farthest vertex on a live side
        for (const Vec3& v : E.vertices)
            if (on_live_side(height(v))) reach = std::max(reach, std::abs(height(v)));
        if (!(reach > 0)) continue;
        const bool one_sided = E.planar && !scene[em].material.two_sided_emission;
        std::vector<std::pair<double, size_t>> between;
        // Only occluders within the box of the receiver and the emitter can stand between them.
        std::vector<Vec3> both = corners;
        both.insert(both.end(), E.vertices.begin(), E.vertices.end());
        const auto [both_lo, both_hi] = box_of(both, flat);
        for (const int o : grid_->within(both_lo, both_hi)) {
            const Poly& P = polys_[o];
            if (o == surface || o == em) continue;
            bool near = false, front = !one_sided;
            double closest = 1e300;
            for (const Vec3& v : P.vertices) {
                const double h = height(v);
                near = near || (std::abs(h) < reach && (std::abs(h) <= flat || on_live_side(h)));
                if (one_sided) front = front || dot(v - E.vertices[0], E.normal) > flat;
                closest = std::min(closest, std::abs(h));
            }
            if (near && front) between.emplace_back(closest, o);
        }
        std::sort(between.begin(), between.end());
        // The point x seen from y, projected onto the receiver's plane (x between y and it).
        auto project = [&](const Vec3& y, const Vec3& x, Vec3& out_p) {
            const double hy = height(y), hx = height(x);
            if (!on_live_side(hy) || std::abs(hx) >= std::abs(hy) || (std::abs(hx) > flat && hx * hy < 0)) return false;
            out_p = y + (x - y) * (hy / (hy - hx));
            return true;
        };
        // Whether the occluder's shadow can reach the surface: the box of its vertices seen from
        // the emitter's vertices, in (u, v), meets the unit square (kept when a vertex does not
        // project, e.g. one above an emitter vertex's height).
        auto shadow_reaches = [&](const Poly& P) {
            double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
            for (const Vec3& y : E.vertices)
                for (const Vec3& x : P.vertices) {
                    Vec3 q;
                    if (!project(y, x, q)) return true;
                    const auto uv = A.uv(q);
                    for (int k = 0; k < 2; ++k) lo[k] = std::min(lo[k], uv[k]), hi[k] = std::max(hi[k], uv[k]);
                }
            return lo[0] <= 1 + tolerance[0] && hi[0] >= -tolerance[0] && lo[1] <= 1 + tolerance[1] && hi[1] >= -tolerance[1];
        };
        for (const auto& [unused, o] : between) {
            const Poly& P = polys_[o];
            if (!shadow_reaches(P)) continue;
            const size_t cost = E.vertices.size() * P.edges.size() + P.vertices.size() * E.edges.size();
            if (pairs + cost > kMaxPairs) {
                ++skipped;
                continue;
            }
            pairs += cost;
            // EV: an emitter vertex and an occluder edge; a kink where an emitter edge at the
            // vertex is parallel to the occluder edge (the whole emitter edge then meets it).
            // An edge whose shadow boundaries from all the emitter's vertices lie on one parameter
            // line within a fifth of a span (an edge a few millimetres off the receiver: a board
            // leaning on a wall) draws a penumbra narrower than the spline resolves: at its scale
            // a jump, one line of order 0 (as a contact line) instead of kinks the spline would
            // blur light across (the wall's light leaked under the board, 1.3x in the wedge).
            for (const auto& e : P.edges) {
                std::vector<std::pair<Segment, int>> events;  // and its order
                for (size_t v = 0; v < E.vertices.size(); ++v) {
                    Vec3 a, b;
                    if (!project(E.vertices[v], P.vertices[e[0]], a) || !project(E.vertices[v], P.vertices[e[1]], b)) continue;
                    int order = 2;
                    for (int f : E.edges_at[v])
                        if (parallel(E.vertices[E.edges[f][1]] - E.vertices[E.edges[f][0]], P.vertices[e[1]] - P.vertices[e[0]])) order = 1;
                    events.emplace_back(line_of(a, b), order);
                }
                const int axis = events.empty() ? -1 : events[0].first.k;
                bool narrow = events.size() == E.vertices.size() && (axis == 0 || axis == 1);
                double lo = 1e300, hi = -1e300, length = 0;
                for (const auto& [event, order] : events) {
                    narrow = narrow && event.k == axis;
                    lo = std::min(lo, event.position), hi = std::max(hi, event.position);
                    length = std::max(length, event.length);
                }
                if (narrow && hi - lo <= 2 * tolerance[axis]) {
                    record(Segment{axis, 0.5 * (lo + hi), length}, 0, hi - lo);
                    continue;
                }
                for (const auto& [event, order] : events) record(event, order);
            }
            // VE: an occluder vertex and an emitter edge.
            for (size_t w = 0; w < P.vertices.size(); ++w)
                for (const auto& e : E.edges) {
                    Vec3 a, b;
                    if (std::abs(height(P.vertices[w])) <= flat) continue;  // on the receiver: the contact line's end
                    if (!project(E.vertices[e[0]], P.vertices[w], a) || !project(E.vertices[e[1]], P.vertices[w], b)) continue;
                    int order = 2;
                    for (int f : P.edges_at[w])
                        if (parallel(P.vertices[P.edges[f][1]] - P.vertices[P.edges[f][0]], E.vertices[e[1]] - E.vertices[e[0]])) order = 1;
                    record(line_of(a, b), order);
                }
        }
    }
    // Lights at infinity: an occluder edge's shadow is its projection along the disc's rim where
    // a plane through the edge touches the cone of the disc's directions, one on each side: the
    // penumbra between them; a jump where it is narrower than the tolerance.
    for (const Distant& D : distant_) {
        const Vec3& d = D.source.direction;
        const double dn = dot(d, A.n), r = 0.5 * D.source.angle;
        // (Grazing: part of the disc below the horizon, little light, no clean edge.)
        if (std::abs(dn) <= std::sin(r) + 1e-6 || !live[dn > 0 ? 0 : 1]) continue;
        const double sign = dn > 0 ? 1 : -1;
        // The receiver's box across the light, widened by the penumbra's reach.
        std::array<double, 2> lo{1e300, 1e300}, hi{-1e300, -1e300};
        for (const Vec3& c : {A.o, A.o + A.du, A.o + A.dv, A.o + A.du + A.dv}) {
            const auto x = D.across(c);
            for (int k = 0; k < 2; ++k) lo[k] = std::min(lo[k], x[k]), hi[k] = std::max(hi[k], x[k]);
        }
        const double widen = std::tan(r) * D.depth;
        for (int k = 0; k < 2; ++k) lo[k] -= widen, hi[k] += widen;
        std::vector<int> near = D.over(lo, hi);
        std::sort(near.begin(), near.end());
        near.erase(std::unique(near.begin(), near.end()), near.end());
        std::vector<std::pair<double, int>> between;  // nearest first
        for (const int o : near) {
            if (o == surface) continue;
            double closest = 1e300;
            for (const Vec3& v : polys_[o].vertices)
                if (sign * height(v) > flat) closest = std::min(closest, sign * height(v));
            if (closest < 1e300) between.emplace_back(closest, o);
        }
        std::sort(between.begin(), between.end());
        // The shadow rays' lift moves a sun's shadow edge by the lift times the tangent of its
        // incidence: nodes beside a jump closer than that took the other side's light (adaptive
        // knots put spans of millimetres there).
        const std::array<double, 2> lifted_band = lift_band(std::sqrt(std::max(0.0, 1 - dn * dn)) / std::abs(dn));
        // The edge's shadow along `dir` as (u, v) segment ends, clipped: false if it has none.
        auto shadow = [&](const Vec3& a, const Vec3& b, const Vec3& dir, std::array<double, 2>& pa,
                          std::array<double, 2>& pb) {
            const double down = sign * dot(dir, A.n);
            if (!(down > 1e-9)) return false;
            pa = A.uv(a - dir * (sign * height(a) / down));
            pb = A.uv(b - dir * (sign * height(b) / down));
            return clip_unit(pa, pb) && std::abs(pa[0] - pb[0]) + std::abs(pa[1] - pb[1]) >= 1e-9;
        };
        for (const auto& [unused, o] : between) {
            const Poly& P = polys_[o];
            const size_t cost = P.edges.size() * (r > 0 ? 2 : 1);
            if (pairs + cost > kMaxPairs) {
                ++skipped;
                continue;
            }
            pairs += cost;
            for (const auto& e : P.edges) {
                Vec3 a = P.vertices[e[0]], b = P.vertices[e[1]];
                const double ha = sign * height(a), hb = sign * height(b);
                if (ha <= flat && hb <= flat) continue;  // on the receiver (a contact line) or behind it
                if (ha < 0) a = a + (b - a) * (ha / (ha - hb));
                if (hb < 0) b = b + (a - b) * (hb / (hb - ha));
                const Vec3 along = normalize(b - a);
                // The rim's grazing directions: in the plane through the edge at angle r from d.
                std::vector<Vec3> rims;
                if (r == 0) rims.push_back(d);
                else {
                    const Vec3 off = d - along * dot(d, along);
                    const double s = length(off);
                    if (s <= std::sin(r) + 1e-9) continue;  // the edge points into the disc
                    const Vec3 x = off / s, y = cross(along, x);
                    for (const double side : {-1.0, 1.0}) {
                        const double c = side * std::sin(r) / s;
                        const Vec3 normal = x * c + y * std::sqrt(1 - c * c);
                        rims.push_back(normalize(d - normal * dot(d, normal)));  // where the plane touches the cone
                    }
                }
                struct Rim {
                    std::array<double, 2> a, b;
                    Segment line;
                    Vec3 dir;
                };
                std::vector<Rim> found;
                for (const Vec3& w : rims) {
                    Rim rim{{}, {}, {}, w};
                    if (!shadow(a, b, w, rim.a, rim.b)) continue;
                    rim.line = line_of_uv(rim.a, rim.b);
                    found.push_back(rim);
                }
                if (found.empty()) continue;
                const int k = found[0].line.k;
                const bool narrow = found.size() == rims.size() && (k == 0 || k == 1) &&
                                    std::all_of(found.begin(), found.end(), [&](const Rim& x) {
                                        return x.line.k == k && std::abs(x.line.position - found[0].line.position) <= 2 * tolerance[k];
                                    });
                // Its length: the part of it that bounds light (a window sill's shadow across
                // the floor only where the window is).
                if (narrow) {
                    // One jump, checked along the centre direction beyond the penumbra's half.
                    Segment jump{k, 0, found[0].line.length};
                    double band = 0;
                    for (const Rim& x : found) jump.position += x.line.position / found.size();
                    for (const Rim& x : found)  // (at its widest: a penumbra widens away from its edge)
                        band = std::max({band, 2 * std::abs(x.a[k] - jump.position), 2 * std::abs(x.b[k] - jump.position)});
                    band = std::max(band, lifted_band[k]);
                    jump.length *= bounds_light(found[0].a, found[0].b, d, 1.5 * tolerance[k]);
                    if (jump.length > 0) record(jump, 0, band);
                    continue;
                }
                for (Rim& x : found) {
                    x.line.length *= bounds_light(x.a, x.b, x.dir, 0.5 * std::min(tolerance[0], tolerance[1]));
                    if (x.line.length > 0) record(x.line, 1);
                }
            }
        }
    }
    if (skipped) {
        std::ostringstream why;
        why << (out.note.empty() ? "" : out.note + "; ") << skipped << " farther occluders not searched (over " << kMaxPairs
            << " vertex-edge pairs)";
        out.note = why.str();
    }
    return out;
}

KnotVector discontinuity_knots(std::vector<DiscontinuityLine> lines, int num_coeffs, int degree, double a, double b,
                               const std::vector<double>& density, std::vector<DiscontinuityLine>& placed) {
    placed.clear();
    const int inner = num_coeffs - degree - 1;
    const double span = (b - a) / std::max(inner + 1, 1);
    // Lines at the ends are the clamped ends' knots already; close ones are one line.
    std::sort(lines.begin(), lines.end(), [](const DiscontinuityLine& x, const DiscontinuityLine& y) { return x.position < y.position; });
    std::vector<DiscontinuityLine> merged;
    for (const DiscontinuityLine& l : lines) {
        if (!(l.position > a + 0.2 * span && l.position < b - 0.2 * span)) continue;
        if (!merged.empty() && l.position - merged.back().position < 0.2 * span) {
            DiscontinuityLine& m = merged.back();
            m.order = std::min(m.order, l.order);
            m.band = std::max(m.band, l.band);
            m.length = std::min(m.length + l.length, 1.0);
            m.grade = m.grade > 0 && l.grade > 0 ? std::max(m.grade, l.grade) : 0;  // a jump among them stays one
        } else
            merged.push_back(l);
    }
    // At most half the inner knots go to lines, the lowest orders (the strongest) first.
    std::vector<size_t> by_order(merged.size());
    std::iota(by_order.begin(), by_order.end(), 0);
    std::stable_sort(by_order.begin(), by_order.end(), [&](size_t x, size_t y) {
        return merged[x].order != merged[y].order ? merged[x].order < merged[y].order : merged[x].length > merged[y].length;
    });
    std::vector<std::pair<double, int>> fixed;  // position, multiplicity
    int used = 0;
    auto taken = [&](double x, double within) {
        return std::any_of(fixed.begin(), fixed.end(), [&](const auto& f) { return std::abs(f.first - x) <= within; });
    };
    for (size_t k : by_order) {
        const DiscontinuityLine& l = merged[k];
        if (l.grade > 0) {  // its knots inside [a, b], apart from those placed
            std::vector<double> xs;
            for (const int o : {0, -1, 1, -2, 2}) {
                const double x = l.position + o * l.grade;
                if (x > a + 0.5 * l.grade && x < b - 0.5 * l.grade && !taken(x, 0.25 * l.grade)) xs.push_back(x);
            }
            if (used + int(xs.size()) > inner / 2) continue;
            for (const double x : xs) fixed.emplace_back(x, 1);
            used += int(xs.size());
            placed.push_back(l);
            continue;
        }
        // Only where the light is less smooth than the spline between knots (C^(degree-1)): a
        // D2 line under a quadratic changes the error's constant, not its order, and its knot
        // is better spent by the probe.
        const int m = degree + 1 - l.order;
        if (l.order >= std::max(degree, 1) || used + m > inner / 2 || taken(l.position, 1e-9 * (b - a))) continue;
        fixed.emplace_back(l.position, m);
        used += m;
        placed.push_back(merged[k]);
    }
    std::sort(fixed.begin(), fixed.end());
    // The density's integral from a to x (uniform if none was given).
    const size_t cells = density.size();
    std::vector<double> cumulative(cells + 1, 0.0);
    for (size_t k = 0; k < cells; ++k) cumulative[k + 1] = cumulative[k] + density[k];
    auto mass = [&](double x) {
        const double s = (x - a) / (b - a);
        if (cells == 0) return s;
        const double c = std::clamp(s * cells, 0.0, double(cells));
        const size_t k = std::min(size_t(c), cells - 1);
        return cumulative[k] + (c - k) * density[k];
    };
    auto inverse = [&](double target, double lo, double hi) {  // x in [lo, hi] with mass(x) = target
        for (int it = 0; it < 60; ++it) {
            const double mid = 0.5 * (lo + hi);
            (mass(mid) < target ? lo : hi) = mid;
        }
        return 0.5 * (lo + hi);
    };
    // The remaining knots go to the gaps by their share of the density (largest remainders).
    std::vector<double> bounds{a};
    for (const auto& f : fixed) bounds.push_back(f.first);
    bounds.push_back(b);
    const int rest = inner - used;
    const size_t gaps = bounds.size() - 1;
    const double total = mass(b) - mass(a);
    std::vector<int> count(gaps, 0);
    std::vector<std::pair<double, size_t>> remainder;
    int given = 0;
    for (size_t g = 0; g < gaps; ++g) {
        const double share = rest * (mass(bounds[g + 1]) - mass(bounds[g])) / total;
        count[g] = int(std::floor(share));
        given += count[g];
        remainder.emplace_back(share - count[g], g);
    }
    std::sort(remainder.rbegin(), remainder.rend());
    for (int k = 0; k < rest - given; ++k) ++count[remainder[size_t(k) % gaps].second];
    std::vector<double> t(degree + 1, a);
    for (size_t g = 0; g < gaps; ++g) {
        const double m0 = mass(bounds[g]), m1 = mass(bounds[g + 1]);
        for (int j = 1; j <= count[g]; ++j) t.push_back(inverse(m0 + (m1 - m0) * j / (count[g] + 1), bounds[g], bounds[g + 1]));
        if (g + 1 < gaps) t.insert(t.end(), fixed[g].second, fixed[g].first);
    }
    t.insert(t.end(), degree + 1, b);
    return KnotVector(std::move(t), degree);
}

}  // namespace bsgi
