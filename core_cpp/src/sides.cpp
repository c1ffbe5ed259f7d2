#include "bsgi/sides.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <stdexcept>

#include "bsgi/cosine_rule.h"
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

constexpr int kRays = kTheta * kPhi;
// A checked ray end that carries light (sees light directly, or lit cells through enough rays):
// lit cells stay lit, so it is never checked again.
constexpr int32_t kNotChecked = -1, kCarries = -2;
// What lights a point directly: scene surface e (an emitter), scene.size() + l (distant light
// l), scene.size() + the number of distant lights (the world); kNoLight: nothing.
constexpr int kNoLight = -1;

// Records of the cells a point's probe rays reach, with their counts of rays: what each checked
// ray end sees, and where each dark cell's own rays end. Most of the probe's memory at a
// thousand objects was these as 4-byte words (21 kB a surface of (cell, rays) pairs, 4 kB of
// ends); a record here is a varint count, then per cell the varint step from the previous cell
// id (sorted: a point's rays land on a few surfaces, so steps are small) and its rays in a byte
// (at most kRays), padded to 4 bytes so that an int32 indexes 8 GB, in chunks of 64 kB
// (a growing vector would hold up to twice its size). A record is dropped once its end carries
// light or its cell is lit (neither is asked again), and the pool compacted in place when a
// third of it is dropped.
class ReachedCells {
public:
    // Appends to `out` the record of the sorted cells[0, m), a cell repeated once per ray.
    static void encode(const uint32_t* cells, size_t m, std::vector<uint8_t>& out) {
        size_t distinct = 0;
        for (size_t r = 0; r < m; ++r) distinct += r == 0 || cells[r] != cells[r - 1];
        put(out, distinct);
        uint32_t previous = 0;
        for (size_t r = 0; r < m;) {
            size_t next = r;
            while (next < m && cells[next] == cells[r]) ++next;
            put(out, cells[r] - previous);
            out.push_back(uint8_t(next - r));
            previous = cells[r];
            r = next;
        }
    }
    // f(cell, rays) for each cell of the record starting at `record` (an encoded one).
    template <class F>
    static void for_each(const uint8_t* record, F&& f) {
        uint32_t count = uint32_t(get(record)), cell = 0;
        for (uint32_t j = 0; j < count; ++j) {
            cell += uint32_t(get(record));
            f(cell, uint32_t(*record++));
        }
    }
    // The bytes of the record starting at `record`.
    static size_t size_of(const uint8_t* record) {
        const uint8_t* at = record;
        const size_t count = get(at);
        for (size_t j = 0; j < count; ++j) get(at), ++at;
        return size_t(at - record);
    }

    // Stores an encoded record; returns its index.
    int32_t add(const uint8_t* record, size_t size) {
        if (chunks_.empty() || used_ + size > kChunkBytes) {
            if (chunks_.size() >= size_t(INT32_MAX) / kChunkWords)
                throw std::length_error("the sides probe's record of what ray ends see passed 8 GB");
            chunks_.push_back(std::make_unique<uint8_t[]>(kChunkBytes));
            used_ = 0;
        }
        const size_t at = (chunks_.size() - 1) * kChunkBytes + used_;
        std::copy(record, record + size, chunks_.back().get() + used_);
        used_ += padded(size);
        return int32_t(at / 4);
    }
    const uint8_t* operator[](int32_t index) const {
        return chunks_[size_t(index) / kChunkWords].get() + 4 * (size_t(index) % kChunkWords);
    }
    void drop(int32_t index) { dropped_ += padded(size_of((*this)[index])); }
    // Whether at least a third of the pool (and a chunk) is dropped records.
    bool mostly_dropped() const { return dropped_ >= kChunkBytes && 3 * dropped_ >= bytes(); }
    // Moves the records still indexed down over the dropped ones, in place (the pool is most of
    // the probe's memory: a copy would double it): for_each_index(g) calls g(index) on each
    // index still held, by reference, which gets the record's new index. Returns the bytes it
    // held beside the pool while it ran.
    template <class ForEachIndex>
    size_t compact(ForEachIndex&& for_each_index) {
        std::vector<int32_t*> live;
        for_each_index([&](int32_t& index) { live.push_back(&index); });
        std::sort(live.begin(), live.end(), [](const int32_t* a, const int32_t* b) { return *a < *b; });
        size_t chunk = 0, used = 0;
        for (int32_t* index : live) {
            const uint8_t* record = (*this)[*index];
            const size_t size = padded(size_of(record));
            if (used + size > kChunkBytes) ++chunk, used = 0;
            uint8_t* to = chunks_[chunk].get() + used;
            std::memmove(to, record, size);  // to <= record: records only move down
            *index = int32_t((chunk * kChunkBytes + used) / 4);
            used += size;
        }
        chunks_.resize(live.empty() ? 0 : chunk + 1);
        used_ = used;
        dropped_ = 0;
        return live.capacity() * sizeof(live[0]);
    }
    // The bytes held.
    size_t capacity() const { return chunks_.size() * kChunkBytes + chunks_.capacity() * sizeof(chunks_[0]); }

private:
    static size_t padded(size_t size) { return (size + 3) / 4 * 4; }
    static void put(std::vector<uint8_t>& out, size_t value) {
        for (; value >= 0x80; value >>= 7) out.push_back(uint8_t(value | 0x80));
        out.push_back(uint8_t(value));
    }
    static size_t get(const uint8_t*& at) {
        size_t value = 0;
        for (int shift = 0;; shift += 7) {
            const uint8_t byte = *at++;
            value |= size_t(byte & 0x7f) << shift;
            if (byte < 0x80) return value;
        }
    }
    // Bytes stored (with the unused ends of full chunks).
    size_t bytes() const { return chunks_.empty() ? 0 : (chunks_.size() - 1) * kChunkBytes + used_; }
    static constexpr size_t kChunkBytes = size_t(1) << 16, kChunkWords = kChunkBytes / 4;
    std::vector<std::unique_ptr<uint8_t[]>> chunks_;
    size_t used_ = 0, dropped_ = 0;
};

