// The two integrals of the gathering solver, for one receiver node at a time: the surface
// integral (8)/(35) over the emitters (direct light), and the hemispherical integral (26)-(32)
// of the radiance other surfaces send (indirect light).
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <unordered_map>
#include <vector>

#include "bsgi/hemisphere_map.h"
#include "bsgi/quadrature.h"
#include "bsgi/radiance.h"
#include "bsgi/ray_caster.h"
#include "bsgi/scatter_table.h"
#include "bsgi/scene.h"
#include "bsgi/solver.h"
#include "bsgi/tensor_spline.h"

namespace bsgi {

// A spatial Schoenberg node (u_i, v_j) of a receiver, or the point of the surface it was moved to
// (a hidden node moved to the contact line). Its point is evaluated where it is gathered.
struct SpatialNode {
    double u = 0, v = 0;
};

// A receiver's spatial nodes: the tensor grid (u_i, v_j), i slowest, and the few moved off it
// (hidden nodes moved to the contact line) kept aside. Stored as a grid they are two short
// arrays; as a list they took 16 bytes a node (measured with the gather's list of them: the
// interior at 1,000 objects peaked at 476 MB with lists, 422 MB with grids).
class SpatialNodes {
public:
    SpatialNodes() = default;
    SpatialNodes(std::vector<double> u, std::vector<double> v) : u_(std::move(u)), v_(std::move(v)) {}
    size_t size() const { return u_.size() * v_.size(); }
    SpatialNode operator[](size_t j) const {
        if (!moved_.empty())
            if (const auto it = moved_.find(j); it != moved_.end()) return it->second;
        return {u_[j / v_.size()], v_[j % v_.size()]};
    }
    void move(size_t j, const SpatialNode& to) { moved_[j] = to; }
    // The grid's nodes along u (k = 0) or v (k = 1).
    const std::vector<double>& axis(int k) const { return k == 0 ? u_ : v_; }

private:
    std::vector<double> u_, v_;
    std::unordered_map<size_t, SpatialNode> moved_;
};

// A receiving surface during the solve: its nodes and its radiance splines (Figure 4), one per
// side: the lower side where the surface transmits (section 4.3) or where light reaches an opaque
// surface's back (which reflects it with the BSDF mirrored, as Cycles shades it). A side the
// scene does not light (sides.h) is not solved: its spline is a single zero coefficient.
struct Receiver {
    int surface = -1;
    int index = -1;                   // position among the receivers
    // Decomposition (38): the diffuse part D is the surface's receiver, the glossy part S its
    // partner; the light leaving the surface is their sum (weighed by the tint if tinted).
    const Receiver* partner = nullptr;
    bool is_partner = false;
    Representation kind = Representation::Diffuse;
    const Bsdf* bsdf = nullptr;
    const Texture* albedo = nullptr;  // the albedo texture of a diffuse part holding irradiance / pi
    std::optional<CoatedBase> coat;   // with an albedo texture under a layered coat: its texels as seen
    // A textured GGX f0: this receiver is the surface at f0 = 1 and its partner at f0 = 0; the
    // texture T weighs them T and 1 - T.
    const Texture* tint = nullptr;
    // A normal map (normal_map.h): the splines are over the bumped normal, read at the map's.
    const Texture* normals = nullptr;
    int sides = 1;                    // spline slots: 2 if the back side is solved
    std::array<bool, 2> live{true, false};
    HemisphereMap map{1.0};
    SpatialNodes nodes;               // spatial Schoenberg nodes (u_i, v_j), i slowest
    std::vector<Vec3> directions;     // outgoing local directions of the angular nodes, upper side
    size_t per_node = 1;              // angular nodes per spatial node (1 if diffuse)
    std::vector<TensorSpline> Le, L, Ltmp;  // cumulative, incremental, temporary; per side
    std::shared_ptr<const std::vector<KnotVector>> axes;  // of a solved side's splines, which share them
    // While the direct phase gathers (SolverSettings::distant_support_means), per spatial node
    // whether its light is a mean over its support (set by the node's own thread); gather_all
    // leaves those and the nodes beside them unsharpened, then frees it.
    mutable std::vector<uint8_t> support_means;

