// Which sides of each surface the scene lights ("model only what the scene requires"): Cycles
// shades every opaque surface on both sides with the same BSDF, but a side no light reaches (the
// inside of a closed mesh with nothing in it, the outside of a room in a black world) needs no
// spline. A cheap probe decides it before anything is allocated.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bsgi/ray_caster.h"
#include "bsgi/scene.h"
#include "bsgi/solver.h"

namespace bsgi {

// Per surface: whether its front (0) and back (1) side gets a spline, and why.
struct SurfaceSides {
    std::array<bool, 2> live{true, false};
    std::array<std::string, 2> why;
    // A two-sided emitter whose back side sees only itself (a closed bulb): its back's light
    // reaches no other surface, so it is neither gathered by others nor solved.
    bool encloses_emission = false;
};

// Probes, from the centres of a coarse grid of cells on each side of every receiving surface,
// what each cell sees: an emitter's emitting side (shadow rays to a few points of it), a distant
// light, the world (if it has light), or cells of other sides; marks lit every cell that sees
// light directly or sees lit cells (a fixed point over that graph, each ray's end checked on its
// own), and solves every side with a lit cell. Transmitting surfaces get both sides; emitters the
// sides they emit from. With settings.two_sided off every opaque surface gets its front side only.
// `bytes`, if given, receives the memory the probe held at its peak (for the solve's estimate).
std::vector<SurfaceSides> probe_sides(const Scene& scene, const RayCaster& caster, const SolverSettings& settings,
                                      size_t* bytes = nullptr);

// The same probe in parts, for a solve split over machines (bsgi.RayExecutor): part p of n
// probes the cells of the surfaces owner() gives it, and the parts reach the one probe's
// answer by exchanging the cells they light (a cell is numbered (surface * 2 + side) * 36 +
// its cell of 6 x 6) until none lights more:
//     SidesProbe probe(scene, caster, settings, p, n);
//     lit = probe.lit_directly();             // its cells lit directly (or emitting), to all
//     lit = probe.settle(cells others lit);   // repeated, until no part returns any
//     probe.sides()                           // right for the surfaces it owns
// With one part, settle({}) once is the whole probe.
class SidesProbe {
public:
    // Probes the views of its part's cells (on settings.threads threads). The scene and caster
    // must outlive it.
    SidesProbe(const Scene& scene, const RayCaster& caster, const SolverSettings& settings, int part = 0, int parts = 1);
    ~SidesProbe();
    // The part of `parts` that probes surface `surface` of a scene of `surfaces`.
    static int owner(int surface, int parts, int surfaces);
    // Its cells lit directly or emitting, not returned before (all of them at the first call).
    std::vector<uint32_t> lit_directly();
    // Marks `lit_elsewhere` lit (cells other parts lit; its own and those marked already are
    // skipped), lights what its cells then see, to a fixed point over its own cells, and returns
    // its cells lit since the last call (of this or lit_directly()).
    std::vector<uint32_t> settle(const std::vector<uint32_t>& lit_elsewhere);
    // Per surface as probe_sides() gives it, for the surfaces this part owns and those that are
    // not probed (transmitting, or all with two_sided off); the rest as default.
    std::vector<SurfaceSides> sides() const;
    // The bytes it has held at its peak.
    size_t peak_bytes() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};
// The same with the scene's own ray caster (what the solve casts rays at).
std::vector<SurfaceSides> probe_sides(const Scene& scene, const SolverSettings& settings, size_t* bytes = nullptr);

}  // namespace bsgi