// What the centre of one cell of one side sees: light, and whether its rays reach surfaces. A
// cell not lit directly asks its rays' ends whether they carry light; a large scene's probe
// would hold millions of them, so the rays are cast again when asked (the probe is
// deterministic), at a pass of the fixed point where a cell they depend on was lit. Cells are
// numbered (surface * 2 + side) * kCells + cell.
// A view is 20 bytes (what it holds is in the probe's pools, freed once it is lit): there are
// 72 a surface.
struct CellView {
    int32_t light = kNoLight;
    // If it asks: the record (in the probe's ReachedCells) of the receiving cells its rays end
    // in, and when it was last asked (the count of cells lit before; -1: never). Until one of
    // these or of its checked ends' cells is lit, asking again would give the same answer.
    int32_t ends = -1;
    int32_t asked_at = -1;
    // Once an end of its rays is asked: its block of kRays in the probe's `checks`, per ray
    // kNotChecked, kCarries, or the record of the cells that end's own probe rays reach.
    int32_t checked = -1;
    bool asks = false;     // in the surface's domain and not lit directly
    bool escaped = false;  // some rays reach no surface
    bool others = false;   // some rays reach another surface than the one probed
};

// Why a cell is lit: it emits, receives light directly (`source` a light as above) or
// receives light reflected by scene surface `source`.
struct Reason {
    enum Kind : int8_t { kDark, kEmits, kDirect, kReflected } kind = kDark;
    int32_t source = 0;
};

int cell_of(double u, double v) {
    const int a = std::clamp(int(u * kPoints), 0, kPoints - 1), b = std::clamp(int(v * kPoints), 0, kPoints - 1);
    return a * kPoints + b;
}

// The probe's cosine-weighted set on the side of normal n = +-frame.z, turned about the normal
// by `turn` (a fraction of the azimuth step): each cell turns its set by its own amount, so that
// the cells' rays do not line up with the edges of boxes made of patches, where a ray may slip
// between two patches that meet. The directions go in the cosine rule's tiles of neighbours
// (tile_order), traced together in packets. The turn is one rotation of them all: a sine and
// cosine a point rather than a ray.
struct ProbeSet {
    std::array<double, kRays> cos_t, sin_t, cos_phi, sin_phi;
    ProbeSet() {
        const std::vector<std::pair<int, int>> order = tile_order(kTheta, kPhi);
        for (int k = 0; k < kRays; ++k) {
            const auto [row, column] = order[size_t(k)];
            const double w = (row + 0.5) / kTheta, phi = 2 * kPi * column / kPhi;
            cos_t[k] = std::sqrt(w), sin_t[k] = std::sqrt(1 - w);
            cos_phi[k] = std::cos(phi), sin_phi[k] = std::sin(phi);
        }
    }
};
void probe_directions(const SurfacePoint& p, int side, double turn, std::array<Vec3, kRays>& dirs) {
    static const ProbeSet set;
    const double c = std::cos(2 * kPi * turn / kPhi), s = std::sin(2 * kPi * turn / kPhi);
    for (int k = 0; k < kRays; ++k) {
        const double cos_phi = set.cos_phi[k] * c - set.sin_phi[k] * s, sin_phi = set.sin_phi[k] * c + set.cos_phi[k] * s;
        dirs[k] = p.frame.to_world({set.sin_t[k] * cos_phi, set.sin_t[k] * sin_phi, side ? -set.cos_t[k] : set.cos_t[k]});
    }
}