    using Splines = std::vector<TensorSpline> Receiver::*;
    size_t values() const { return sides * nodes.size() * per_node; }
    // Direction of value a of a node on a side: the angular node's, mirrored below for side 1.
    Vec3 outgoing(int side, size_t a) const {
        const Vec3 d = kind == Representation::Diffuse ? Vec3{0, 0, 1} : directions[a];
        return side == 0 ? d : Vec3{d.x, d.y, -d.z};
    }
    bool solves(int side) const { return side < sides && live[side]; }
    // The back side of an opaque surface scatters as the front does with both directions mirrored
    // through the surface: f(flip wo, flip wi), flip(x, y, z) = (x, y, -z).
    bool mirrored(int side) const { return side == 1 && !bsdf->transmits(); }
    // BSDF value for value a of a node on a side and light arriving from local direction wi.
    Vec3 scatter(int side, size_t a, const Vec3& wi) const {
        const Vec3 wo = outgoing(side, a);
        return mirrored(side) ? bsdf->eval({wo.x, wo.y, -wo.z}, {wi.x, wi.y, -wi.z}) : bsdf->eval(wo, wi);
    }
    // Sets the RGB coefficient of (side, spatial node, angular node) of one of the spline sets
    // (Float64, or Float32: a regather's correction).
    void set_coefficient(Splines which, int side, size_t node, size_t a, const Vec3& value) {
        TensorSpline& s = (this->*which)[side];
        const size_t i = 3 * (node * per_node + a);
        if (s.precision() == Precision::Float32) {
            float* c = s.coeffs_f32() + i;
            c[0] = float(value.x), c[1] = float(value.y), c[2] = float(value.z);
        } else {
            double* c = s.coeffs().data() + i;
            c[0] = value.x, c[1] = value.y, c[2] = value.z;
        }
    }
    // Radiance leaving (u, v) along `local`, from one of the spline sets (with the partner's);
    // `texel` multiplies this receiver's own part, `partner_texel` its partner's (their detail
    // textures as seen there).
    // (Inline: every gathered ray ends here, and a call returns its Vec3 through memory.)
    Vec3 radiance(Splines which, double u, double v, const Vec3& local, const Vec3& texel = {1, 1, 1},
                  const Vec3& partner_texel = {1, 1, 1}) const {
        const Vec3 L = own_radiance(which, u, v, local) * texel;
        return partner ? L + partner->own_radiance(which, u, v, local) * partner_texel : L;
    }
    Vec3 own_radiance(Splines which, double u, double v, const Vec3& local) const {
        const int side = local.z >= 0 ? 0 : 1;
        return side < sides ? evaluate_side(kind, map, (this->*which)[side], u, v, local) : Vec3{0, 0, 0};
    }
};

// One term of a row of the transport operator (36)-(37): the weight of coefficient `index`
// (RGB triple number) of spline set side `side` of receiver `receiver` in a node's gathered light.
struct TransportTerm {
    uint32_t receiver;
    uint32_t index;
    uint8_t side;
    float weight;
};

// Integration nodes along an axis at a density (rounded, at least one).
inline int nodes_along(int count, double density) { return std::max(1, int(std::lround(count * density))); }

// Directional albedo along wo, the integral of rho(wo, wi) cos over the upper hemisphere, by the
// gather's cosine-weighted rule of 16 x 32 nodes (Gauss in cos theta: within 2e-3 of a
// 200 x 400 rule for wide GGX lobes from the normal to grazing wo).
Vec3 directional_albedo(const Bsdf& b, const Vec3& wo = {0, 0, 1});

// Whether an emitter's normal turns across it: a curved emitter lights itself too, and the
// gatherer checks its cells' rule (Gatherer::emitter_cell).
bool curved_emitter(const Surface& e);

// The direct light's sources: the emitting surfaces, the lights at infinity (distant lights and
// the world map's bright part), or both.
enum class LightParts { Emitters, Distant, All };

// A weight per scene surface over its parameter square: kCells x kCells values per surface (v
// major), taken bilinearly between the cells' centres (the error estimate's input scales).
class InputScales {
public:
    static constexpr int kCells = 8;
    // The values for `surfaces` scene surfaces, kCells x kCells each.
    static constexpr size_t values_for(size_t surfaces) { return surfaces * kCells * kCells; }
    InputScales(const double* values, size_t surfaces) : values_(values, values + values_for(surfaces)) {}
    double at(int surface, double u, double v) const;

private:
    std::vector<double> values_;
};

class Gatherer {
public:
    Gatherer(const Scene& scene, const SolverSettings& settings, const RayCaster& caster);
    // The bytes a gatherer keeps of emitter e's points (a grid per cell of a curved one's domain).
    static size_t emitter_grid_bytes(const Surface& e);

