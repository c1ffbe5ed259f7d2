// Ray casting against the scene's tessellated surfaces. The only interface to Embree: all rtc*
// calls live in src/embree_scene.cpp, so a port to Embree 4 stays local to that file.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>

#include "bsgi/frame.h"
#include "bsgi/surface.h"
#include "bsgi/vec3.h"

namespace bsgi {

struct RayHit {
    int surface = -1;  // -1: the ray escaped
    double t = 0;      // ray parameter: the hit is at origin + t * dir
    double u = 0, v = 0;  // surface parameters interpolated from the tessellation (not yet refined)
    // Where on the tessellation, and the local frame (1)-(3) of the tessellation there (flat
    // triangles): normal from Tessellation::normals (else the winding normal), tangent x along
    // the triangle's s_u (of its linear map from (u, v)). Exact for meshes.
    uint32_t triangle = 0;
    Vec3 tangent, normal;
};

// Rays in structure-of-arrays form, as numpy hands them over: origins and directions are
// 3 per ray; tnear/tfar may be null (0 and infinity).
struct RayBatch {
    const double* origins = nullptr;
    const double* directions = nullptr;
    const double* tnear = nullptr;
    const double* tfar = nullptr;
    size_t count = 0;
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

    // Closest hits of rays [begin, end) of a batch into hits[0 .. end-begin). Faster than one by
    // one: the per-triangle data of each hit is prefetched while the next ray is traced.
    void closest_hit_block(const RayBatch& rays, size_t begin, size_t end, RayHit* hits) const;

    // Closest hits of n rays leaving one origin (a gather's hemisphere), traced as coherent
    // packets of 16: neighbouring directions share their traversal of the BVH (a gather's
    // hemispheres twice as fast as one ray at a time). The hits are those of closest_hit but
    // where two triangles lie at the same distance (a shared edge): either may be reported.
    void closest_hits_from(const Vec3& origin, const Vec3* dirs, size_t n, RayHit* hits) const;

    // Plain Embree closest-hit queries on the same rays, writing only t (infinity: no hit) and
    // the surface: the baseline the benchmark compares closest_hit_block against.
    void raw_closest_hit_batch(const RayBatch& rays, float* t, int32_t* surface, int threads) const;

    size_t triangle_count() const;
    // Bounding box of everything added.
    void bounds(Vec3& lo, Vec3& hi) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace bsgi