// The first surface a probe ray meets that is not a window pane, from the ray's first hit:
// light passes panes, so the probe looks through them (escaped past kMaxPanes panes, as the
// gathering gives up there).
SurfaceHit past_panes(const RayCaster& caster, SurfaceHit hit, const Vec3& dir) {
    for (int k = 0; k < RayCaster::kMaxPanes; ++k) {
        if (hit.surface < 0 || !caster.pane(hit.surface)) return hit;
        hit = caster.closest_hit(caster.spawn(hit.p, hit.frame.z, dir), dir);
    }
    return hit.surface < 0 || !caster.pane(hit.surface) ? hit : SurfaceHit{};
}

// The probe's rays from point p on `side`, cast a packet at a time as they are read: their
// directions and the first surfaces they meet that are not panes. The questions the probe asks
// of a point's rays (does one escape to the world, do two reach lit cells) are often answered
// before the last packet.
class ProbeRays {
public:
    static constexpr int kPacket = 16;  // the ray scene traces packets of 16 (embree_scene.cpp)
    ProbeRays(const RayCaster& caster, const SurfacePoint& p, int side, double turn) : caster_(caster) {
        probe_directions(p, side, turn, dirs_);
        origin_ = caster.spawn(p.p, p.frame.z, dirs_[0]);
    }
    const Vec3& dir(int k) const { return dirs_[size_t(k)]; }
    const SurfaceHit& hit(int k) {
        while (k >= cast_) {
            const int m = std::min(kPacket, kRays - cast_);
            caster_.closest_hits_from(origin_, &dirs_[size_t(cast_)], size_t(m), &hits_[size_t(cast_)]);
            for (int r = cast_; r < cast_ + m; ++r) hits_[size_t(r)] = past_panes(caster_, hits_[size_t(r)], dirs_[size_t(r)]);
            cast_ += m;
        }
        return hits_[size_t(k)];
    }

private:
    const RayCaster& caster_;
    Vec3 origin_;
    std::array<Vec3, kRays> dirs_;
    std::array<SurfaceHit, kRays> hits_;
    int cast_ = 0;
};

uint32_t end_cell(const SurfaceHit& hit, const Vec3& dir) {
    return uint32_t((2 * hit.surface + (dot(dir, hit.frame.z) < 0 ? 0 : 1)) * kCells + cell_of(hit.u, hit.v));
}

// The centre of cell c of surface i and the turn of its probe rays' set.
SurfacePoint cell_centre(const Surface& surface, int c) {
    return surface.evaluate((c / kPoints + 0.5) / kPoints, (c % kPoints + 0.5) / kPoints);
}
double cell_turn(int i, int c, int side) { return std::fmod((2 * (i * kCells + c) + side + 1) * 0.6180339887498949, 1.0); }

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
            if (stop > 0 && max_component(caster.transmittance(origin, segment, 0.0, stop)) > 0) return true;
        }
    return false;
}

int world_light(const Scene& scene) { return int(scene.size() + scene.distant_lights().size()); }

std::string light_name(const Scene& scene, int light) {
    const int n = int(scene.size());
    if (light < n) return "light from '" + scene[light].surface->name() + "'";
    if (light < world_light(scene)) return "light from '" + scene.distant_lights()[light - n].name + "'";
    return "world light";
}

// What lights point p of surface i on a side directly (`emitters`, then distant lights; not the
// world, which the caller finds with the rays it casts anyway): a light as above, or kNoLight.
int direct_light(const Scene& scene, const std::vector<int>& emitters, const RayCaster& caster, int i,
                 const SurfacePoint& p, int side) {
    const Vec3 n = side ? -p.frame.z : p.frame.z;
    for (const int e : emitters)
        if (e != i && sees_emitter(caster, p, n, scene[e])) return e;
    const std::vector<DistantLight>& distant = scene.distant_lights();
    for (size_t l = 0; l < distant.size(); ++l)
        if (dot(distant[l].direction, n) > 0 &&
            max_component(caster.transmittance(caster.spawn(p.p, p.frame.z, distant[l].direction), distant[l].direction)) > 0)
            return int(scene.size() + l);
    return kNoLight;
}

