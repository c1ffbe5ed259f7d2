// Ray casting against the scene's tessellated surfaces. The only interface to Embree: all rtc*
// calls live in src/embree_scene.cpp, so a port to Embree 4 stays local to that file.
#pragma once
#include <memory>

#include "bsgi/surface.h"
#include "bsgi/vec3.h"

namespace bsgi {

struct RayHit {
    int surface = -1;  // -1: the ray escaped
    double t = 0;      // distance along the (unit) direction
    double u = 0, v = 0;  // surface parameters interpolated from the tessellation (not yet refined)
};

class RayScene {
public:
    RayScene();
    ~RayScene();
    RayScene(const RayScene&) = delete;
    RayScene& operator=(const RayScene&) = delete;

    void add(int surface_id, const Tessellation& tess);
    void commit();  // builds the BVH; call once after all add()

    // Thread-safe after commit(). Directions need not be normalized for occluded().
    RayHit closest_hit(const Vec3& origin, const Vec3& dir, double tnear, double tfar) const;
    bool occluded(const Vec3& origin, const Vec3& dir, double tnear, double tfar) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace bsgi
