#include "bsgi/mesh_chart.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace bsgi {

namespace {

constexpr double kUvTolerance = 1e-6;  // UVs this far outside [0, 1] are rounding, not errors
constexpr double kInside = 1e-12;      // barycentric slack of the point-in-triangle test

double cross2(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

}  // namespace

MeshChart::MeshChart(std::string name, std::vector<double> positions, std::vector<uint32_t> triangles,
                     std::vector<double> corner_uvs, const std::vector<double>& corner_normals)
    : Surface(std::move(name)) {
    auto fail = [&](const std::string& what) { throw std::invalid_argument("surface '" + this->name() + "': " + what); };
    if (positions.size() % 3 != 0) fail("positions must have 3 values per vertex");
    if (triangles.size() % 3 != 0) fail("triangles must have 3 vertex indices each");
    if (positions.empty() || triangles.empty()) fail("empty mesh (no vertices or no triangles)");
    const size_t nv = positions.size() / 3, nt = triangles.size() / 3;
    if (corner_uvs.size() != 6 * nt) {
        std::ostringstream msg;
        msg << "expected 2 UV values for each of the " << 3 * nt << " triangle corners, got " << corner_uvs.size();
        fail(msg.str());
    }
    if (!corner_normals.empty()) {
        if (corner_normals.size() != 9 * nt)
            fail("expected 3 normal values for each of the " + std::to_string(3 * nt) + " triangle corners, got " +
                 std::to_string(corner_normals.size()));
        std::vector<Vec3> given(3 * nt);
        for (size_t c = 0; c < 3 * nt; ++c) given[c] = {corner_normals[3 * c], corner_normals[3 * c + 1], corner_normals[3 * c + 2]};
        corner_normals_ = checked_corner_normals(this->name(), given.data(), int(given.size()));
    }
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    positions_.resize(nv);
    for (size_t i = 0; i < nv; ++i) {
        const Vec3 p{positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]};
        if (!is_finite(p)) fail("vertex " + std::to_string(i) + " is NaN or infinite");
        positions_[i] = p;
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    }
    size_ = length(hi - lo);
    if (!(size_ > 0)) fail("all vertices coincide (no surface)");

    tris_.resize(nt);
    std::vector<Vec3> vertex_normals(nv);
    Vec3 mean_normal{0, 0, 0};
    for (size_t t = 0; t < nt; ++t) {
        Triangle& T = tris_[t];
        for (int c = 0; c < 3; ++c) {
            T.v[c] = triangles[3 * t + c];
            if (T.v[c] >= nv) fail("triangle " + std::to_string(t) + " uses vertex " + std::to_string(T.v[c]) + " of " + std::to_string(nv));
            for (int a = 0; a < 2; ++a) {
                double x = corner_uvs[6 * t + 2 * c + a];
                if (!std::isfinite(x)) fail("UV of triangle " + std::to_string(t) + " is NaN or infinite");
                if (x < -kUvTolerance || x > 1 + kUvTolerance) {
                    std::ostringstream msg;
                    msg << "UV (" << corner_uvs[6 * t + 2 * c] << ", " << corner_uvs[6 * t + 2 * c + 1] << ") of triangle " << t
                        << " is outside [0, 1]^2, the chart's parameter domain: normalise the UV map";
                    fail(msg.str());
                }
                T.uv[2 * c + a] = std::clamp(x, 0.0, 1.0);
            }
        }
        const Vec3 P0 = positions_[T.v[0]], E1 = positions_[T.v[1]] - P0, E2 = positions_[T.v[2]] - P0;
        const Vec3 n = cross(E1, E2);  // twice the area, along the winding normal
        area_ += 0.5 * length(n);
        for (int c = 0; c < 3; ++c) vertex_normals[T.v[c]] += n;
        mean_normal += n;
        // s_u, s_v of the affine map from UV to the triangle: [E1 E2] = [s_u s_v] M.
        const double du1 = T.uv[2] - T.uv[0], dv1 = T.uv[3] - T.uv[1], du2 = T.uv[4] - T.uv[0], dv2 = T.uv[5] - T.uv[1];
        const double det = cross2(du1, dv1, du2, dv2);
        const double uv_scale = std::max({std::abs(du1), std::abs(dv1), std::abs(du2), std::abs(dv2)});
        T.in_chart = std::abs(det) > 1e-12 * uv_scale * uv_scale && uv_scale > 0;
        if (T.in_chart) {
            T.dpdu = (E1 * dv2 - E2 * dv1) / det;
            T.dpdv = (E2 * du1 - E1 * du2) / det;
        } else {
            T.dpdu = T.dpdv = {0, 0, 0};
            ++degenerate_uv_;
        }
    }
    if (degenerate_uv_ == nt) fail("the UV map has no area (every triangle's UVs are collinear)");
    // The frame's normal follows the winding (the side Blender renders as front). Triangles
    // without area borrow the normal of the triangles around them, then the mesh's mean normal.
    Vec3 fallback;
    if (!unit_or_fail(mean_normal, 0.0, fallback)) fallback = {0, 0, 1};
    for (Triangle& T : tris_) {
        const Vec3 P0 = positions_[T.v[0]], E1 = positions_[T.v[1]] - P0, E2 = positions_[T.v[2]] - P0;
        const Vec3 n = cross(E1, E2);
        const double edge = std::max({length(E1), length(E2), length(E2 - E1)});
        if (length(n) > 1e-12 * edge * edge && unit_or_fail(n, 0.0, T.normal)) continue;
        const Vec3 around = vertex_normals[T.v[0]] + vertex_normals[T.v[1]] + vertex_normals[T.v[2]];
        if (!unit_or_fail(around, 0.0, T.normal)) T.normal = fallback;
    }
    build_grid();
}