// The views of the cells of one side; a view that asks gets its ends' record appended to
// `records`, and `ends` its place there (the caller moves it to the probe's pool).
std::vector<CellView> probe_side(const Scene& scene, const std::vector<int>& emitters, const RayCaster& caster, int i,
                                 int side, std::vector<uint8_t>& records) {
    std::vector<CellView> cells(kCells);
    const Surface& surface = *scene[i].surface;
    std::array<uint32_t, kRays> ends;
    for (int c = 0; c < kCells; ++c) {
        CellView& view = cells[c];
        size_t m = 0;
        if (!surface.in_domain((c / kPoints + 0.5) / kPoints, (c % kPoints + 0.5) / kPoints)) continue;
        const SurfacePoint p = cell_centre(surface, c);
        view.light = direct_light(scene, emitters, caster, i, p, side);
        ProbeRays rays(caster, p, side, cell_turn(i, c, side));
        for (int k = 0; k < kRays; ++k) {
            // A lit cell's rays tell only whether it sees out of the side (for a two-sided
            // emitter: whether its back encloses its light); a dark side's message reads them.
            if (view.light != kNoLight && !scene[i].material.two_sided_emission) break;
            const Vec3& dir = rays.dir(k);
            const SurfaceHit& hit = rays.hit(k);
            if (hit.surface < 0) {
                view.escaped = true;
                if (scene.has_world() && view.light == kNoLight) view.light = world_light(scene);
                continue;
            }
            view.others |= hit.surface != i;
            if (scene[hit.surface].receiver) ends[m++] = end_cell(hit, dir);
        }
        view.asks = view.light == kNoLight;
        if (!view.asks) continue;
        std::sort(ends.begin(), ends.begin() + m);
        view.ends = int32_t(records.size());
        ReachedCells::encode(ends.data(), m, records);
    }
    return cells;
}

// The blocks of checked ray ends of cells (CellView::checked), in a deque: a vector would hold
// up to twice what it needs as it grows.
using CheckedEnds = std::deque<std::array<int32_t, kRays>>;

// What the probe holds at its end, its peak: the cells' views with what their rays' ends see,
// and each cell's reason. A heap block costs its capacity and about 16 bytes.
size_t held_bytes(const std::vector<std::array<std::vector<CellView>, 2>>& views, const std::vector<Reason>& why,
                  const std::vector<int32_t>& lit_as, const ReachedCells& seen, const CheckedEnds& checks,
                  const std::vector<int32_t>& free_checks) {
    constexpr size_t kBlock = 16;
    auto block = [](const auto& v) { return v.capacity() * sizeof(v[0]) + (v.capacity() ? kBlock : 0); };
    // A deque's blocks hold one block of checked ends each (512 bytes or less) and a pointer.
    const size_t checked = checks.size() * (sizeof(checks[0]) + kBlock + sizeof(void*));
    size_t bytes = block(views) + block(why) + block(lit_as) + seen.capacity() + kBlock + checked + block(free_checks);
    for (const auto& surface : views)
        for (const std::vector<CellView>& cells : surface) bytes += block(cells);
    return bytes;
}

}  // namespace

// The probe's state between calls: the views of its part's cells, what their rays' ends see,
// and which cells of the whole scene are lit (its own, and those other parts sent).
struct SidesProbe::Impl {
    const Scene& scene;
    const RayCaster& caster;
    SolverSettings settings;
    int part, parts;
    std::vector<SurfaceSides> out;
    std::vector<int> probed;  // both sides of every opaque receiver of this part
    std::vector<int> emitters;
    std::vector<std::array<std::vector<CellView>, 2>> views;
    // What checked ray ends see, and the cells' ends: see ReachedCells.
    ReachedCells seen;
    // The cells' blocks of checked ends (CellView::checked), those of lit cells free for others.
    CheckedEnds checks;
    std::vector<int32_t> free_checks;
    // Per cell of the scene: what lit it first (kDark: not lit); for a cell another part lit,
    // kReflected by its own surface (only a part's own cells' reasons are read).
    std::vector<Reason> why;
    // The order in which cells were lit (1, 2, ...; 0: lit from the start or dark): a view asked
    // after the last cell it depends on was lit would give the same answer.
    std::vector<int32_t> lit_as;
    int32_t lit_count = 0;
    std::vector<uint32_t> fresh;  // own cells lit since settle() last returned
    // The most the probe held before the end: at a compaction of `seen`, with the compaction's list.
    size_t peak = 0;

