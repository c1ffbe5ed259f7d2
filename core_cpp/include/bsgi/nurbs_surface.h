// Rational NURBS surfaces exactly as Blender evaluates them.
//
// Blender keeps no knot vector in its files and exposes none: it builds one from the point
// count, the order and three flags per direction (`calcknots` in blenkernel's curve.cc), and
// shows the surface over a range of it (`BKE_nurb_makeFaces`). Both are reproduced here, so a
// surface exported from Blender is the surface Blender draws. Parameters are normalised: (u, v)
// in [0, 1]^2 spans Blender's evaluation range, the same normalisation as the UV map of the mesh
// Blender makes from the surface.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "bsgi/surface.h"

namespace bsgi {

// One parametric direction of a Blender NURBS: `use_endpoint_u`, `use_bezier_u`, `use_cyclic_u`
// and the point count and order in that direction.
struct NurbsDirection {
    int points = 0;
    int order = 4;  // degree + 1; Blender allows 2..6
    bool endpoint = false, bezier = false, cyclic = false;

    int degree() const { return order - 1; }
    // Basis functions in use: cyclic directions repeat the first order-1 points at the end.
    int basis_count() const { return points + (cyclic ? order - 1 : 0); }
};

// Why Blender would refuse this direction (it draws nothing then), or "" if it is valid.
// Mirrors Blender's check: at least two points, no fewer points than the order, and in Bézier
// mode whole segments (cyclic: a multiple of order-1 points; open without endpoints: more
// points than the order).
std::string blender_nurbs_problem(const NurbsDirection& d);

// Blender's knot vector (basis_count() + order integer knots): the first knot is repeated by the
// endpoint/Bézier flags, inner knots once (order-1 times in Bézier mode), and cyclic or endpoint
// directions end with a copy of the starting widths.
std::vector<double> blender_knots(const NurbsDirection& d);

// Blender's evaluation range [knots[order-1], cyclic ? knots[points+order-1] : knots[points]].
std::pair<double, double> blender_range(const NurbsDirection& d, const std::vector<double>& knots);

// Which side is the front, the side the frame's z points to. Blender's meshes of NURBS surfaces
// face -(s_u x s_v) (checked on its primitives), so surfaces from Blender keep Blender's front
// by default; the frame is then x along s_u, z = -(s_u x s_v) / |s_u x s_v|, y = z x x (still
// right-handed). SuCrossSv is paper (2) literally.
enum class NurbsFront { Blender, SuCrossSv };

class NurbsSurface final : public Surface {
public:
    // `control` holds u.points * v.points points (x, y, z, w) in Blender's order (u fastest):
    // position and weight, not homogeneous (Blender's `points[].co`). `subdivisions` is the
    // number of tessellation steps per knot span; 0 chooses them per span so that chords stay
    // within 2e-4 of the surface's size. Throws
    // std::invalid_argument naming the surface for NaN/infinite points, weights <= 0, orders
    // outside 2..6 and point counts Blender would refuse.
    NurbsSurface(std::string name, std::vector<double> control, NurbsDirection u, NurbsDirection v, int subdivisions = 0,
                 NurbsFront front = NurbsFront::Blender);

    SurfacePoint evaluate(double u, double v) const override;
    // Position, s_u, s_v and the mixed derivative s_uv at normalised parameters.
    void derivatives(double u, double v, Vec3& p, Vec3& su, Vec3& sv, Vec3& suv) const;
    // A grid through every knot span, its vertices on the surface.
    Tessellation tessellate() const override;
    // The same grid lifted to the convex side by twice each cell's chord deviation, so that it
    // encloses the surface where it is convex (spheres, cylinders) and rays cannot slip between
    // the triangles and the surface at silhouettes.
    Tessellation tessellate_for_rays() const override;
    void refine_parameters(const Vec3& p, double& u, double& v) const override { project(p, u, v); }
    double area() const override { return area_; }
    bool periodic_u() const override { return u_.cyclic; }
    bool periodic_v() const override { return v_.cyclic; }
    // Knots (C0 ones, where the spans meet at an angle: a bulb's neck, a cone's rim).
    std::array<std::vector<double>, 2> creases() const override;

    const NurbsDirection& direction_u() const { return u_; }
    const NurbsDirection& direction_v() const { return v_; }
    NurbsFront front() const { return front_; }
    const std::vector<double>& knots_u() const { return knots_u_; }
    const std::vector<double>& knots_v() const { return knots_v_; }
    std::pair<double, double> range_u() const { return range_u_; }
    std::pair<double, double> range_v() const { return range_v_; }

protected:
    void first_derivatives(double u, double v, Vec3& su, Vec3& sv) const override {
        Vec3 p, suv;
        derivatives(u, v, p, su, sv, suv);
    }

private:
    // Normal at a point where s_u x s_v vanishes, from the mixed derivative: next to a
    // collapsed row s_v ~ (u - u0) s_uv, so the normal tends to +-(s_u x s_uv).
    Vec3 limit_normal(double u, double v, const Vec3& su, const Vec3& sv, const Vec3& suv) const;
    std::vector<double> breakpoints(const std::vector<double>& knots, std::pair<double, double> range) const;
    // Tessellation parameters along one direction (normalised), `along_u` choosing which.
    std::vector<double> grid_parameters(bool along_u) const;
    Tessellation grid(bool lifted) const;

    NurbsDirection u_, v_;
    std::vector<double> control_;  // (w x, w y, w z, w): homogeneous, u fastest
    std::vector<double> knots_u_, knots_v_;
    std::pair<double, double> range_u_, range_v_;
    int subdivisions_;
    NurbsFront front_;
    double area_ = 0;
};

}  // namespace bsgi