    // The point of the surface at node j of r.
    SurfacePoint node_point(const Receiver& r, size_t j) const {
        return scene_[r.surface].surface->evaluate(r.nodes[j].u, r.nodes[j].v);
    }
    // Reflected (and transmitted) direct light at node j of r: r.values() / r.nodes.size()
    // values into out, side-major then angular node.
    void direct(const Receiver& r, size_t j, Vec3* out, size_t& rays) const;
    // The same with the lights at infinity as their mean weighed by node j's basis function where
    // one of their shadow edges crosses its support (SolverSettings::distant_support_means; marks
    // r.support_means): 17 evaluations of their light a node (its own, 16 over its support),
    // 256 more where an edge crosses, the support's points no viewer sees left out (enclosed,
    // by receiver_of).
    void direct_over_support(const Receiver& r, size_t j, const std::vector<const Receiver*>& receiver_of, Vec3* out,
                             size_t& rays) const;
    // The light of the lights at infinity (a sun, the world map's bright part) that a diffuse r
    // reflects at (u, v) of its surface on `side`, its channels summed: 0 without such lights or
    // for a glossy r (and no ray cast, no point evaluated).
    double distant_light_at(const Receiver& r, double u, double v, int side, size_t& rays) const;
    static constexpr double kEdgeContrast = 0.3;
    // Light arriving from the other surfaces' splines `which` at node j of r, scattered, and
    // with `with_world` the world's light along the rays no occluder stops (the final gather:
    // one set of rays for both). `density` scales the integration nodes along each axis (the
    // final gather uses more, late bounces fewer).
    void indirect(const Receiver& r, size_t j, const std::vector<const Receiver*>& receiver_of, Receiver::Splines which,
                  double density, bool with_world, Vec3* out, size_t& rays) const;
    // The same gathered from the change of the others' radiance: the splines Le of `now_of`
    // less those of `before_of` (a second final gather's correction; the world cancels).
    // Returns whether a ray met a glossy surface whose lobe is narrower than `lobe_width`
    // (Bsdf::lobe_width: its reflections' change is view-dependent and sharp). With `scale_of`,
    // each surface's change is weighted by its scale where the ray meets it (the error
    // estimate's input).
    bool indirect_change(const Receiver& r, size_t j, const std::vector<const Receiver*>& now_of,
                         const std::vector<const Receiver*>& before_of, double density, double lobe_width, Vec3* out,
                         size_t& rays, const InputScales* scale_of = nullptr) const;
    // The world's light at node j of r, scattered: the hemispherical integral (26)-(32) over
    // the directions no occluder stops, of the constant world or of the world map's smooth
    // remainder (its bright part is among the distant samples of direct()). Same layout as direct().
    void world(const Receiver& r, size_t j, Vec3* out, size_t& rays) const;
    // Generalized form factors (36)-(37): for a Lambertian, opaque receiver, the row of the
    // transport operator at node j of a side, so that its gathered light is albedo *
    // sum(weight * coefficient) over the receivers' incremental splines: the rays are cast once,
    // not every bounce.
    void transport_row(const Receiver& r, int side, size_t j, const std::vector<const Receiver*>& receiver_of,
                       std::vector<TransportTerm>& row, size_t& rays) const;
    // Whether every one of a few directions over `side`'s hemisphere at p ends on a side of a
    // surface that is neither solved nor emitting (the inside of a closed, unlit mesh).
    bool enclosed(const SurfacePoint& p, int side, const std::vector<const Receiver*>& receiver_of, size_t& rays) const;
    // Whether p of r is enclosed on one of the sides r solves (under a block resting on it).
    // One side is enough: the other side's light (an open floor's underside lit by the sky) has
    // no edge there.
    bool hidden(const Receiver& r, const SurfacePoint& p, const std::vector<const Receiver*>& receiver_of, size_t& rays) const;
    // Direct irradiance at a point on the given sides (for probing where the light has detail).
    Vec3 irradiance(int surface, const SurfacePoint& p, size_t& rays, std::array<bool, 2> sides = {true, false}) const;
    // The world map's bright part (a sun) as the directions its shadow rays take, each with the
    // largest channel of the irradiance it brings to a surface facing it.
    std::vector<std::pair<Vec3, double>> world_bright() const;
    const RayCaster& caster() const { return caster_; }

private:
    // The hemispherical integral at node j of r of radiance_along(hit, world direction), the
    // radiance arriving along each integration direction given what its ray hit.
    template <typename Incoming>
    void hemisphere(const Receiver& r, size_t j, double density, Incoming&& radiance_along, Vec3* out, size_t& rays) const;
    Vec3 texel_seen(const Texture& texture, const SurfaceHit& hit, const Vec3& dir, double solid_angle) const;
    // The radiance of h's splines `which` seen along dir at the hit, its textures filtered over
    // the footprint of a ray of that solid angle.
    Vec3 seen_radiance(const Receiver& h, Receiver::Splines which, const SurfaceHit& hit, const Vec3& dir,
                       double solid_angle) const;
    double ray_solid_angle(double density) const;
    // Follows a gathering ray through window panes (thin glass): visit(hit, direction, weight)
    // for each end of the ray tree, the ray straight on and the reflected one at each pane hit.
    template <typename Visit>
    void through_panes(const Vec3& o, const Vec3& dir, const Vec3& weight, int depth, Visit&& visit, size_t& rays) const;
    // The same from the ray's first hit, already cast.
    template <typename Visit>
    void past_panes(const SurfaceHit& hit, const Vec3& dir, const Vec3& weight, int depth, Visit&& visit, size_t& rays) const;
    // Traces n rays leaving p along world directions dirs (each lifted to its side of p's
    // surface) in packets of neighbours (RayCaster::closest_hits_from), each followed through
    // window panes: visit(m, hit, direction, weight) for each end of ray m's tree.
    template <typename Visit>
    void trace_from(const SurfacePoint& p, const Vec3* dirs, size_t n, Visit&& visit, size_t& rays) const;
    static constexpr double kMinPaneReflection = 0.01;
    // The world's radiance along an unblocked direction, as the hemispherical integrals see it:
    // the constant, or the world map without its bright part.
    Vec3 world_along(const Vec3& dir) const { return world_smooth_ ? world_smooth_->radiance(dir) : scene_.world_radiance(); }
    template <typename Incoming>
    void gather_sides(const Receiver& r, int first, int last, bool mirror, int nt, int np, double density,
                      Incoming&& incoming, Vec3* out) const;
    ScatterTable& scatter_table(const Receiver& r, int first, int last, bool mirror, int nt, int np, int nb) const;
    // A curved emitter's points on a dyadic grid over one cell of its domain, evaluated once: the
    // nodes of its cells down to a few splits are read, not evaluated (a point costs about what
    // a ray does, and a curved cell is checked at its quarters' nodes too).
    struct EmitterGrid {
        double s0, s1, t0, t1;
        std::vector<SurfacePoint> points;  // (kEmitterGridSteps + 1)^2, s fastest
    };
    static constexpr int kEmitterGridSteps = 32;
    // A parameter cell [s0, s1] x [t0, t1] of an emitter with its corners evaluated, in the order
    // (s0, t0), (s1, t0), (s0, t1), (s1, t1): a split evaluates only the points its quarters add.
    struct EmitterCell {
        double s0, s1, t0, t1;
        std::array<SurfacePoint, 4> corner;
        const EmitterGrid* grid;  // null on a flat emitter
    };
    // The emitter's point at (s, t): the grid's where it has it, else evaluated into `scratch`
    // (a reference, not a copy: reading the grid was 15% of a point-light solve with copies).
    static const SurfacePoint& emitter_point(const Surface& emitter, const EmitterGrid* grid, double s, double t,
                                             SurfacePoint& scratch);
    // The point evaluated on the grid's side of a crease along its domain cell's edge.
    static SurfacePoint point_inside(const Surface& emitter, const EmitterGrid& grid, double s, double t);
    template <typename Visit>
    void emitter_cell(const SurfacePoint& r, const Surface& emitter, const Material& light, const EmitterCell& cell,
                      int depth, double ratio, std::array<bool, 2> sides, Visit&& visit, size_t& rays) const;
    // Light arriving on the receiver's sides marked in `sides` (front: along its normal).
    template <typename Visit>
    void for_each_emitter_sample(int receiver, const SurfacePoint& r, double ratio, std::array<bool, 2> sides,
                                 Visit&& visit, size_t& rays, LightParts parts = LightParts::All) const;
    // direct() at point p of r's surface, from the lights `parts`.
    void direct_at(const Receiver& r, const SurfacePoint& p, LightParts parts, Vec3* out, size_t& rays) const;
    // Light leaving a hit on h's surface towards -dir, as h's splines read it (leaving_local; a
    // Lambertian surface's read needs only the side, not the shading frame).
    Vec3 leaving(const Receiver& h, const SurfaceHit& hit, const Vec3& dir) const;