    Impl(const Scene& scene_, const RayCaster& caster_, const SolverSettings& settings_, int part_, int parts_);
    bool lit(size_t id) const { return why[id].kind != Reason::kDark; }
    // f(index) on each record of `seen` a view holds, by reference: its ends', its checked ends'.
    template <class View, class F>
    void for_each_record(View& view, F&& f) {
        if (view.ends >= 0) f(view.ends);
        if (view.checked >= 0)
            for (int32_t& checked : checks[size_t(view.checked)])
                if (checked >= 0) f(checked);
    }
    // A view never asked again (its cell lit) gives back its records and its block of checked ends.
    void release(CellView& view) {
        for_each_record(view, [&](int32_t index) { seen.drop(index); });
        view.ends = -1;
        if (view.checked >= 0) free_checks.push_back(view.checked), view.checked = -1;
    }
    void settle();
    std::vector<SurfaceSides> sides() const;
};

// The scene in 8 runs of consecutive surfaces per part, dealt in turn: its runs lie all over
// the scene, so that parts get about equal work. Measured on the interior at a thousand objects
// in two parts: runs 7.75 and 7.56 s of work, halves 7.31 and 6.37 s (fewer rounds, 3 against
// 10, but the slower part sets each round's pace), single surfaces dealt in turn 8.1 and 7.1 s;
// the rounds' critical path about 8 s for each.
int SidesProbe::owner(int surface, int parts, int surfaces) {
    return parts <= 1 || surfaces <= 0 ? 0 : int(int64_t(surface) * 8 * parts / surfaces % parts);
}

SidesProbe::Impl::Impl(const Scene& scene_, const RayCaster& caster_, const SolverSettings& settings_, int part_, int parts_)
    : scene(scene_), caster(caster_), settings(settings_), part(part_), parts(parts_) {
    if (parts < 1 || part < 0 || part >= parts)
        throw std::invalid_argument("sides probe: part " + std::to_string(part) + " of " + std::to_string(parts));
    const size_t n = scene.size();
    out.resize(n);
    for (size_t i = 0; i < n; ++i) {
        const SceneSurface& s = scene[i];
        if (s.material.bsdf && s.material.bsdf->transmits()) {
            out[i].live = {true, true};
            out[i].why = {"transmits", "transmits"};
        } else if (!settings.two_sided) {
            out[i].why = {"one-sided solve", "one-sided solve (two_sided off)"};
        } else if (s.receiver && owner(int(i), parts, int(n)) == part) {
            probed.push_back(int(i));
        }
    }
    why.resize(2 * n * kCells);
    lit_as.assign(why.size(), 0);
    if (probed.empty()) return;
    emitters = scene.emitters();
    views.resize(n);
    // The sides in chunks, each surface's ends' records moved into `seen` after its chunk.
    constexpr size_t kChunk = 256;
    std::vector<std::vector<uint8_t>> records(kChunk);
    for (size_t first = 0; first < probed.size(); first += kChunk) {
        const size_t count = std::min(kChunk, probed.size() - first);
        parallel_for(count, 1, settings.threads, [&](size_t begin, size_t end) {
            for (size_t k = begin; k < end; ++k) {
                records[k].clear();
                for (int side = 0; side < 2; ++side)
                    views[probed[first + k]][side] = probe_side(scene, emitters, caster, probed[first + k], side, records[k]);
            }
        });
        for (size_t k = 0; k < count; ++k)
            for (std::vector<CellView>& side : views[probed[first + k]])
                for (CellView& view : side)
                    if (view.ends >= 0) {
                        const uint8_t* record = &records[k][size_t(view.ends)];
                        view.ends = seen.add(record, ReachedCells::size_of(record));
                    }
    }
    std::vector<std::vector<uint8_t>>().swap(records);
    // Two-sided emitters whose back sees only themselves keep their light inside.
    for (int i : probed) {
        if (!scene[i].material.two_sided_emission) continue;
        bool inside = true;
        for (const CellView& v : views[i][1]) inside &= !v.escaped && !v.others;
        out[i].encloses_emission = inside;
    }
    // Cells lit directly (or emitting); settle() goes on from them.
    for (int i : probed)
        for (int side = 0; side < 2; ++side)
            for (int c = 0; c < kCells; ++c) {
                const size_t id = (2 * size_t(i) + side) * kCells + c;
                CellView& v = views[i][side][c];
                const bool emits = (side == 0 || (scene[i].material.two_sided_emission && !out[i].encloses_emission)) &&
                                   scene[i].material.emits();
                if (emits) why[id].kind = Reason::kEmits;
                else if (v.light != kNoLight) why[id] = {Reason::kDirect, v.light};
                if (emits) release(v);  // never asked
                if (lit(id)) fresh.push_back(uint32_t(id));
            }
}

