// Discs and ellipses (Blender's disk and ellipse area lights): s(u, v) = c + u (cos(2 pi v) a +
// sin(2 pi v) b), u the radius fraction, v the angle, periodic in v, the edge u = 0 collapsed into
// the centre. The front is along a x b.
#pragma once
#include "bsgi/surface.h"

namespace bsgi {

class DiskPatch final : public Surface {
public:
    DiskPatch(std::string name, const Vec3& center, const Vec3& axis_a, const Vec3& axis_b);
    SurfacePoint evaluate(double u, double v) const override;
    Tessellation tessellate() const override;
    void refine_parameters(const Vec3& p, double& u, double& v) const override;
    double area() const override { return area_; }
    bool periodic_v() const override { return true; }

private:
    Vec3 c_, a_, b_;
    Vec3 normal_;
    double area_;
};

}  // namespace bsgi
