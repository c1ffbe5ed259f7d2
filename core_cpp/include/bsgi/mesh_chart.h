// A triangle mesh with a UV map as one parametric surface: s(u, v) is the mesh point whose UV
// coordinates are (u, v), linear on each triangle. The UV islands need not fill [0, 1]^2: the
// parameter-domain mask chi of (8) is 1 inside the UV triangles and 0 elsewhere, and points
// outside the domain are pulled onto its nearest point (paper Figure 2c).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "bsgi/surface.h"

namespace bsgi {

class MeshChart final : public Surface {
public:
    // positions: 3 per vertex. triangles: 3 vertex indices each, counter-clockwise seen from the
    // front. corner_uvs: 2 per triangle corner (3 corners per triangle, in triangle order), as
    // Blender stores UVs per face corner; all in [0, 1]^2. Throws std::invalid_argument naming
    // the surface for empty meshes, indices out of range, NaN/infinite values, UVs outside
    // [0, 1]^2 or a UV map without area. corner_normals: empty (flat faces), or 3 per triangle
    // corner (smooth shading: interpolated barycentrically, as Cycles does).
    MeshChart(std::string name, std::vector<double> positions, std::vector<uint32_t> triangles,
              std::vector<double> corner_uvs, const std::vector<double>& corner_normals = {});

    // On the triangle holding (u, v); outside the domain, at the nearest domain point.
    SurfacePoint evaluate(double u, double v) const override;
    bool in_domain(double u, double v) const override;
    Tessellation tessellate() const override;
    // Hits on the tessellation (the mesh itself) already carry exact parameters.
    void refine_parameters(const Vec3&, double&, double&) const override {}
    double area() const override { return area_; }
    bool tessellation_is_exact() const override { return true; }
    bool has_shading_normals() const override { return !corner_normals_.empty(); }

    size_t triangle_count() const { return tris_.size(); }
    // Triangles whose UVs have no area: they block rays but are not part of the chart.
    size_t degenerate_uv_triangles() const { return degenerate_uv_; }
    // The triangle holding (u, v) and the barycentric weights of its corners 1 and 2, or -1.
    int locate(double u, double v, double& b1, double& b2) const;

private:
    struct Triangle {
        uint32_t v[3];
        double uv[6];
        Vec3 dpdu, dpdv;  // of the affine map UV -> mesh on this triangle
        Vec3 normal;      // winding normal; neighbours' where the triangle has no area
        bool in_chart;    // false when its UVs have no area
    };
    SurfacePoint point_on(const Triangle& t, double b1, double b2) const;
    int nearest(double u, double v, double& b1, double& b2) const;
    double closest_in_triangle(const Triangle& t, double u, double v, double& b1, double& b2) const;
    void build_grid();

    std::vector<Vec3> positions_;
    std::vector<Triangle> tris_;
    std::vector<Vec3> corner_normals_;  // 3 per triangle; empty: flat
    size_t degenerate_uv_ = 0;
    double area_ = 0;
    // Uniform grid over [0, 1]^2 listing the chart triangles overlapping each cell.
    int grid_ = 1;
    std::vector<uint32_t> cell_start_, cell_tris_;
};

}  // namespace bsgi