// Cells that see a lit cell, to a fixed point; `why` keeps what lit each first. Light is
// carried per cell rather than per side, so that only where a side is lit lights others: the
// floor under a box standing on it (its rays end on the box's inside) lights no one. A ray
// landing in a lit cell counts only if its own end sees light or a lit cell too: the box's
// inside, whose rays meet the floor where the box's bottom lies on it, stays dark although the
// floor cell at the box's edge is lit.
// Whether a cell is lit only grows with the cells lit (a ray's end that carries light keeps
// carrying it), so the fixed point is the least one whatever the order the cells are asked in:
// parts that each settle their own cells, given the others', and exchange what they lit until
// none lights more, reach the cells one part reaches alone.
void SidesProbe::Impl::settle() {
    // A ray's end carries light if its cell is lit and the point itself sees light directly or
    // sees a lit cell (a cell lit at its centre may be dark where the ray ends).
    // Whether a cell lit since the view was last asked is one its answer depends on: where its
    // rays end, or what a checked end's rays reach.
    auto changed_for = [&](const CellView& view) {
        if (view.asked_at < 0) return true;
        auto after = [&](uint32_t id) { return lit_as[id] > view.asked_at; };
        bool changed = false;
        for_each_record(view, [&](int32_t index) {
            if (!changed) ReachedCells::for_each(seen[index], [&](uint32_t cell, uint32_t) { changed |= after(cell); });
        });
        return changed;
    };
    // What the end h of a ray, in cell `end`, sees: true if light directly (the world's through
    // any of its rays); else appends to `out` the record of the cells its rays reach.
    auto check_end = [&](uint32_t end, const SurfaceHit& h, std::vector<uint8_t>& out) {
        const int surface = int(end / (2 * kCells)), end_side = (end / kCells) % 2;
        const SurfacePoint p = scene[surface].surface->evaluate(h.u, h.v);
        if (direct_light(scene, emitters, caster, surface, p, end_side) != kNoLight) return true;
        std::array<uint32_t, kRays> reached;
        size_t m = 0;
        ProbeRays rays(caster, p, end_side, 0.5);
        uint32_t lit_rays = 0;
        for (int r = 0; r < kRays; ++r) {
            const SurfaceHit& hit = rays.hit(r);
            if (hit.surface < 0 && scene.has_world()) return true;
            if (hit.surface < 0 || !scene[hit.surface].receiver) continue;
            reached[m++] = end_cell(hit, rays.dir(r));
            // Enough rays reach lit cells: it carries light (what the record would say), and
            // the rest need not be cast.
            if (lit(reached[m - 1]) && ++lit_rays == kRaysToCarry) return true;
        }
        std::sort(reached.begin(), reached.begin() + m);
        ReachedCells::encode(reached.data(), m, out);
        return false;
    };
    // Whether a checked end whose record is `record` carries light: enough of its rays reach lit cells.
    auto reaches_lit = [&](const uint8_t* record) {
        uint32_t rays = 0;
        ReachedCells::for_each(record, [&](uint32_t cell, uint32_t count) { rays += lit(cell) ? count : 0; });
        return rays >= kRaysToCarry;
    };
    // The block of a view's checked ends, one allocated if it has none.
    auto checks_of = [&](CellView& view) {
        if (view.checked < 0) {
            if (!free_checks.empty()) {
                view.checked = free_checks.back();
                free_checks.pop_back();
            } else {
                if (checks.size() >= size_t(INT32_MAX)) throw std::length_error("the sides probe's checked ray ends passed its index");
                view.checked = int32_t(checks.size());
                checks.emplace_back();
            }
            checks[size_t(view.checked)].fill(kNotChecked);
        }
        return checks[size_t(view.checked)].data();
    };
    // Whether the end h of ray k of a cell's view, in cell `end`, carries light.
    std::vector<uint8_t> record;
    auto carries_light = [&](CellView& view, int k, uint32_t end, const SurfaceHit& h) {
        if (!lit(end)) return false;
        int32_t& checked = checks_of(view)[k];
        if (checked == kNotChecked) {
            record.clear();
            checked = check_end(end, h, record) ? kCarries : seen.add(record.data(), record.size());
        }
        if (checked >= 0 && reaches_lit(seen[checked])) seen.drop(checked), checked = kCarries;
        return checked == kCarries;
    };
    // The rays of cell c of a side of surface i, in order: visit(k, hit, end cell) for those
    // that end on a receiver, until it returns true.
    auto cell_rays = [&](int i, int side, int c, auto&& visit) {
        ProbeRays rays(caster, cell_centre(*scene[i].surface, c), side, cell_turn(i, c, side));
        for (int k = 0; k < kRays; ++k) {
            const SurfaceHit& hit = rays.hit(k);
            if (hit.surface < 0 || !scene[hit.surface].receiver) continue;
            if (visit(k, hit, end_cell(hit, rays.dir(k)))) return;
        }
    };
    // Each pass asks, in order, every dark cell whose answer may have changed (Gauss-Seidel: a
    // cell lit early in a pass counts for the cells after it). Casting a cell's rays and checking
    // their ends is the work: it is done ahead, on all threads, for the next kPrefetch cells that
    // would be asked given the cells lit by then (those lit meanwhile add a few ends, checked in
    // order, and a few cells, asked in order), keeping the ends of their rays that reach
    // receivers, which the ordered pass reads instead of casting the rays again (it did: four
    // fifths of the probe at 300 objects). More cells lit only make a cell stop earlier, so the
    // ends kept up to where the prefetch stopped suffice.
    struct Cell {
        int i, side, c;
        size_t id() const { return (2 * size_t(i) + side) * kCells + c; }
    };
    struct RayEnd {
        int k;
        uint32_t end;  // its cell
        int surface;
        double u, v;
    };
    const size_t cells = probed.size() * 2 * kCells;
    auto cell_at = [&](size_t p) { return Cell{probed[p / (2 * kCells)], int(p / kCells % 2), int(p % kCells)}; };
    // A cell is lit by kRaysToCarry of its rays ending in lit cells (and carrying light there):
    // the record of where its rays end tells, without casting them again, when too few do (the
    // inside of a closed mesh, whose rays all end on its own dark inside, is most of the cells
    // asked).
    auto asks_now = [&](const Cell& cell) {
        const CellView& view = views[cell.i][cell.side][cell.c];
        return !lit(cell.id()) && view.asks && view.ends >= 0 && reaches_lit(seen[view.ends]) && changed_for(view);
    };
    constexpr size_t kPrefetch = 64;  // cells (a smaller window sees more of the cells lit meanwhile)
    std::vector<Cell> window;
    std::vector<size_t> window_at;                         // their positions in the pass
    // Per cell: what its ends checked ahead see, each as the ray, 1 if it sees light directly
    // (else 0 and its record).
    std::vector<std::vector<uint8_t>> found(kPrefetch);
    std::vector<std::vector<RayEnd>> ends(kPrefetch);     // per cell: its rays that reach receivers, in order
    auto prefetch = [&] {
        parallel_for(window.size(), 1, settings.threads, [&](size_t begin, size_t end) {
            for (size_t d = begin; d < end; ++d) {
                const Cell& cell = window[d];
                const CellView& view = views[cell.i][cell.side][cell.c];
                std::vector<uint8_t>& out = found[d];
                out.clear();
                ends[d].clear();
                int carrying = 0;
                cell_rays(cell.i, cell.side, cell.c, [&](int k, const SurfaceHit& hit, uint32_t end) {
                    ends[d].push_back({k, end, hit.surface, hit.u, hit.v});
                    if (!lit(end)) return false;
                    const int32_t checked = view.checked < 0 ? kNotChecked : checks[size_t(view.checked)][k];
                    bool carries = checked == kCarries || (checked >= 0 && reaches_lit(seen[checked]));
                    if (checked == kNotChecked) {
                        out.push_back(uint8_t(k));
                        const size_t flag = out.size();
                        out.push_back(0);
                        if (check_end(end, hit, out)) out[flag] = 1, carries = true;
                        else carries = reaches_lit(&out[flag + 1]);
                    }
                    return carries && ++carrying == kRaysToCarry;
                });
            }
        });
        for (size_t d = 0; d < window.size(); ++d) {
            CellView& view = views[window[d].i][window[d].side][window[d].c];
            const std::vector<uint8_t>& records = found[d];
            for (size_t r = 0; r < records.size();) {
                int32_t& checked = checks_of(view)[records[r]];
                if (records[r + 1]) {
                    checked = kCarries;
                    r += 2;
                    continue;
                }
                const size_t size = ReachedCells::size_of(&records[r + 2]);
                checked = seen.add(&records[r + 2], size);
                r += 2 + size;
            }
        }
    };
    for (bool changed = true; changed;) {
        changed = false;
        window.clear(), window_at.clear();
        size_t slot = 0;
        for (size_t p = 0; p < cells; ++p) {
            const Cell cell = cell_at(p);
            const size_t id = cell.id();
            CellView& view = views[cell.i][cell.side][cell.c];
            if (!asks_now(cell)) continue;
            while (slot < window_at.size() && window_at[slot] < p) ++slot;
            if (slot == window_at.size()) {
                window.clear(), window_at.clear(), slot = 0;
                for (size_t q = p; q < cells && window.size() < kPrefetch; ++q)
                    if (asks_now(cell_at(q))) window.push_back(cell_at(q)), window_at.push_back(q);
                prefetch();
            }
            view.asked_at = lit_count;
            int carrying = 0;
            auto visit = [&](int k, const SurfaceHit& hit, uint32_t end) {
                if (!carries_light(view, k, end, hit) || ++carrying < kRaysToCarry) return false;
                why[id] = {Reason::kReflected, hit.surface};
                lit_as[id] = ++lit_count;
                fresh.push_back(uint32_t(id));
                changed = true;
                return true;
            };
            if (window_at[slot] == p) {
                for (const RayEnd& e : ends[slot]) {
                    SurfaceHit hit;
                    hit.surface = e.surface, hit.u = e.u, hit.v = e.v;
                    if (visit(e.k, hit, e.end)) break;
                }
            } else {
                cell_rays(cell.i, cell.side, cell.c, visit);  // asked since the window was fetched
            }
            if (lit(id)) {
                release(view);
                if (seen.mostly_dropped()) {
                    const size_t held = held_bytes(views, why, lit_as, seen, checks, free_checks);
                    peak = std::max(peak, held + seen.compact([&](auto&& move) {
                        for (int j : probed)
                            for (auto& cells_of_side : views[j])
                                for (CellView& other : cells_of_side) for_each_record(other, move);
                    }));
                }
            }
        }
    }
}