void MeshChart::build_grid() {
    const size_t in_chart = tris_.size() - degenerate_uv_;
    grid_ = std::clamp(int(std::sqrt(double(in_chart))), 1, 2048);
    const size_t cells = size_t(grid_) * grid_;
    auto cell_range = [&](const Triangle& T, int& i0, int& i1, int& j0, int& j1) {
        const double u0 = std::min({T.uv[0], T.uv[2], T.uv[4]}), u1 = std::max({T.uv[0], T.uv[2], T.uv[4]});
        const double v0 = std::min({T.uv[1], T.uv[3], T.uv[5]}), v1 = std::max({T.uv[1], T.uv[3], T.uv[5]});
        i0 = std::clamp(int(u0 * grid_), 0, grid_ - 1), i1 = std::clamp(int(u1 * grid_), 0, grid_ - 1);
        j0 = std::clamp(int(v0 * grid_), 0, grid_ - 1), j1 = std::clamp(int(v1 * grid_), 0, grid_ - 1);
    };
    std::vector<uint32_t> count(cells + 1, 0);
    for (const Triangle& T : tris_) {
        if (!T.in_chart) continue;
        int i0, i1, j0, j1;
        cell_range(T, i0, i1, j0, j1);
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i) ++count[size_t(j) * grid_ + i + 1];
    }
    cell_start_.assign(cells + 1, 0);
    for (size_t c = 0; c < cells; ++c) cell_start_[c + 1] = cell_start_[c] + count[c + 1];
    cell_tris_.resize(cell_start_[cells]);
    std::vector<uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
    for (size_t t = 0; t < tris_.size(); ++t) {
        if (!tris_[t].in_chart) continue;
        int i0, i1, j0, j1;
        cell_range(tris_[t], i0, i1, j0, j1);
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i) cell_tris_[fill[size_t(j) * grid_ + i]++] = uint32_t(t);
    }
}

int MeshChart::locate(double u, double v, double& b1, double& b2) const {
    if (!(u >= -kInside && u <= 1 + kInside && v >= -kInside && v <= 1 + kInside)) return -1;
    const int i = std::clamp(int(u * grid_), 0, grid_ - 1), j = std::clamp(int(v * grid_), 0, grid_ - 1);
    const size_t c = size_t(j) * grid_ + i;
    for (uint32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        const Triangle& T = tris_[cell_tris_[k]];
        const double du1 = T.uv[2] - T.uv[0], dv1 = T.uv[3] - T.uv[1], du2 = T.uv[4] - T.uv[0], dv2 = T.uv[5] - T.uv[1];
        const double det = cross2(du1, dv1, du2, dv2);
        const double pu = u - T.uv[0], pv = v - T.uv[1];
        const double x1 = cross2(pu, pv, du2, dv2) / det, x2 = cross2(du1, dv1, pu, pv) / det;
        if (x1 >= -kInside && x2 >= -kInside && 1 - x1 - x2 >= -kInside) {
            b1 = x1, b2 = x2;
            return int(cell_tris_[k]);
        }
    }
    return -1;
}

bool MeshChart::in_domain(double u, double v) const {
    double b1, b2;
    return locate(u, v, b1, b2) >= 0;
}

double MeshChart::closest_in_triangle(const Triangle& T, double u, double v, double& b1, double& b2) const {
    const double du1 = T.uv[2] - T.uv[0], dv1 = T.uv[3] - T.uv[1], du2 = T.uv[4] - T.uv[0], dv2 = T.uv[5] - T.uv[1];
    const double det = cross2(du1, dv1, du2, dv2);
    const double pu = u - T.uv[0], pv = v - T.uv[1];
    const double x1 = cross2(pu, pv, du2, dv2) / det, x2 = cross2(du1, dv1, pu, pv) / det;
    if (x1 >= 0 && x2 >= 0 && x1 + x2 <= 1) {
        b1 = x1, b2 = x2;
        return 0;
    }
    // Outside: the closest point lies on an edge. Edges as (start corner, end corner).
    double best = 1e300;
    const double bary[3][2] = {{0, 0}, {1, 0}, {0, 1}};
    for (int e = 0; e < 3; ++e) {
        const int a = e, b = (e + 1) % 3;
        const double au = T.uv[2 * a], av = T.uv[2 * a + 1], eu = T.uv[2 * b] - au, ev = T.uv[2 * b + 1] - av;
        const double len2 = eu * eu + ev * ev;
        const double s = len2 > 0 ? std::clamp(((u - au) * eu + (v - av) * ev) / len2, 0.0, 1.0) : 0.0;
        const double qu = au + s * eu - u, qv = av + s * ev - v;
        const double d2 = qu * qu + qv * qv;
        if (d2 < best) {
            best = d2;
            b1 = (1 - s) * bary[a][0] + s * bary[b][0];
            b2 = (1 - s) * bary[a][1] + s * bary[b][1];
        }
    }
    return std::sqrt(best);
}