    // A direction of a distant light's disc, and the irradiance it brings to a surface facing it.
    struct DistantSample {
        Vec3 direction;
        Vec3 irradiance;
    };

    const Scene& scene_;
    const SolverSettings& settings_;
    const RayCaster& caster_;
    // Per thread, the scatter tables of its last few glossy receivers (scatter_table()).
    mutable std::mutex scatter_mutex_;
    mutable std::unordered_map<std::thread::id, std::vector<std::unique_ptr<ScatterTable>>> scatter_tables_;
    std::vector<DistantSample> distant_;  // of all distant lights and the world map's bright part
    size_t world_bright_first_ = 0;       // where the world map's bright part begins in distant_
    std::optional<EnvironmentMap> world_smooth_;
    std::vector<int> emitters_;
    std::vector<int> self_lit_;  // curved emitters, which light themselves too
    // Each emitter's domain as cells between its creases (one cell for most), parallel to emitters_.
    std::vector<std::vector<EmitterCell>> emitter_domains_;
    std::vector<std::unique_ptr<EmitterGrid>> emitter_grids_;  // the curved emitters' cells'
    QuadratureRule cell_rule_;  // on [0, 1], for one emitter cell
    std::vector<double> cell_edges_;  // the cumulative weights of cell_rule_: node p covers [edge p, edge p+1]
    // cell_rule_ over each half of [0, 1], one node where the halves' nodes meet, and for each
    // node the index of cell_rule_'s node at the same place (-1 if none): a curved emitter cell's
    // rule over its quarters, from the points the cell's own rule evaluates plus the rest.
    QuadratureRule halves_rule_;
    std::vector<int> halves_known_;
};

}  // namespace bsgi