std::vector<SurfaceSides> SidesProbe::Impl::sides() const {
    std::vector<SurfaceSides> out = this->out;
    auto text = [&](const Reason& r) {
        return r.kind == Reason::kEmits    ? std::string("emits")
               : r.kind == Reason::kDirect ? "receives " + light_name(scene, r.source)
                                           : "receives light reflected by '" + scene[r.source].surface->name() + "'";
    };
    for (int i : probed)
        for (int side = 0; side < 2; ++side) {
            // The reason of a cell lit directly if there is one, else of the first lit cell.
            bool escaped = false, reflected = false;
            out[i].live[side] = false;
            out[i].why[side].clear();
            for (int c = 0; c < kCells; ++c) {
                const size_t id = (2 * size_t(i) + side) * kCells + c;
                escaped |= views[i][side][c].escaped;
                if (!lit(id)) continue;
                if (!out[i].live[side] || (why[id].kind != Reason::kReflected && reflected)) {
                    out[i].why[side] = text(why[id]);
                    reflected = why[id].kind == Reason::kReflected;
                }
                out[i].live[side] = true;
            }
            if (!out[i].live[side])
                out[i].why[side] = side == 1 && out[i].encloses_emission
                                       ? "emits, but only into itself (the inside of a closed mesh)"
                                       : escaped ? "sees no light" : "sees no light (the inside of a closed mesh?)";
        }
    return out;
}

