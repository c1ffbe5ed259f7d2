// A piece of a surface between two curves of its parameter domain: the paper's section 5.1
// splits surfaces along the discontinuities of their light so that no spline spans one (here
// lines where another surface passes through this one: lit on one side, in its shadow on the
// other). The piece maps the unit square onto the band u0 <= u <= u1, lower(u) <= v <= upper(u)
// of the parent:
//     s(a, b) = parent(u(a), lower(u) + b (upper(u) - lower(u))),  u(a) = u0 + a (u1 - u0),
// each curve v(u) a cubic (Catmull-Rom) through samples at equal steps of u, or a constant:
// C1, so the piece's frame and Jacobian are continuous. Where the curves meet (the ends of a
// closed line's inside) the edge b collapses, like a NURBS sphere's pole. Along v instead, the
// roles of u and v swap: the band v0 <= v <= v1, lower(v) <= u <= upper(v), with
//     s(a, b) = parent(lower(v) + a (upper(v) - lower(v)), v(b)),  v(b) = v0 + b (v1 - v0),
// so that a and b keep the parent's orientation.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "bsgi/surface.h"

namespace bsgi {

// v = c(u) on [u0, u1] through samples at equal steps (one sample: a constant).
class BoundaryCurve {
public:
    BoundaryCurve(double u0, double u1, std::vector<double> samples);
    double operator()(double u) const { double d; return evaluate(u, d); }
    // Value and derivative dc/du.
    double evaluate(double u, double& derivative) const;

private:
    double u0_, u1_;
    std::vector<double> samples_;
};

class SplitPiece final : public Surface {
public:
    // t0, t1: the band's range of u (along_v: of v); lower, upper: the curves' samples.
    // Throws std::invalid_argument naming the piece when the band is empty or leaves [0, 1]^2:
    // t0 >= t1, samples outside [0, 1] or NaN, or lower above upper anywhere.
    SplitPiece(std::string name, std::shared_ptr<const Surface> parent, double t0, double t1,
               std::vector<double> lower, std::vector<double> upper, bool along_v = false);

    SurfacePoint evaluate(double a, double b) const override;
    Tessellation tessellate() const override { return grid(false); }
    Tessellation tessellate_for_rays() const override { return grid(true); }
    void refine_parameters(const Vec3& p, double& a, double& b) const override { project(p, a, b); }
    double area() const override { return area_; }

    // The parent's (u, v) at the piece's (a, b), and back: (a, b) of a parent point in the band
    // (outside it, clamped onto it).
    void parent_parameters(double a, double b, double& u, double& v) const;
    void piece_parameters(double u, double v, double& a, double& b) const;
    // The band's (a, b) at a parent point without clamping (outside the band, a or b leaves
    // [0, 1]): the parent's parameters of the curves alone, as a bake's texels are routed.
    static void band_parameters(const BoundaryCurve& lower, const BoundaryCurve& upper, double t0, double t1, bool along_v,
                                double u, double v, double& a, double& b);
    double t0() const { return t0_; }
    double t1() const { return t1_; }
    bool along_v() const { return along_v_; }

private:
    Tessellation grid(bool lifted) const;
    // The parent's (u, v) at (a, b) and their derivatives du/da, du/db, dv/da, dv/db.
    void map(double a, double b, double& u, double& v, double d[4]) const;

    std::shared_ptr<const Surface> parent_;
    double t0_, t1_;
    bool along_v_;
    BoundaryCurve lower_, upper_;
    double area_ = 0;
};

}  // namespace bsgi
