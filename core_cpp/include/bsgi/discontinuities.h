// Discontinuities of the direct light on a receiver, found from the geometry of the emitters and
// occluders (discontinuity meshing, Lischinski, Tampieri and Greenberg 1992; paper section 5.1):
// where the lines fall on parameter lines u = const or v = const, knots of the multiplicity
// their order asks for keep a sharp shadow sharp in the spline.
#pragma once
#include <array>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "bsgi/knots.h"
#include "bsgi/ray_caster.h"
#include "bsgi/scene.h"

namespace bsgi {

// A parameter line u = position (or v = position) along which the direct light is C^(order-1):
// order 0 a jump (a contact line), 1 a kink (an EV event whose emitter edge is parallel to the
// occluder edge, the usual case of parallel polygons), 2 a jump of the second derivative (a
// generic EV or VE event).
struct DiscontinuityLine {
    double position;
    int order;
    // A jump (order 0) that stands for a penumbra narrower than the spline resolves: the band's
    // width in the parameter, which the nodes beside the knot keep out of (0: a true jump).
    double band = 0;
    // The part of the other parameter's range along which the light is discontinuous there
    // (a tensor-product knot spans all of it; a shadow edge of a small object a little).
    double length = 1;
    // A steep but continuous fall of width `grade` in the parameter centred on the line (a near
    // contact's): simple knots at position + grade x {-2, -1, 0, 1, 2} instead of a jump.
    double grade = 0;
};

struct ReceiverDiscontinuities {
    std::array<std::vector<DiscontinuityLine>, 2> lines;  // along u, along v
    int oblique = 0;       // event segments crossing the surface that are no parameter line
    bool planar = false;   // the receiver is a plane with an affine (u, v): the only kind searched
    std::string note;      // why not searched, or what was left out (for the surface's report)
};

// A light at infinity as a disc of directions: a distant light (Blender's sun), or the world
// map's bright directions around one centre (an HDRI's or a sky's sun).
struct DistantSource {
    Vec3 direction;    // unit, towards the light
    double angle = 0;  // the disc's angular diameter
};

// The world map's bright directions (direction, irradiance) as discs: each within kClusterAngle
// of the brightest left joins it, the disc's angle twice the farthest member's; discs bringing
// under kMinShare of the bright part's irradiance cast no line worth a knot.
std::vector<DistantSource> bright_world_sources(const std::vector<std::pair<Vec3, double>>& bright);

// What DiscontinuityFinder::find searches: the direct light's events (EV, VE, contact lines, the
// distant lights' shadow edges) and near contacts.
struct DiscontinuityKinds {
    bool events = true, near_contacts = true;
};

// The polygonal emitters and occluders of a scene, their feature edges extracted once.
class DiscontinuityFinder {
public:
    // `distant`: the lights at infinity whose shadow edges count (the scene's distant lights
    // and the world's bright part); `caster`: keeps an edge of theirs only where it bounds light
    // on the receiver (an edge in another's shadow, a window wall's outer edges, bounds none).
    DiscontinuityFinder(const Scene& scene, std::vector<DistantSource> distant = {}, const RayCaster* caster = nullptr,
                        DiscontinuityKinds kinds = {});
    const DiscontinuityKinds& kinds() const { return kinds_; }
    ~DiscontinuityFinder();
    DiscontinuityFinder(DiscontinuityFinder&&) noexcept;

    // The lines on receiver `surface` (its sides `live`): EV events (an emitter vertex and an
    // occluder edge), VE events (an occluder vertex and an emitter edge), contact lines (an
    // occluder edge lying on the receiver), near contacts (the outline of an occluder's face
    // parallel to the receiver a little off it) and the shadow edges of lights at infinity (an
    // occluder edge seen along the disc's rim). A segment counts as the parameter line
    // u = const when its u varies by at most `tolerance[0]` over the part crossing the
    // surface (likewise v). `rays`: the shadow rays that checked the distant lights' edges.
    ReceiverDiscontinuities find(int surface, std::array<bool, 2> live, std::array<double, 2> tolerance,
                                 size_t& rays) const;

    // Polygonal surfaces (a plane, or a mesh whose tessellation is the surface) with at most
    // this many feature edges take part; curved ones do not.
    static constexpr int kMaxEdges = 64;
    // Emitter x occluder edge pairs examined per receiver, nearest occluders first beyond it.
    static constexpr size_t kMaxPairs = 200000;
    // Contact lines' bands (the lift over the tangent of the wedge's angle, find()) stop growing
    // at wedges narrower than 0.6 degrees: a crevice, dark on both sides of its nodes.
    static constexpr double kMaxContactCot = 100;
    // Near contacts (find()): a face within 2 degrees of parallel to the receiver, at a gap of at
    // most a span (wider, the spline follows the fall of the light under it).
    static constexpr double kNearContactCos = 0.99939;
    static constexpr double kNearContactSpans = 1.0;

    static constexpr double kClusterAngle = 0.1;  // radians (5.7 degrees: a sun and its aureole)
    static constexpr double kMinShare = 0.01;

    struct Polygonal;  // a surface's feature edges (discontinuities.cpp)
    struct Distant;    // a distant source and its occluders by cells across it (discontinuities.cpp)
    struct Grid;       // the occluders by cells of their boxes (discontinuities.cpp)

private:
    std::vector<Polygonal> polys_;  // by scene index; empty edges: not polygonal
    std::vector<int> emitters_;     // scene indices, found once: find() runs for every receiver
    std::vector<Distant> distant_;
    std::unique_ptr<Grid> grid_;
    const Scene* scene_;
    const RayCaster* caster_;
    DiscontinuityKinds kinds_;
};

// Clamped knots on [a, b] with num_coeffs coefficients: each line of order below the degree
// (where the light is less smooth than the spline, C^(degree-1)) gets a knot of multiplicity
// degree + 1 - order, a graded line its five simple knots (lines closer than a fifth of a uniform
// span merged, the lowest order kept, their lengths added; at most half the inner knots go to
// lines, lowest orders first and of an order the longest first), and the remaining inner
// knots are spread between them, each gap getting its share of `density` (given on equal cells
// of [a, b]; empty: uniform) equidistributed. `placed`: the lines that got knots.
KnotVector discontinuity_knots(std::vector<DiscontinuityLine> lines, int num_coeffs, int degree, double a, double b,
                               const std::vector<double>& density, std::vector<DiscontinuityLine>& placed);

}  // namespace bsgi