int MeshChart::nearest(double u, double v, double& b1, double& b2) const {
    // Rings of grid cells around (u, v); a triangle first met in ring r + 1 is at least r cells
    // away, so stop once the best distance is below that.
    const int ci = std::clamp(int(u * grid_), 0, grid_ - 1), cj = std::clamp(int(v * grid_), 0, grid_ - 1);
    const double cell = 1.0 / grid_;
    int best_tri = -1;
    double best = 1e300;
    for (int r = 0; r <= grid_; ++r) {
        for (int j = cj - r; j <= cj + r; ++j) {
            if (j < 0 || j >= grid_) continue;
            const bool edge_row = (j == cj - r || j == cj + r);
            for (int i = ci - r; i <= ci + r; i += edge_row ? 1 : 2 * r) {
                if (i >= 0 && i < grid_) {
                    const size_t c = size_t(j) * grid_ + i;
                    for (uint32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
                        double x1, x2;
                        const double d = closest_in_triangle(tris_[cell_tris_[k]], u, v, x1, x2);
                        if (d < best) best = d, best_tri = int(cell_tris_[k]), b1 = x1, b2 = x2;
                    }
                }
                if (r == 0) break;
            }
        }
        if (best_tri >= 0 && best <= r * cell) break;
    }
    return best_tri;
}

SurfacePoint MeshChart::point_on(const Triangle& T, double b1, double b2) const {
    SurfacePoint s;
    s.p = positions_[T.v[0]] * (1 - b1 - b2) + positions_[T.v[1]] * b1 + positions_[T.v[2]] * b2;
    s.dpdu = T.dpdu;
    s.dpdv = T.dpdv;
    s.jacobian = length(cross(T.dpdu, T.dpdv));
    s.frame = frame_with_normal(T.normal, T.dpdu, T.dpdv);
    if (!corner_normals_.empty()) {
        const double w[3] = {1 - b1 - b2, b1, b2};
        s.shading = interpolated_shading(&corner_normals_[3 * size_t(&T - tris_.data())], w, 3, s.frame.z);
    }
    return s;
}

SurfacePoint MeshChart::evaluate(double u, double v) const {
    u = std::clamp(u, 0.0, 1.0);
    v = std::clamp(v, 0.0, 1.0);
    double b1 = 0, b2 = 0;
    int t = locate(u, v, b1, b2);
    if (t < 0) t = nearest(u, v, b1, b2);
    return point_on(tris_[t], b1, b2);
}

Tessellation MeshChart::tessellate() const {
    // The mesh itself. A vertex whose corners carry different UVs (a seam) is split, one copy
    // per distinct UV, so each tessellation vertex has one (u, v).
    const size_t nc = 3 * tris_.size();
    std::vector<std::tuple<uint32_t, uint64_t, uint32_t>> corners(nc);  // (vertex, uv bits, corner)
    for (size_t t = 0; t < tris_.size(); ++t)
        for (int c = 0; c < 3; ++c) {
            const float uv[2] = {float(tris_[t].uv[2 * c]), float(tris_[t].uv[2 * c + 1])};
            uint64_t bits;
            std::memcpy(&bits, uv, sizeof bits);
            corners[3 * t + c] = {tris_[t].v[c], bits, uint32_t(3 * t + c)};
        }
    std::sort(corners.begin(), corners.end());
    Tessellation out;
    out.triangles.resize(nc);
    for (size_t k = 0; k < nc; ++k) {
        const auto& [vertex, bits, corner] = corners[k];
        if (k == 0 || vertex != std::get<0>(corners[k - 1]) || bits != std::get<1>(corners[k - 1])) {
            const Vec3& p = positions_[vertex];
            out.positions.insert(out.positions.end(), {p.x, p.y, p.z});
            float uv[2];
            std::memcpy(uv, &bits, sizeof uv);
            out.uvs.insert(out.uvs.end(), {uv[0], uv[1]});
        }
        out.triangles[corner] = uint32_t(out.uvs.size() / 2 - 1);
    }
    out.normals.reserve(3 * tris_.size());
    for (const Triangle& T : tris_) out.normals.insert(out.normals.end(), {float(T.normal.x), float(T.normal.y), float(T.normal.z)});
    return out;
}

}  // namespace bsgi
