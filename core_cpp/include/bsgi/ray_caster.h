// Ray queries that answer in the surfaces' own terms: which surface, its parameters (u, v), the
// point and the local frame (1)-(3) there (paper section 5: "the ray tracer must be able to
// compute ray intersections with these surfaces and the corresponding parameter values as well
// as surface derivatives to compute the local frame").
//
// Embree finds the hit on the tessellation; surfaces whose tessellation is exact (meshes,
// parallelograms) answer from the hit triangle directly, curved ones (NURBS) are intersected
// exactly by Newton's method from the tessellated hit. Curved surfaces also decide self-hits:
// a tessellation hit whose exact intersection lies behind the ray's start is skipped, and so is
// one where the ray passes the triangle without meeting the surface (see
// Surface::tessellate_for_rays).
#pragma once
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "bsgi/ray_scene.h"
#include "bsgi/surface.h"
#include "bsgi/thin_glass.h"

namespace bsgi {

struct SurfaceHit {
    int surface = -1;  // -1: the ray escaped
    double t = 0;      // origin + t * dir is the hit
    double u = 0, v = 0;
    Vec3 p;
    Frame frame;
    Vec3 shading{0, 0, 0};  // the shading normal on a smooth-shaded face (SurfacePoint::shading)
};

// The frame the hit surface's radiance splines are in (SurfacePoint's radiance_frame).
inline Frame radiance_frame(const SurfaceHit& h) { return radiance_frame(h.frame, h.shading); }

// Light leaving the hit towards -dir, as the hit surface's radiance splines read it: its side the
// geometric one, its angles in the radiance frame (a direction between the face and its shading
// plane keeps its side, at the angle of its mirror image).
inline Vec3 leaving_local(const SurfaceHit& h, const Vec3& dir) {
    const Vec3 geometric = h.frame.to_local(-dir);
    if (is_zero(h.shading)) return geometric;
    Vec3 local = radiance_frame(h).to_local(-dir);
    local.z = std::copysign(std::abs(local.z), geometric.z);
    return local;
}

// Outputs of a batch of closest-hit queries; null pointers are skipped. frame holds 9 values
// per hit, x, y, z = normal.
struct HitArrays {
    int32_t* surface = nullptr;
    double* t = nullptr;
    double* uv = nullptr;
    double* position = nullptr;
    double* frame = nullptr;
    double* leaving = nullptr;  // 3 per hit: -dir as the hit surface's radiance reads it (leaving_local)
};

class RayCaster {
public:
    // Surface id i is surfaces[i]; null entries take no part. The surfaces must outlive the
    // caster. Tessellates and builds the BVH. panes[i], where given, makes surface i a window
    // pane (thin glass): it blocks closest_hit() like any surface, but transmittance() lets
    // light through it.
    explicit RayCaster(std::vector<const Surface*> surfaces, std::vector<std::optional<ThinGlass>> panes = {});
    // Fills h.shading where the hit surface has shading normals (smooth faces): what reading its
    // glossy radiance needs (leaving_local). Hits on meshes do not look it up unasked (a
    // Lambertian surface's light is read without it); hits refined on curved surfaces have it.
    void look_up_shading(SurfaceHit& h) const {
        if (h.surface >= 0 && smooth_[size_t(h.surface)]) h.shading = surfaces_[size_t(h.surface)]->evaluate(h.u, h.v).shading;
    }

    // Distance by which spawn() lifts ray origins off a surface: it scales with the scene's
    // extent (Embree works in float, relative to the scene's centre).
    double offset() const { return offset_; }
    // Origin for a ray leaving point p (normal n) along dir: p lifted by offset() to the side
    // of the surface that dir goes to.
    Vec3 spawn(const Vec3& p, const Vec3& n, const Vec3& dir) const {
        return p + n * (dot(dir, n) >= 0 ? offset_ : -offset_);
    }

    // Thread-safe. Hits lie in (tnear, tfar).
    SurfaceHit closest_hit(const Vec3& o, const Vec3& d, double tnear = 0,
                           double tfar = std::numeric_limits<double>::infinity()) const;
    // Closest hits of n rays from origin o (RayScene::closest_hits_from: traced in packets;
    // give neighbouring directions one after another), resolved like closest_hit's.
    void closest_hits_from(const Vec3& o, const Vec3* dirs, size_t n, SurfaceHit* hits) const;
    bool occluded(const Vec3& o, const Vec3& d, double tnear = 0, double tfar = std::numeric_limits<double>::infinity()) const;
    // The fraction of light passing along the segment (tnear, tfar), per colour channel: the
    // product of the panes' shadow transmittance over the panes crossed, 0 if anything opaque (or
    // more than kMaxPanes panes) lies on it. Without panes in the way, as fast as occluded().
    Vec3 transmittance(const Vec3& o, const Vec3& d, double tnear = 0,
                       double tfar = std::numeric_limits<double>::infinity()) const;
    static constexpr int kMaxPanes = 8;
    // The pane surface i is, or null if it is opaque (or takes no part).
    const ThinGlass* pane(int surface) const {
        // (has_panes_ first: every gathered ray asks, and most scenes have none.)
        return has_panes_ && surface >= 0 && size_t(surface) < panes_.size() && panes_[surface] ? &*panes_[surface] : nullptr;
    }
    bool has_panes() const { return has_panes_; }

    // Batches on `threads` threads (0: all).
    void closest_hit_batch(const RayBatch& rays, const HitArrays& out, int threads = 0) const;
    void occluded_batch(const RayBatch& rays, uint8_t* occluded, int threads = 0) const;
    void transmittance_batch(const RayBatch& rays, double* transmittance, int threads = 0) const;  // 3 per ray

    const RayScene& ray_scene() const { return rays_; }
    size_t triangle_count() const { return rays_.triangle_count(); }

private:
    SurfaceHit resolve(RayHit h, const Vec3& o, const Vec3& d, double tnear, double tfar) const;

    std::vector<const Surface*> surfaces_;
    std::vector<std::optional<ThinGlass>> panes_;
    bool has_panes_ = false;
    RayScene rays_;
    bool all_exact_ = true;
    std::vector<uint8_t> exact_;  // per surface: its tessellation is the surface (a byte, not a virtual call, per hit)
    std::vector<uint8_t> smooth_;  // per surface: it has shading normals (look_up_shading)
    double magnitude_ = 1, offset_ = 1e-5;
};

}  // namespace bsgi
