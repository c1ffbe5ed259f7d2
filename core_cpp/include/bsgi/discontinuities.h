// Discontinuities of the direct light on a receiver, found from the geometry of the emitters and
// occluders (discontinuity meshing, Lischinski, Tampieri and Greenberg 1992; paper section 5.1):
// where the lines fall on parameter lines u = const or v = const, knots of the multiplicity
// their order asks for keep a sharp shadow sharp in the spline.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "bsgi/knots.h"
#include "bsgi/scene.h"

namespace bsgi {

// A parameter line u = position (or v = position) along which the direct light is C^(order-1):
// order 0 a jump (a contact line), 1 a kink (an EV event whose emitter edge is parallel to the
// occluder edge, the usual case of parallel polygons), 2 a jump of the second derivative (a
// generic EV or VE event).
struct DiscontinuityLine {
    double position;
    int order;
};

struct ReceiverDiscontinuities {
    std::array<std::vector<DiscontinuityLine>, 2> lines;  // along u, along v
    int oblique = 0;       // event segments crossing the surface that are no parameter line
    bool planar = false;   // the receiver is a plane with an affine (u, v): the only kind searched
    std::string note;      // why not searched, or what was left out (for the surface's report)
};

// The polygonal emitters and occluders of a scene, their feature edges extracted once.
class DiscontinuityFinder {
public:
    explicit DiscontinuityFinder(const Scene& scene);
    ~DiscontinuityFinder();
    DiscontinuityFinder(DiscontinuityFinder&&) noexcept;

    // The lines on receiver `surface` (its sides `live`): EV events (an emitter vertex and an
    // occluder edge), VE events (an occluder vertex and an emitter edge) and contact lines
    // (an occluder edge lying on the receiver). A segment counts as the parameter line
    // u = const when its u varies by at most `tolerance[0]` over the part crossing the
    // surface (likewise v).
    ReceiverDiscontinuities find(int surface, std::array<bool, 2> live, std::array<double, 2> tolerance) const;

    // Polygonal surfaces (a plane, or a mesh whose tessellation is the surface) with at most
    // this many feature edges take part; curved ones do not.
    static constexpr int kMaxEdges = 64;
    // Emitter x occluder edge pairs examined per receiver, nearest occluders first beyond it.
    static constexpr size_t kMaxPairs = 200000;

    struct Polygonal;  // a surface's feature edges (discontinuities.cpp)

private:
    std::vector<Polygonal> polys_;  // by scene index; empty edges: not polygonal
    std::vector<int> emitters_;     // scene indices, found once: find() runs for every receiver
    const Scene* scene_;
};

// Clamped knots on [a, b] with num_coeffs coefficients: each line of order below the degree
// (where the light is less smooth than the spline, C^(degree-1)) gets a knot of multiplicity
// degree + 1 - order (lines closer than a fifth of a uniform span merged, the lowest order
// kept; at most half the inner knots go to lines, lowest orders first), and the remaining inner
// knots are spread between them, each gap getting its share of `density` (given on equal cells
// of [a, b]; empty: uniform) equidistributed. `placed`: the lines that got knots.
KnotVector discontinuity_knots(std::vector<DiscontinuityLine> lines, int num_coeffs, int degree, double a, double b,
                               const std::vector<double>& density, int& placed);

}  // namespace bsgi