SidesProbe::SidesProbe(const Scene& scene, const RayCaster& caster, const SolverSettings& settings, int part, int parts)
    : impl_(std::make_unique<Impl>(scene, caster, settings, part, parts)) {}
SidesProbe::~SidesProbe() = default;

std::vector<uint32_t> SidesProbe::lit_directly() {
    std::vector<uint32_t> lit;
    lit.swap(impl_->fresh);
    return lit;
}

std::vector<uint32_t> SidesProbe::settle(const std::vector<uint32_t>& lit_elsewhere) {
    Impl& p = *impl_;
    for (const uint32_t id : lit_elsewhere) {
        if (id >= p.why.size()) throw std::invalid_argument("sides probe: cell " + std::to_string(id) + " is not in the scene");
        if (p.lit(id)) continue;
        const int surface = int(id / (2 * kCells));
        p.why[id] = {Reason::kReflected, surface};
        p.lit_as[id] = ++p.lit_count;
    }
    if (!p.probed.empty()) p.settle();
    std::vector<uint32_t> lit;
    lit.swap(p.fresh);
    return lit;
}

std::vector<SurfaceSides> SidesProbe::sides() const { return impl_->sides(); }

size_t SidesProbe::peak_bytes() const {
    const Impl& p = *impl_;
    if (p.probed.empty()) return 0;
    return std::max(p.peak, held_bytes(p.views, p.why, p.lit_as, p.seen, p.checks, p.free_checks));
}

std::vector<SurfaceSides> probe_sides(const Scene& scene, const RayCaster& caster, const SolverSettings& settings, size_t* bytes) {
    SidesProbe probe(scene, caster, settings);
    probe.settle({});
    if (bytes) *bytes = probe.peak_bytes();
    return probe.sides();
}

}  // namespace bsgi
