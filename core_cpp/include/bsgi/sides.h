// Which sides of each surface the scene lights ("model only what the scene requires"): Cycles
// shades every opaque surface on both sides with the same BSDF, but a side no light reaches (the
// inside of a closed mesh with nothing in it, the outside of a room in a black world) needs no
// spline. A cheap probe decides it before anything is allocated.
#pragma once
#include <array>
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
// The same with the scene's own ray caster (what the solve casts rays at).
std::vector<SurfaceSides> probe_sides(const Scene& scene, const SolverSettings& settings, size_t* bytes = nullptr);

}  // namespace bsgi
