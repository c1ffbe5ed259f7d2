#include "bsgi/gather.h"
#include "bsgi/cosine_rule.h"
#include "bsgi/radiance.h"
#include "bsgi/scatter_table.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <tuple>

namespace bsgi {

namespace {

// On a smooth-shaded face the cosine-weighted rule's directions (local, upper hemisphere) carry
// the shading normal's cosine instead of the geometric one: max(0, n_s . w) / w.z, with the back
// side's directions mirrored through the surface as its gather traces them.
class ShadingCosine {
public:
    ShadingCosine(const SurfacePoint& p, int side) : smooth_(smooth_shaded(p)) {
        if (!smooth_) return;
        n_ = p.frame.to_local(p.shading);
        if (side == 1) n_ = {-n_.x, -n_.y, n_.z};
    }
    double factor(const Vec3& w) const { return smooth_ ? std::max(dot(n_, w), 0.0) / w.z : 1.0; }

private:
    bool smooth_;
    Vec3 n_{0, 0, 1};
};

constexpr double kPi = 3.14159265358979323846;
// Emitter cells whose normals turn by more than about 45 degrees are split down to a tenth of
// their distance from the receiver, and, however far they are, at least kCurvedEmitterDepth
// times: a small sphere seen from afar is still a sphere, whose half facing away must not fall
// on the few nodes of one cell, and whose visibility past an occluder those nodes sample (with
// the cells left whole where their rule checked out, a sphere on a table hid most of a bulb from
// the backdrop behind it: 3.5 times too dark there, the turn of its largest cell mistaken for
// 30 degrees by the terminator rule below).
constexpr double kMaxEmitterCellBend = 0.7;
constexpr double kCurvedEmitterCellRatio = 0.1;
constexpr int kCurvedEmitterDepth = 4;
// A curved emitter's cell is checked: its rule against the same rule over its quarters, on the
// unshadowed integrand (surface points, no rays). Cells whose normals turn by less than 10
// degrees from corner to centre are not (the rule's error falls as the fourth power of the
// turn: at 20 degrees a bulb's light was within 0.3% of a fine quadrature of it).
constexpr double kCheckedEmitterCellBend = 0.985;
// How far a checked cell's rule may be off its quarters' (relative to what the cell would give
// facing the receiver, at emitter cell ratio 1) and be corrected to them rather than split:
// 0.05 takes a point light's sphere to within 0.2% of the closed form (0.7% with the curved
// cells' split alone) for 19% more rays.
constexpr double kCheckedEmitterCellTolerance = 0.05;
// A curved emitter's cell across its terminator as seen from the receiver (cos_e changes sign
// inside it) holds a kink of the integrand, max(cos_e, 0), that the cell's rule cannot follow
// (the error grows as the square of the normals' turn across the cell). Such cells are split,
// only along the terminator, until their normals turn from corner to centre by less than half
// the emitter cell ratio (the sine of 30 degrees at the presets' ratio 1: 24% more rays in a room
// lit by point lights' spheres), and not below 15 degrees however small the ratio (a floor only:
// what it saves has not been measured).
constexpr double kMinTerminatorTurn = 0.25;
constexpr int kTerminatorDepth = 7;

// B-spline quadrature (11) on [0, 1] with n coefficients: of the quadratic quasi-interpolant
// for degree 2 (with 3 coefficients this is Simpson's rule), of Schoenberg's approximation otherwise.
QuadratureRule emitter_quadrature(int n, int degree) {
    const KnotVector k = KnotVector::clamped_uniform(n, degree, 0.0, 1.0);
    return k.degree() == 2 ? quasi_interpolant_quadrature(k) : schoenberg_quadrature(k);
}

// A node of a cell's rule at its corner or centre (Simpson's rule has nine such nodes) is the
// point the cell already evaluated; any other node is evaluated.
template <typename Cell, typename Evaluate>
const SurfacePoint& known_point(const Cell& cell, const SurfacePoint& centre, double x, double y, Evaluate&& evaluate) {
    if ((x == 0 || x == 1) && (y == 0 || y == 1)) return cell.corner[(x == 1) + 2 * (y == 1)];
    if (x == 0.5 && y == 0.5) return centre;
    return evaluate();
}

}  // namespace

bool curved_emitter(const Surface& e) {
    const Vec3 n0 = e.evaluate(0.5, 0.5).frame.z;
    for (double u : {0.1, 0.5, 0.9})
        for (double v : {0.1, 0.5, 0.9})
            if (dot(e.evaluate(u, v).frame.z, n0) <= 1 - 1e-9) return true;
    return false;
}

size_t Gatherer::emitter_grid_bytes(const Surface& e) {
    if (!curved_emitter(e)) return 0;
    const auto [su, sv] = e.creases();
    const size_t side = kEmitterGridSteps + 1;
    return (su.size() + 1) * (sv.size() + 1) * (side * side * sizeof(SurfacePoint) + sizeof(EmitterGrid));
}

Vec3 directional_albedo(const Bsdf& b, const Vec3& wo) {
    const CosineRule& rule = cosine_rule(16, 32);
    Vec3 sum{0, 0, 0};
    for (int m = 0; m < rule.size(); ++m) sum += b.eval(wo, rule.direction(m)) * rule.weight(m);
    return sum * (kPi / rule.size());  // pi times the mean of rho over the cosine-weighted rule
}

Gatherer::Gatherer(const Scene& scene, const SolverSettings& settings, const RayCaster& caster)
    : scene_(scene), settings_(settings), caster_(caster), emitters_(scene.emitters()) {
    for (const int i : emitters_) {
        // A curved emitter can light itself (non-convex surfaces, the inside of a sphere); a flat
        // one cannot, and integrating over it from its own points would only cost time.
        if (curved_emitter(*scene[i].surface)) self_lit_.push_back(i);
    }
    for (const int i : emitters_) {
        // Cells start between the creases: a cell's nodes cannot follow a kink of cos_e inside it.
        const Surface& e = *scene[i].surface;
        auto [su, sv] = e.creases();
        su.insert(su.begin(), 0.0), su.push_back(1.0), sv.insert(sv.begin(), 0.0), sv.push_back(1.0);
        std::vector<EmitterCell>& cells = emitter_domains_.emplace_back();
        const bool curved = std::find(self_lit_.begin(), self_lit_.end(), i) != self_lit_.end();
        for (size_t a = 0; a + 1 < su.size(); ++a)
            for (size_t b = 0; b + 1 < sv.size(); ++b) {
                const EmitterGrid* grid = nullptr;
                SurfacePoint scratch[4];
                if (curved) {
                    auto g = std::make_unique<EmitterGrid>(EmitterGrid{su[a], su[a + 1], sv[b], sv[b + 1], {}});
                    const int m = kEmitterGridSteps;
                    g->points.reserve(size_t(m + 1) * (m + 1));
                    for (int y = 0; y <= m; ++y)
                        for (int x = 0; x <= m; ++x)
                            g->points.push_back(point_inside(e, *g, g->s0 + (g->s1 - g->s0) * x / m, g->t0 + (g->t1 - g->t0) * y / m));
                    grid = emitter_grids_.emplace_back(std::move(g)).get();
                }
                cells.push_back({su[a], su[a + 1], sv[b], sv[b + 1],
                                 {emitter_point(e, grid, su[a], sv[b], scratch[0]), emitter_point(e, grid, su[a + 1], sv[b], scratch[1]),
                                  emitter_point(e, grid, su[a], sv[b + 1], scratch[2]), emitter_point(e, grid, su[a + 1], sv[b + 1], scratch[3])},
                                 grid});
            }
    }
    cell_rule_ = emitter_quadrature(settings.emitter_coeffs, settings.emitter_degree);
    // Node p covers the share of the cell its weight gives it (midway between nodes where a
    // rule has negative weights).
    const auto& w = cell_rule_.weights;
    const bool positive = std::all_of(w.begin(), w.end(), [](double x) { return x > 0; });
    cell_edges_.assign(1, 0.0);
    for (size_t p = 0; p < w.size(); ++p)
        cell_edges_.push_back(positive ? cell_edges_.back() + w[p]
                                       : (p + 1 < w.size() ? 0.5 * (cell_rule_.nodes[p] + cell_rule_.nodes[p + 1]) : 1.0));
    for (double& e : cell_edges_) e /= cell_edges_.back();
    for (int half = 0; half < 2; ++half)
        for (size_t p = 0; p < cell_rule_.nodes.size(); ++p) {
            const double x = 0.5 * (half + cell_rule_.nodes[p]), w = 0.5 * cell_rule_.weights[p];
            if (!halves_rule_.nodes.empty() && std::abs(halves_rule_.nodes.back() - x) < 1e-12) {
                halves_rule_.weights.back() += w;
                continue;
            }
            halves_rule_.nodes.push_back(x), halves_rule_.weights.push_back(w);
            const auto same = std::find_if(cell_rule_.nodes.begin(), cell_rule_.nodes.end(),
                                           [&](double y) { return std::abs(x - y) < 1e-12; });
            halves_known_.push_back(same == cell_rule_.nodes.end() ? -1 : int(same - cell_rule_.nodes.begin()));
        }
    // Distant lights: their disc by the cell rule in 1 - cos theta (uniform in solid angle) and
    // equally spaced azimuths (exact for the cosine of a tilted receiver); the weights scaled so
    // that a surface facing the light gets its irradiance.
    for (const DistantLight& light : scene.distant_lights()) {
        const Frame f = Frame::from_normal(light.direction);
        const double cap = 1 - std::cos(0.5 * light.angle);
        const size_t n = cap > 1e-12 ? cell_rule_.nodes.size() : 1, first = distant_.size();
        double facing = 0;  // sum of weight * cos over the disc
        for (size_t p = 0; p < n; ++p)
            for (size_t k = 0; k < 2 * n; ++k) {
                const double w = n == 1 ? 1.0 : cell_rule_.weights[p];
                const double cos_t = n == 1 ? 1.0 : 1 - cap * cell_rule_.nodes[p], phi = kPi * (k + 0.5) / n;
                const double sin_t = std::sqrt(std::max(0.0, 1 - cos_t * cos_t));
                distant_.push_back({f.to_world({sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t}), light.irradiance * w});
                facing += w * cos_t;
            }
        for (size_t i = first; i < distant_.size(); ++i) distant_[i].irradiance = distant_[i].irradiance / facing;
    }
    if (const EnvironmentMap* map = scene.world_map()) {
        // The bright part (an HDRI's sun, a sky's sun disc, too small for the hemisphere nodes
        // to find) as directions for shadow rays.
        EnvironmentMap::Split split = map->split(settings.world_bright_factor, size_t(settings.world_bright_samples));
        world_bright_first_ = distant_.size();
        for (const auto& b : split.bright) distant_.push_back({b.direction, b.irradiance});
        world_smooth_.emplace(map->height(), map->width(), std::move(split.smooth));
    }
}

const SurfacePoint& Gatherer::emitter_point(const Surface& emitter, const EmitterGrid* grid, double s, double t,
                                            SurfacePoint& scratch) {
    if (!grid) return scratch = emitter.evaluate(s, t);
    const int m = kEmitterGridSteps;
    const double x = (s - grid->s0) / (grid->s1 - grid->s0) * m, y = (t - grid->t0) / (grid->t1 - grid->t0) * m;
    // Nearest grid line by truncation (not std::round, a library call here): below -0.5 the test
    // below fails as it should.
    const long i = long(x + 0.5), j = long(y + 0.5);
    if (std::abs(x - double(i)) < 1e-9 && std::abs(y - double(j)) < 1e-9 && i >= 0 && i <= m && j >= 0 && j <= m)
        return grid->points[size_t(j) * (m + 1) + size_t(i)];
    return scratch = point_inside(emitter, *grid, s, t);
}

SurfacePoint Gatherer::point_inside(const Surface& emitter, const EmitterGrid& grid, double s, double t) {
    // On a crease at the cell's edge the surface has two normals: the cell's points take the
    // one on its side (a bulb's equator seen with the neck's normal was never fine enough).
    const double es = 1e-9 * (grid.s1 - grid.s0), et = 1e-9 * (grid.t1 - grid.t0);
    return emitter.evaluate(std::clamp(s, grid.s0 + es, grid.s1 - es), std::clamp(t, grid.t0 + et, grid.t1 - et));
}

std::vector<std::pair<Vec3, double>> Gatherer::world_bright() const {
    std::vector<std::pair<Vec3, double>> out;
    if (!world_smooth_) return out;
    for (size_t i = world_bright_first_; i < distant_.size(); ++i)
        out.emplace_back(distant_[i].direction, max_component(distant_[i].irradiance));
    return out;
}

// The geometric part of (8) over the parameter cell [s0, s1] x [t0, t1] of an emitter: the
// cell's B-spline quadrature rule where the cell is small seen from the receiver, else the sum
// over its four quarters. The kernel 1/r^4 peaks where the receiver is close (contact edges,
// a lamp just above a surface), and a glossy lobe varies across a wide cell: cells shrink
// until both are resolved. visit(wi, value) gets each visible sample's unit direction (world)
// and its radiance times cos_r cos_e / d^2 times the area element and weight.
template <typename Visit>
void Gatherer::emitter_cell(const SurfacePoint& r, const Surface& emitter, const Material& light, const EmitterCell& cell,
                            int depth, double ratio, std::array<bool, 2> sides, Visit&& visit, size_t& rays) const {
    const double s0 = cell.s0, s1 = cell.s1, t0 = cell.t0, t1 = cell.t1;
    const double sm = 0.5 * (s0 + s1), tm = 0.5 * (t0 + t1);
    SurfacePoint scratch;
    const SurfacePoint centre = emitter_point(emitter, cell.grid, sm, tm, scratch);
    const Vec3 c = centre.p;
    double radius = 0, bend = 1;
    for (const SurfacePoint& corner : cell.corner) {
        radius = std::max(radius, length(corner.p - c));
        bend = std::min(bend, dot(corner.frame.z, centre.frame.z));
    }
    const double centre_dist = length(c - r.p), dist = centre_dist - radius;
    const bool curved = bend < kMaxEmitterCellBend;
    const double limit = curved ? std::min(ratio, kCurvedEmitterCellRatio) : ratio;
    // cos_e can change sign inside the cell only if at its centre it is smaller than the turn of
    // the normals plus that of the direction to the receiver across the cell (the corners' signs
    // alone miss a terminator that passes between them).
    const double cos_centre = -dot(c - r.p, centre.frame.z) / centre_dist;
    // The sine of the turn, 1 past 90 degrees (a bulb's globe as one cell, turning by 150 degrees,
    // had the sine of 30 and was left whole).
    const double turn = bend < 0 ? 1.0 : std::sqrt(1 - bend * bend);
    const bool terminator = turn > std::max(kMinTerminatorTurn, 0.5 * settings_.emitter_cell_ratio) &&
                            depth < kTerminatorDepth && std::abs(cos_centre) < turn + radius / centre_dist;
    const bool split = 2 * radius > limit * dist || (curved && depth < kCurvedEmitterDepth) || terminator;
    auto split_in_four = [&] {
        const EmitterGrid* g = cell.grid;
        const SurfacePoint bottom = emitter_point(emitter, g, sm, t0, scratch), top = emitter_point(emitter, g, sm, t1, scratch);
        const SurfacePoint left = emitter_point(emitter, g, s0, tm, scratch), right = emitter_point(emitter, g, s1, tm, scratch);
        const auto& k = cell.corner;
        emitter_cell(r, emitter, light, {s0, sm, t0, tm, {k[0], bottom, left, centre}, g}, depth + 1, ratio, sides, visit, rays);
        emitter_cell(r, emitter, light, {sm, s1, t0, tm, {bottom, k[1], centre, right}, g}, depth + 1, ratio, sides, visit, rays);
        emitter_cell(r, emitter, light, {s0, sm, tm, t1, {left, centre, k[2], top}, g}, depth + 1, ratio, sides, visit, rays);
        emitter_cell(r, emitter, light, {sm, s1, tm, t1, {centre, right, top, k[3]}, g}, depth + 1, ratio, sides, visit, rays);
    };
    if (depth < settings_.emitter_max_depth && split) {
        split_in_four();
        return;
    }
    const double ds = s1 - s0, dt = t1 - t0;
    const double offset = caster_.offset();
    const std::vector<double>& nodes = cell_rule_.nodes;
    const size_t n = nodes.size();
    // The unshadowed integrand of (8) at the emitter's point ep, without Le and the rule's
    // weight: cos_r cos_e / d^4 times the Jacobian (and a spot light's cone); 0 where no light
    // arrives (emitters radiate from their front, and their back if two-sided).
    auto geometric = [&](const SurfacePoint& ep, bool facing_receiver = false) {
        const Vec3 d = ep.p - r.p;
        const double cos_g = dot(d, r.frame.z), facing = -dot(d, ep.frame.z);
        const double d2 = dot(d, d);
        // facing_receiver: as if the emitter faced the receiver (cos_e = 1): the most it could give.
        const double cos_e = facing_receiver ? std::sqrt(d2) : light.two_sided_emission ? std::abs(facing) : facing;
        if (cos_e <= 0 || cos_g == 0 || !sides[cos_g < 0]) return 0.0;
        const double cos_r = receiver_cosine(r, d);  // the shading normal's, on a smooth face
        const double cone = light.cone ? light.cone->factor(-d / std::sqrt(d2)) : 1.0;  // a spot light's
        return cone <= 0 ? 0.0 : cone * cos_r * cos_e / (d2 * d2) * ep.jacobian;
    };
    // The cell's points and integrand at its rule's nodes, 0 outside the domain (the mask chi
    // of (8)); per thread, reused by each leaf cell (no cell reads them after a split).
    // points: the grid's, the cell's corners and centre, or those evaluated into `evaluated`.
    thread_local std::vector<const SurfacePoint*> points;
    thread_local std::vector<SurfacePoint> evaluated;
    thread_local std::vector<double> integrand;
    points.resize(n * n), evaluated.resize(n * n), integrand.assign(n * n, 0.0);
    const bool checked = bend < kCheckedEmitterCellBend;
    double coarse = 0, most = 0;  // most: the cell's integral as if it faced the receiver
    for (size_t p = 0; p < n; ++p)
        for (size_t k = 0; k < n; ++k) {
            const double s = s0 + ds * nodes[p], t = t0 + dt * nodes[k];
            if (!emitter.in_domain(s, t)) continue;
            const SurfacePoint& ep = *(points[p * n + k] = &known_point(cell, centre, nodes[p], nodes[k], [&]() -> const SurfacePoint& {
                return emitter_point(emitter, cell.grid, s, t, evaluated[p * n + k]);
            }));
            const double w = cell_rule_.weights[p] * cell_rule_.weights[k];
            coarse += w * (integrand[p * n + k] = geometric(ep));
            if (checked) most += w * geometric(ep, true);
        }
    // A curved cell's rule misses how cos_e and the Jacobian vary across it (a bulb's cells
    // turning by 45 degrees were 1-3% bright seen from the side). The same unshadowed integral
    // by the rule over the cell's quarters costs surface evaluations but no rays: where the two
    // differ by more than the tolerance the cell is split, else its samples are scaled by their
    // ratio (the quarters' error is the rule's order smaller).
    double correction = 1;
    if (checked) {
        const std::vector<double>& x = halves_rule_.nodes;
        double fine = 0;
        for (size_t a = 0; a < x.size(); ++a)
            for (size_t b = 0; b < x.size(); ++b) {
                const int pa = halves_known_[a], pb = halves_known_[b];
                const double s = s0 + ds * x[a], t = t0 + dt * x[b];
                const double g = pa >= 0 && pb >= 0 ? integrand[pa * n + pb]
                                 : emitter.in_domain(s, t) ? geometric(emitter_point(emitter, cell.grid, s, t, scratch)) : 0.0;
                fine += halves_rule_.weights[a] * halves_rule_.weights[b] * g;
            }
        // Relative to what the cell would give if it faced the receiver: a cell the terminator
        // crosses, mostly turned away, is not split without end for a small absolute error.
        const bool coarse_fails = std::abs(fine - coarse) > kCheckedEmitterCellTolerance * ratio * most;
        if (coarse_fails && depth < settings_.emitter_max_depth) {
            split_in_four();
            return;
        }
        if (coarse > 0) correction = fine / coarse;
    }
    // A cell the receiver sees partly shadowed (a penumbra) is split while it is, down to
    // emitter_shadow_depth: the nodes' visibility is then resolved finely only where it
    // changes. Its samples are kept until the cell is known to be whole.
    const bool shadow_split = depth < settings_.emitter_shadow_depth;
    std::vector<std::pair<Vec3, Vec3>> kept;
    if (shadow_split) kept.reserve(n * n);  // one allocation a cell, in the hot loop
    int lit = 0, dark = 0;
    // Each node stands for the part of the cell its weight covers: an emission texture is
    // averaged over that part (exact for the integral where the geometric factor is constant).
    const std::vector<double>& edge = cell_edges_;
    for (size_t p = 0; p < n; ++p)
        for (size_t k = 0; k < n; ++k) {
            const double g = integrand[p * n + k];
            if (g <= 0) continue;
            const SurfacePoint& ep = *points[p * n + k];
            const Vec3 d = ep.p - r.p;
            const double facing = -dot(d, ep.frame.z), len = length(d);
            // Both ends lifted off their surfaces, and the segment stopped short of the emitter,
            // so neither surface, nor one meeting the emitter along its edge, shadows it.
            const Vec3 origin = caster_.spawn(r.p, r.frame.z, d);
            const Vec3 segment = ep.p + ep.frame.z * (facing > 0 ? offset : -offset) - origin;
            const double stop = 1.0 - 2 * offset / length(segment);
            ++rays;
            if (stop <= 0) continue;
            const Vec3 pass = caster_.transmittance(origin, segment, 0.0, stop);  // 0: shadowed; < 1: through panes
            const bool through = max_component(pass) > 0;
            ++(through ? lit : dark);
            if (!through) continue;
            const double w = cell_rule_.weights[p] * cell_rule_.weights[k] * ds * dt;
            const Vec3 Le = light.emission_over(s0 + ds * edge[p], s0 + ds * edge[p + 1], t0 + dt * edge[k], t0 + dt * edge[k + 1]);
            const Vec3 value = Le * pass * (w * g * correction);
            if (shadow_split) kept.emplace_back(d / len, value);
            else visit(d / len, value);
        }
    if (!shadow_split) return;
    if (lit && dark) {
        split_in_four();
        return;
    }
    for (const auto& [wi, value] : kept) visit(wi, value);
}

template <typename Visit>
void Gatherer::for_each_emitter_sample(int receiver, const SurfacePoint& r, double ratio, std::array<bool, 2> sides,
                                       Visit&& visit, size_t& rays, LightParts parts) const {
    for (size_t i = 0; i < emitters_.size(); ++i) {
        const int e = emitters_[i];
        if (parts == LightParts::Distant) break;
        if (e == receiver && std::find(self_lit_.begin(), self_lit_.end(), e) == self_lit_.end()) continue;
        const SceneSurface& es = scene_[e];
        for (const EmitterCell& cell : emitter_domains_[i])
            emitter_cell(r, *es.surface, es.material, cell, 0, ratio, sides, visit, rays);
    }
    for (const DistantSample& d : distant_) {
        if (parts == LightParts::Emitters) break;
        const double cos_r = dot(d.direction, r.frame.z);
        if (cos_r == 0 || !sides[cos_r < 0]) continue;
        ++rays;
        const Vec3 pass = caster_.transmittance(caster_.spawn(r.p, r.frame.z, d.direction), d.direction);
        if (!(max_component(pass) > 0)) continue;
        visit(d.direction, d.irradiance * pass * receiver_cosine(r, d.direction));
    }
}

Vec3 Gatherer::irradiance(int surface, const SurfacePoint& p, size_t& rays, std::array<bool, 2> sides) const {
    Vec3 e{0, 0, 0};
    for_each_emitter_sample(surface, p, settings_.emitter_cell_ratio, sides,
                            [&](const Vec3&, const Vec3& value) { e += value; }, rays);
    return e;
}

void Gatherer::direct(const Receiver& r, size_t j, Vec3* out, size_t& rays) const {
    direct_at(r, node_point(r, j), LightParts::All, out, rays);
}

double Gatherer::distant_light_at(const Receiver& r, double u, double v, int side, size_t& rays) const {
    if (distant_.empty() || r.per_node != 1 || side >= r.sides) return 0;
    Vec3 out[2];
    direct_at(r, scene_[r.surface].surface->evaluate(u, v), LightParts::Distant, out, rays);
    return out[side].x + out[side].y + out[side].z;
}

void Gatherer::direct_over_support(const Receiver& r, size_t j, const std::vector<const Receiver*>& receiver_of, Vec3* out,
                                   size_t& rays) const {
    const std::vector<double>&us = r.nodes.axis(0), &vs = r.nodes.axis(1);
    const SpatialNode node = r.nodes[j];
    const size_t i = us.empty() || vs.empty() ? 0 : j / vs.size(), k = vs.empty() ? 0 : j % vs.size();
    // (A node moved off its place, a hidden one to a contact line, keeps its basis function
    // B_i B_k: its support is the grid's. basis_at below holds at most degree 7.)
    if (!settings_.distant_support_means || distant_.empty() || us.empty() || vs.empty() || (*r.axes)[0].degree() > 7 ||
        (*r.axes)[1].degree() > 7) {
        direct(r, j, out, rays);
        return;
    }
    const Surface& surface = *scene_[r.surface].surface;
    const size_t n = r.sides * r.per_node;
    const SurfacePoint p = surface.evaluate(node.u, node.v);
    direct_at(r, p, LightParts::Emitters, out, rays);
    std::vector<Vec3> sun(n), at(n);
    direct_at(r, p, LightParts::Distant, sun.data(), rays);
    // The node's basis function B_i(u) B_k(v): where it is not zero, and its value. Its mean of
    // the light weighed by it makes the coefficients' integral the light's (sum_i c_i int B_i =
    // int f where every c_i is such a mean): the patch keeps its light at any resolution.
    const KnotVector &ku = (*r.axes)[0], &kv = (*r.axes)[1];
    auto support = [](const KnotVector& kn, size_t c, double& lo, double& hi) {
        const auto& t = kn.knots();
        lo = std::max(t[c], kn.domain_begin()), hi = std::min(t[c + size_t(kn.degree()) + 1], kn.domain_end());
    };
    auto basis_at = [](const KnotVector& kn, size_t c, double x) {
        const int span = kn.find_span(x), d = kn.degree();
        if (int(c) < span - d || int(c) > span) return 0.0;
        double b[8];
        kn.basis(x, span, b);
        return b[int(c) - (span - d)];
    };
    double u0, u1, v0, v1;
    support(ku, i, u0, u1);
    support(kv, k, v0, v1);
    auto brightness = [n](const std::vector<Vec3>& x) {
        double b = 0;
        for (size_t a = 0; a < n; ++a) b += x[a].x + x[a].y + x[a].z;
        return b;
    };
    // The light's mean over an m x m grid of cells over the support, weighed by the basis
    // function, sampled at (shift_u, shift_v) of each cell; its lowest and highest value (with
    // the node's) in lo, hi.
    std::vector<Vec3> mean(n);
    double lo = 0, hi = 0;
    auto mean_over = [&](int m, double shift_u, double shift_v) {
        std::fill(mean.begin(), mean.end(), Vec3{0, 0, 0});
        double total = 0;
        lo = hi = brightness(sun);
        for (int a = 0; a < m; ++a) {
            const double u = u0 + (a + shift_u) / m * (u1 - u0), bu = basis_at(ku, i, u);
            for (int b = 0; b < m; ++b) {
                const double v = v0 + (b + shift_v) / m * (v1 - v0), w = bu * basis_at(kv, k, v);
                if (!(w > 0)) continue;
                const SurfacePoint q = surface.evaluate(u, v);
                direct_at(r, q, LightParts::Distant, at.data(), rays);
                const double light = brightness(at);
                // Points no viewer sees (under a block resting on the surface: unlit, as a shadow
                // is) are left out: they darkened the seen floor beside the block, though no ray
                // meets them. (A lit point is seen: the sun reaches it.)
                if (light <= 0 && hidden(r, q, receiver_of, rays)) continue;
                lo = std::min(lo, light), hi = std::max(hi, light);
                for (size_t c = 0; c < n; ++c) mean[c] += at[c] * w;
                total += w;
            }
        }
        return total;
    };
    // An edge crosses the support where the light at the midpoints of 4 x 4 cells differs from
    // the node's (at 3 x 3 midpoints a block's shadow over a corner of a wide support went
    // unseen: the sunlit room's coarse floor 0.88-0.90 of its light at 8 and 12 coefficients;
    // 6 x 6 found no more than 4 x 4, for twice the rays).
    // Its mean is then taken over 16 x 16 cells, each sampled at a point shifted by a fraction
    // that differs from node to node (a 2D golden-ratio sequence): at the cells' midpoints every
    // node's samples stood on one grid of half-spans, and each edge counted as if moved to its
    // nearest line of it, alike in every node's mean. The sunlit room's coarse floor (its light
    // on the parts seen, against the light there) 0.99, 0.99, 0.99 and 0.98 at 8, 12, 16 and 48
    // coefficients; the room without its block and box -14%, +7%, -5% off at 8, 12, 48 with
    // 6 x 6 midpoints, -0.5%, -0.8%, -1.2% so (12 x 12 shifted cells: +2.3%, -2.6%, -1.1%).
    if (mean_over(4, 0.5, 0.5) > 0 && hi - lo > kEdgeContrast * std::max(std::abs(hi), std::abs(lo))) {
        const double shift_u = std::fmod(0.5 + 0.7548776662466927 * double(j), 1.0);
        const double shift_v = std::fmod(0.5 + 0.5698402909980532 * double(j), 1.0);
        const double total = mean_over(16, shift_u, shift_v);
        if (total > 0) {
            for (size_t c = 0; c < n; ++c) sun[c] = mean[c] * (1.0 / total);
            if (j < r.support_means.size()) r.support_means[j] = 1;
        }
    }
    for (size_t c = 0; c < n; ++c) out[c] += sun[c];
}

void Gatherer::direct_at(const Receiver& r, const SurfacePoint& p, LightParts parts, Vec3* out, size_t& rays) const {
    const size_t n = r.sides * r.per_node;
    std::fill(out, out + n, Vec3{0, 0, 0});
    // Glossy receivers: emitter cells no wider than a fraction of the lobe, seen from here.
    const double ratio = r.kind == Representation::Glossy
                             ? std::min(settings_.emitter_cell_ratio, 0.5 * std::max(r.bsdf->lobe_width(), 0.02))
                             : settings_.emitter_cell_ratio;
    // Light arrives on the sides solved, or on both where the surface transmits.
    const bool transmits = r.bsdf->transmits();
    const std::array<bool, 2> sides{transmits || r.solves(0), transmits || r.solves(1)};
    const Frame frame = radiance_frame(p);  // the BSDF's frame: the shading frame on a smooth face
    for_each_emitter_sample(r.surface, p, ratio, sides, [&](const Vec3& wi_world, const Vec3& value) {
        const Vec3 wi = frame.to_local(wi_world);
        for (int side = 0; side < r.sides; ++side)
            if (r.solves(side))
                for (size_t a = 0; a < r.per_node; ++a) out[side * r.per_node + a] += r.scatter(side, a, wi) * value;
    }, rays, parts);
}

// The albedo texture as a ray sees it: box-filtered over the ray's footprint, the solid angle
// of one integration direction spread over the hit surface at the hit's distance and slant
// (a checker far away is its mean colour, close by its squares).
Vec3 Gatherer::texel_seen(const Texture& texture, const SurfaceHit& hit, const Vec3& dir, double solid_angle) const {
    const SurfacePoint p = scene_[hit.surface].surface->evaluate(hit.u, hit.v);
    const double slant = std::max(std::abs(dot(dir, p.frame.z)), 0.1);
    const double side = hit.t * std::sqrt(solid_angle / slant);  // of the footprint, on the surface
    const double su = length(p.dpdu), sv = length(p.dpdv);
    return texture.filtered(hit.u, hit.v, su > 0 ? 0.5 * side / su : 0.5, sv > 0 ? 0.5 * side / sv : 0.5);
}

double Gatherer::ray_solid_angle(double density) const {
    return 2 * kPi / (double(nodes_along(settings_.hemisphere_nodes_theta, density)) * nodes_along(settings_.hemisphere_nodes_phi, density));
}

Vec3 Gatherer::leaving(const Receiver& h, const SurfaceHit& hit, const Vec3& dir) const {
    if (h.kind == Representation::Diffuse && !h.partner) return hit.frame.to_local(-dir);  // (its side alone)
    if (h.normals) {  // seen from either side, its radiance is its bumped normal's there
        const Vec3 n = bumped_normal(*h.normals, hit.u, hit.v);
        return dot(dir, hit.frame.z) <= 0 ? n : -n;
    }
    SurfaceHit shaded = hit;
    caster_.look_up_shading(shaded);
    return leaving_local(shaded, dir);
}

Vec3 Gatherer::seen_radiance(const Receiver& h, Receiver::Splines which, const SurfaceHit& hit, const Vec3& dir,
                             double solid_angle) const {
    const Texture* detail = h.albedo ? h.albedo : h.tint;
    Vec3 texel = detail ? texel_seen(*detail, hit, dir, solid_angle) : Vec3{1, 1, 1};
    const Vec3 local = leaving(h, hit, dir);
    if (h.albedo && h.coat) texel = h.coat->texel(texel, std::abs(local.z));
    // A tinted pair: f0 = 1 weighed by the texel, f0 = 0 by its complement.
    return h.radiance(which, hit.u, hit.v, local, texel, h.tint ? Vec3{1, 1, 1} - texel : Vec3{1, 1, 1});
}

void Gatherer::indirect(const Receiver& r, size_t j, const std::vector<const Receiver*>& receiver_of,
                        Receiver::Splines which, double density, bool with_world, Vec3* out, size_t& rays) const {
    const double solid_angle = ray_solid_angle(density);
    hemisphere(r, j, density, [&](const SurfaceHit& hit, const Vec3& dir) -> Vec3 {
        if (hit.surface < 0) return with_world ? world_along(dir) : Vec3{0, 0, 0};
        const Receiver* h = receiver_of[hit.surface];
        return h ? seen_radiance(*h, which, hit, dir, solid_angle) : Vec3{0, 0, 0};
    }, out, rays);
}

double InputScales::at(int surface, double u, double v) const {
    auto cell = [](double x, int& i) {  // the lower cell centre's index and the weight of the next
        const double t = std::clamp(x * kCells - 0.5, 0.0, double(kCells - 1));
        i = std::min(int(t), kCells - 2);
        return t - i;
    };
    int iu, iv;
    const double fu = cell(u, iu), fv = cell(v, iv);
    const double* s = &values_[values_for(size_t(surface))];
    auto value = [&](int a, int b) { return s[b * kCells + a]; };
    return (1 - fv) * ((1 - fu) * value(iu, iv) + fu * value(iu + 1, iv)) + fv * ((1 - fu) * value(iu, iv + 1) + fu * value(iu + 1, iv + 1));
}

bool Gatherer::indirect_change(const Receiver& r, size_t j, const std::vector<const Receiver*>& now_of,
                               const std::vector<const Receiver*>& before_of, double density, double lobe_width, Vec3* out,
                               size_t& rays, const InputScales* scale_of) const {
    const double solid_angle = ray_solid_angle(density);
    bool glossy = false;
    hemisphere(r, j, density, [&](const SurfaceHit& hit, const Vec3& dir) -> Vec3 {
        if (hit.surface < 0) return {0, 0, 0};
        const Receiver *now = now_of[hit.surface], *before = before_of[hit.surface];
        Vec3 change{0, 0, 0};
        if (now) change += seen_radiance(*now, &Receiver::Le, hit, dir, solid_angle), glossy |= now->kind != Representation::Diffuse && now->bsdf->lobe_width() < lobe_width;
        if (before) change -= seen_radiance(*before, &Receiver::Le, hit, dir, solid_angle);
        return scale_of ? change * scale_of->at(hit.surface, hit.u, hit.v) : change;
    }, out, rays);
    return glossy;
}

bool Gatherer::enclosed(const SurfacePoint& p, int side, const std::vector<const Receiver*>& receiver_of,
                        size_t& rays) const {
    const Vec3 n = side == 0 ? p.frame.z : -p.frame.z;
    // 4 x 4 cosine-weighted cells and the normal: a node beside the block sees its lit outside
    // (or the room) along most of them, one under it along none.
    constexpr int kCells = 4;
    for (int c = 0; c <= kCells * kCells; ++c) {
        Vec3 local{0, 0, 1};
        if (c < kCells * kCells) {
            const double s2 = (c / kCells + 0.5) / kCells, phi = 2 * kPi * (c % kCells + 0.5) / kCells;
            const double sin_t = std::sqrt(s2);
            local = {sin_t * std::cos(phi), sin_t * std::sin(phi), std::sqrt(1 - s2)};
        }
        if (side == 1) local.z = -local.z;
        const Vec3 dir = p.frame.to_world(local);
        ++rays;
        const SurfaceHit hit = caster_.closest_hit(caster_.spawn(p.p, n, dir), dir);
        if (hit.surface < 0 || caster_.pane(hit.surface) || scene_[hit.surface].material.emits()) return false;
        const int seen = dot(dir, hit.frame.z) < 0 ? 0 : 1;
        const Receiver* h = receiver_of[hit.surface];
        if (h && h->solves(seen)) return false;
    }
    return true;
}

bool Gatherer::hidden(const Receiver& r, const SurfacePoint& p, const std::vector<const Receiver*>& receiver_of,
                      size_t& rays) const {
    for (int side = 0; side < r.sides; ++side)
        if (r.solves(side) && enclosed(p, side, receiver_of, rays)) return true;
    return false;
}

void Gatherer::world(const Receiver& r, size_t j, Vec3* out, size_t& rays) const {
    hemisphere(r, j, 1, [&](const SurfaceHit& hit, const Vec3& dir) { return hit.surface < 0 ? world_along(dir) : Vec3{0, 0, 0}; },
               out, rays);
}

template <typename Visit>
void Gatherer::through_panes(const Vec3& o, const Vec3& dir, const Vec3& weight, int depth, Visit&& visit, size_t& rays) const {
    ++rays;
    past_panes(caster_.closest_hit(o, dir), dir, weight, depth, visit, rays);
}

template <typename Visit>
void Gatherer::past_panes(const SurfaceHit& hit, const Vec3& dir, const Vec3& weight, int depth, Visit&& visit, size_t& rays) const {
    const ThinGlass* glass = caster_.pane(hit.surface);
    if (!glass) {
        visit(hit, dir, weight);
        return;
    }
    if (depth >= RayCaster::kMaxPanes) return;
    // The pane passes 1 - R straight on and reflects R (the thin sheet's factors, times its
    // tints): one ray each, the reflected one only while it carries a noticeable share (a pane's
    // second reflection carries under 1% at normal incidence).
    const Vec3 n = hit.frame.z;
    const double c = dot(dir, n), R = glass->reflectance(c);  // (once: both rays' factors)
    through_panes(caster_.spawn(hit.p, n, dir), dir, weight * glass->transmission_tint * (1 - R), depth + 1, visit, rays);
    const Vec3 reflected = weight * glass->reflection_tint * R;
    if (max_component(reflected) > kMinPaneReflection) {
        const Vec3 mirrored = dir - n * (2 * c);
        through_panes(caster_.spawn(hit.p, n, mirrored), mirrored, reflected, depth + 1, visit, rays);
    }
}

template <typename Visit>
void Gatherer::trace_from(const SurfacePoint& p, const Vec3* dirs, size_t n, Visit&& visit, size_t& rays) const {
    thread_local std::vector<SurfaceHit> hits;
    hits.resize(n);
    for (size_t begin = 0; begin < n;) {  // runs of directions on one side share their origin
        const bool front = dot(dirs[begin], p.frame.z) >= 0;
        size_t end = begin + 1;
        while (end < n && (dot(dirs[end], p.frame.z) >= 0) == front) ++end;
        caster_.closest_hits_from(caster_.spawn(p.p, p.frame.z, dirs[begin]), dirs + begin, end - begin, hits.data() + begin);
        begin = end;
    }
    rays += n;
    for (size_t m = 0; m < n; ++m)
        past_panes(hits[m], dirs[m], Vec3{1, 1, 1}, 0, [&](const SurfaceHit& hit, const Vec3& d, const Vec3& w) { visit(m, hit, d, w); },
                   rays);
}

template <typename Incoming>
void Gatherer::hemisphere(const Receiver& r, size_t j, double density, Incoming&& radiance_along, Vec3* out,
                          size_t& rays) const {
    const SurfacePoint p = node_point(r, j);
    const size_t n = r.sides * r.per_node;
    std::fill(out, out + n, Vec3{0, 0, 0});
    const int nt = nodes_along(settings_.hemisphere_nodes_theta, density), np = nodes_along(settings_.hemisphere_nodes_phi, density);
    // Incoming radiance L[m] along each local direction local[m] (pointing away from the
    // surface; mirrored below it for an opaque back side's gather, see Receiver::scatter). A
    // lobe's directions are in the radiance frame (the shading frame on a smooth face: Cycles
    // turns the BSDF with the shading normal; those below the face itself meet the object's
    // inside, as Cycles' do); the Lambertian rule's in the geometric frame (ShadingCosine).
    const Frame frame = r.kind == Representation::Diffuse ? p.frame : radiance_frame(p);
    thread_local std::vector<Vec3> dirs;
    auto incoming = [&](const Vec3* local, size_t count, bool mirror, Vec3* L) {
        dirs.resize(count);
        for (size_t m = 0; m < count; ++m) {
            dirs[m] = frame.to_world(mirror ? Vec3{local[m].x, local[m].y, -local[m].z} : local[m]);
            L[m] = {0, 0, 0};
        }
        trace_from(p, dirs.data(), count, [&](size_t m, const SurfaceHit& hit, const Vec3& d, const Vec3& w) {
            L[m] += radiance_along(hit, d) * w;
        }, rays);
    };
    // Transmitting surfaces gather from both sides into both; an opaque one gathers each side it
    // solves from that side alone, with its directions mirrored for the back (Receiver::scatter).
    if (r.bsdf->transmits()) {
        gather_sides(r, 0, r.sides, false, nt, np, density, incoming, out);
        return;
    }
    for (int side = 0; side < r.sides; ++side) {
        if (!r.solves(side)) continue;
        if (r.kind == Representation::Diffuse) {
            // Lambertian: the cosine-weighted rule is exact for the BSDF; rho/pi * pi * mean.
            const CosineRule& rule = cosine_rule(nt, np);
            thread_local std::vector<Vec3> L;
            L.resize(size_t(rule.size()));
            incoming(rule.directions(), L.size(), side == 1, L.data());
            Vec3 sum{0, 0, 0};
            const ShadingCosine shading(p, side);
            for (int m = 0; m < rule.size(); ++m) sum += L[m] * (rule.weight(m) * shading.factor(rule.direction(m)));
            out[side * r.per_node] = r.bsdf->eval({0, 0, 1}, {0, 0, 1}) * kPi * sum / double(rule.size());
            continue;
        }
        gather_sides(r, side, side + 1, side == 1, nt, np, density, incoming, out);
    }
}

// The hemispherical integral into the values of sides [first, last) of node out: multiple
// importance sampling of the cosine nodes and, per outgoing direction, bsdf_samples
// BSDF-sampled directions (balance heuristic), the BSDF's factors read from the receiver's
// ScatterTable. Incoming light from both sides where the surface transmits; for the mirrored
// back side of an opaque surface, everything is computed as on the front and `incoming`
// mirrors the directions. All directions are traced first, together.
template <typename Incoming>
void Gatherer::gather_sides(const Receiver& r, int first, int last, bool mirror, int nt, int np, double density,
                            Incoming&& incoming, Vec3* out) const {
    const int nb = r.bsdf->gathered_by_draws() ? nodes_along(settings_.bsdf_samples, density) : 0;
    ScatterTable& table = scatter_table(r, first, last, mirror, nt, np, nb);
    const size_t values = size_t(last - first) * r.per_node;
    Vec3* sides_out = out + size_t(first) * r.per_node;
    const std::vector<ScatterTable::Sample>& samples = table.samples();
    thread_local std::vector<Vec3> wi, L;
    const size_t nodes = table.incoming_count();
    wi.resize(nodes);
    for (size_t t = 0; t < nodes; ++t) wi[t] = table.incoming(t);
    const size_t per_value = table.samples_per_value();
    for (size_t k = 0; k < values * per_value; ++k)
        if (samples[k].kind != ScatterTable::Sample::Kind::None) wi.push_back(samples[k].wi);
    L.resize(wi.size());
    incoming(wi.data(), wi.size(), mirror, L.data());
    for (size_t t = 0; t < nodes; ++t) {
        if (is_zero(L[t])) continue;  // (a regather's change is signed)
        const ScatterTable::Term* terms = table.terms(t);
        for (size_t v = 0; v < values; ++v)
            if (terms[v].scale != 0) sides_out[v] += L[t] * terms[v].f * terms[v].scale;
    }
    size_t next = nodes;
    for (size_t v = 0; v < values; ++v)
        for (size_t m = 0; m < per_value; ++m) {
            const ScatterTable::Sample& s = samples[v * per_value + m];
            if (s.kind == ScatterTable::Sample::Kind::None) continue;
            const Vec3& Ls = L[next++];
            if (is_zero(Ls)) continue;
            sides_out[v] += s.kind == ScatterTable::Sample::Kind::Delta ? Ls * s.f / double(nb) : Ls * s.f * s.scale;
        }
}

// The table of the last few (receiver, density, sides) this thread gathered: a thread takes
// nodes of one receiver after another, and a regather alternates two densities at a node.
// Each thread's tables live as long as this gatherer (a solve's), not as long as the thread.
ScatterTable& Gatherer::scatter_table(const Receiver& r, int first, int last, bool mirror, int nt, int np, int nb) const {
    std::vector<std::unique_ptr<ScatterTable>>* recent;
    {
        std::lock_guard<std::mutex> lock(scatter_mutex_);
        recent = &scatter_tables_[std::this_thread::get_id()];  // stays put when the map grows
    }
    for (size_t k = 0; k < recent->size(); ++k)
        if ((*recent)[k]->matches(r, first, last, mirror, nt, np, nb)) {
            std::rotate(recent->begin(), recent->begin() + k, recent->begin() + k + 1);
            return *recent->front();
        }
    if (recent->size() == ScatterTable::kRecent) recent->pop_back();
    recent->insert(recent->begin(), std::make_unique<ScatterTable>(r, first, last, mirror, nt, np, nb));
    return *recent->front();
}

namespace {

// (coefficient number, weight) of the basis functions non-zero at x: the tensor products of
// each axis' degree + 1 basis values (paper (14)).
void basis_terms(const TensorSpline& s, const double* x, std::vector<std::pair<size_t, double>>& out) {
    const int D = s.dims();
    double basis[8][kMaxDegree + 1];
    size_t first[8], stride[8];
    int order[8];
    size_t st = 1;
    for (int k = D - 1; k >= 0; --k) stride[k] = st, st *= s.axis(k).num_coeffs();
    for (int k = 0; k < D; ++k) {
        const KnotVector& a = s.axis(k);
        const int span = a.find_span(x[k]);
        a.basis(x[k], span, basis[k]);
        first[k] = size_t(span - a.degree());
        order[k] = a.degree() + 1;
    }
    int idx[8] = {0};
    out.clear();
    for (;;) {
        double w = 1;
        size_t offset = 0;
        for (int k = 0; k < D; ++k) w *= basis[k][idx[k]], offset += (first[k] + idx[k]) * stride[k];
        if (w != 0) out.emplace_back(offset, w);
        int k = D - 1;
        while (k >= 0 && ++idx[k] == order[k]) idx[k--] = 0;
        if (k < 0) break;
    }
}

}  // namespace

void Gatherer::transport_row(const Receiver& r, int side_out, size_t j, const std::vector<const Receiver*>& receiver_of,
                             std::vector<TransportTerm>& row, size_t& rays) const {
    const SurfacePoint p = node_point(r, j);
    const int nt = settings_.hemisphere_nodes_theta, np = settings_.hemisphere_nodes_phi;
    const CosineRule& rule = cosine_rule(nt, np);
    const ShadingCosine shading(p, side_out);
    std::vector<std::pair<size_t, double>> terms;
    std::vector<TransportTerm> raw;
    thread_local std::vector<Vec3> dirs;
    dirs.resize(size_t(rule.size()));
    for (int m = 0; m < rule.size(); ++m) {
        Vec3 wi = rule.direction(m);
        if (side_out == 1) wi.z = -wi.z;  // the back side gathers from below
        dirs[m] = p.frame.to_world(wi);
    }
    // Through window panes too: the terms of each surface seen, weighted by what the panes pass
    // (grey: rows are built only without coloured transport, Scene::has_coloured_transport).
    trace_from(p, dirs.data(), dirs.size(), [&](size_t m, const SurfaceHit& hit, const Vec3& d, const Vec3& through) {
        const double pass = through.x;
        if (hit.surface < 0 || !receiver_of[hit.surface]) return;
        // rho/pi * pi * mean; albedo applied later
        const double scale = kPi * rule.weight(int(m)) * shading.factor(rule.direction(int(m))) / rule.size();
        const Vec3 local = leaving(*receiver_of[hit.surface], hit, d);
        const int side = local.z >= 0 ? 0 : 1;
        for (const Receiver* h = receiver_of[hit.surface]; h; h = h->is_partner ? nullptr : h->partner) {
            if (!h->solves(side)) continue;
            double x[4] = {hit.u, hit.v, 0, 0};
            if (h->kind != Representation::Diffuse) h->map.to_disc(local.x, local.y, std::abs(local.z), x + 2);
            basis_terms(h->L[side], x, terms);
            for (const auto& [index, w] : terms)
                raw.push_back({uint32_t(h->index), uint32_t(index), uint8_t(side), float(w * pass * scale)});
        }
    }, rays);
    // Merge the terms of rays that land on the same coefficients.
    std::sort(raw.begin(), raw.end(), [](const TransportTerm& a, const TransportTerm& b) {
        return std::tie(a.receiver, a.side, a.index) < std::tie(b.receiver, b.side, b.index);
    });
    row.clear();
    for (const TransportTerm& t : raw) {
        if (!row.empty() && row.back().receiver == t.receiver && row.back().side == t.side && row.back().index == t.index)
            row.back().weight += t.weight;
        else
            row.push_back(t);
    }
    row.shrink_to_fit();
}

}  // namespace bsgi
