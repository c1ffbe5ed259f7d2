#include "bsgi/ray_caster.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "bsgi/parallel.h"

namespace bsgi {

namespace {

// Ray origins are lifted this fraction of the scene's extent: Embree's float arithmetic (on
// coordinates relative to the scene's centre, see RayScene::commit) loses about 1e-7 of it, so
// this clears rounding by two orders with margin, and stays far below any feature a radiance
// spline resolves.
constexpr double kOffsetRelative = 1e-5;

// Results go out with non-temporal stores where available: they are written once and not read
// back here, so they need not displace the BVH from the cache nor be read before being written.
inline void put(double* dst, double x) {
#if defined(__x86_64__)
    long long bits;
    std::memcpy(&bits, &x, sizeof bits);
    _mm_stream_si64(reinterpret_cast<long long*>(dst), bits);
#else
    *dst = x;
#endif
}

void write(const HitArrays& out, size_t i, const SurfaceHit& h, const Vec3& dir) {
    if (out.surface) out.surface[i] = h.surface;
    if (out.t) put(out.t + i, h.surface >= 0 ? h.t : std::numeric_limits<double>::infinity());
    if (out.uv) put(out.uv + 2 * i, h.u), put(out.uv + 2 * i + 1, h.v);
    if (out.position) {
        double* p = out.position + 3 * i;
        put(p, h.p.x), put(p + 1, h.p.y), put(p + 2, h.p.z);
    }
    if (out.frame) {
        double* f = out.frame + 9 * i;
        const Vec3* axes[3] = {&h.frame.x, &h.frame.y, &h.frame.z};
        for (int a = 0; a < 3; ++a) put(f + 3 * a, axes[a]->x), put(f + 3 * a + 1, axes[a]->y), put(f + 3 * a + 2, axes[a]->z);
    }
    if (out.leaving) {
        const Vec3 w = h.surface >= 0 ? leaving_local(h, dir) : Vec3{0, 0, 0};
        put(out.leaving + 3 * i, w.x), put(out.leaving + 3 * i + 1, w.y), put(out.leaving + 3 * i + 2, w.z);
    }
}

// A hit on a surface its tessellation is (a mesh): the record as it is, its frame
// re-orthonormalised in double (it was stored in float), with one division per vector, not three
// (every gathered ray comes through here).
inline SurfaceHit on_tessellation(const RayHit& h, const Vec3& o, const Vec3& d) {
    SurfaceHit out;
    out.surface = h.surface;
    out.t = h.t, out.u = h.u, out.v = h.v;
    out.p = o + d * h.t;
    out.frame.z = h.normal * (1 / length(h.normal));
    const Vec3 x = h.tangent - out.frame.z * dot(h.tangent, out.frame.z);
    out.frame.x = x * (1 / length(x));
    out.frame.y = cross(out.frame.z, out.frame.x);
    return out;
}

}  // namespace

RayCaster::RayCaster(std::vector<const Surface*> surfaces, std::vector<std::optional<ThinGlass>> panes)
    : surfaces_(std::move(surfaces)), panes_(std::move(panes)) {
    for (size_t i = 0; i < panes_.size() && i < surfaces_.size(); ++i) has_panes_ = has_panes_ || (panes_[i] && surfaces_[i]);
    exact_.assign(surfaces_.size(), 0);
    smooth_.assign(surfaces_.size(), 0);
    for (size_t i = 0; i < surfaces_.size(); ++i) {
        if (!surfaces_[i]) continue;
        rays_.add(int(i), surfaces_[i]->tessellate_for_rays());
        exact_[i] = surfaces_[i]->tessellation_is_exact();
        smooth_[i] = surfaces_[i]->has_shading_normals();
        all_exact_ = all_exact_ && exact_[i];
    }
    rays_.commit();
    Vec3 lo, hi;
    rays_.bounds(lo, hi);
    if (rays_.triangle_count() > 0) magnitude_ = length(hi - lo);
    if (!(magnitude_ > 0)) magnitude_ = 1;
    offset_ = kOffsetRelative * magnitude_;
}

SurfaceHit RayCaster::resolve(RayHit h, const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    double t_self = -1;
    for (int attempt = 0; attempt < 16 && h.surface >= 0; ++attempt) {
        if (exact_[h.surface]) return on_tessellation(h, o, d);
        const Surface& s = *surfaces_[h.surface];
        SurfaceHit out;
        out.surface = h.surface;
        // Exact intersections this close to the start are the surface the ray starts on.
        if (t_self < 0) t_self = tnear + 1e-3 * offset_ / length(d);
        double u = h.u, v = h.v, t = h.t;
        if (s.intersect(o, d, u, v, t) && t > t_self && t < tfar) {
            const SurfacePoint sp = s.evaluate(u, v);
            out.t = t, out.u = u, out.v = v, out.p = sp.p, out.frame = sp.frame, out.shading = sp.shading;
            return out;
        }
        // The ray passes this triangle without meeting the surface, or meets it behind its
        // start (the triangles stand off the surface it starts on) or beyond tfar: look past.
        const double past = std::nextafter(float(h.t), std::numeric_limits<float>::infinity());
        h = rays_.closest_hit(o, d, std::max(past, h.t * (1 + 1e-6)), tfar);
    }
    return SurfaceHit{};
}

SurfaceHit RayCaster::closest_hit(const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    return resolve(rays_.closest_hit(o, d, tnear, tfar), o, d, tnear, tfar);
}

void RayCaster::closest_hits_from(const Vec3& o, const Vec3* dirs, size_t n, SurfaceHit* hits) const {
    constexpr size_t kChunk = 64;
    RayHit raw[kChunk];
    for (size_t start = 0; start < n; start += kChunk) {
        const size_t m = std::min(kChunk, n - start);
        rays_.closest_hits_from(o, dirs + start, m, raw);
        for (size_t k = 0; k < m; ++k) {
            const RayHit& h = raw[k];
            hits[start + k] = h.surface >= 0 && exact_[h.surface]
                                  ? on_tessellation(h, o, dirs[start + k])
                                  : resolve(h, o, dirs[start + k], 0.0, std::numeric_limits<double>::infinity());
        }
    }
}

bool RayCaster::occluded(const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    if (!rays_.occluded(o, d, tnear, tfar)) return false;
    if (all_exact_) return true;
    // The blocker may be a curved surface's tessellation standing off the exact surface near
    // the ray's start: decide on the exact surfaces.
    return closest_hit(o, d, tnear, tfar).surface >= 0;
}

Vec3 RayCaster::transmittance(const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    const Vec3 none{0, 0, 0}, all{1, 1, 1};
    if (!has_panes_) return occluded(o, d, tnear, tfar) ? none : all;
    if (!rays_.occluded(o, d, tnear, tfar)) return all;
    // Walk the hits in order: a pane multiplies, anything else stops the light.
    const double len = length(d), step = offset_ / len;
    Vec3 T = all;
    for (int crossed = 0; crossed <= kMaxPanes; ++crossed) {
        const SurfaceHit h = closest_hit(o, d, tnear, tfar);
        if (h.surface < 0) return T;
        const ThinGlass* glass = pane(h.surface);
        if (!glass || crossed == kMaxPanes) return none;
        T = T * glass->shadow_transmittance(dot(d, h.frame.z) / len);
        tnear = h.t + step;  // past the pane, as spawn() lifts an origin
        if (!(tnear < tfar)) return T;
    }
    return none;
}

void RayCaster::closest_hit_batch(const RayBatch& rays, const HitArrays& out, int threads) const {
    parallel_for(rays.count, 1024, threads, [&](size_t begin, size_t end) {
        constexpr size_t kBlock = 32;  // the hits stay in L1
        RayHit hits[kBlock];
        for (size_t start = begin; start < end; start += kBlock) {
            const size_t n = std::min(kBlock, end - start);
            rays_.closest_hit_block(rays, start, start + n, hits);
            for (size_t k = 0; k < n; ++k) {
                const size_t i = start + k;
                const double* o = rays.origins + 3 * i;
                const double* d = rays.directions + 3 * i;
                const double tnear = rays.tnear ? std::max(0.0, rays.tnear[i]) : 0.0;
                const double tfar = rays.tfar ? rays.tfar[i] : std::numeric_limits<double>::infinity();
                const Vec3 dir{d[0], d[1], d[2]};
                SurfaceHit hit = resolve(hits[k], {o[0], o[1], o[2]}, dir, tnear, tfar);
                if (out.leaving) look_up_shading(hit);
                write(out, i, hit, dir);
            }
        }
#if defined(__x86_64__)
        _mm_sfence();  // make the streamed results visible before the batch returns
#endif
    });
}

void RayCaster::occluded_batch(const RayBatch& rays, uint8_t* result, int threads) const {
    parallel_for(rays.count, 1024, threads, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            const double* o = rays.origins + 3 * i;
            const double* d = rays.directions + 3 * i;
            const double tnear = rays.tnear ? std::max(0.0, rays.tnear[i]) : 0.0;
            const double tfar = rays.tfar ? rays.tfar[i] : std::numeric_limits<double>::infinity();
            result[i] = occluded({o[0], o[1], o[2]}, {d[0], d[1], d[2]}, tnear, tfar) ? 1 : 0;
        }
    });
}

void RayCaster::transmittance_batch(const RayBatch& rays, double* result, int threads) const {
    parallel_for(rays.count, 1024, threads, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) {
            const double* o = rays.origins + 3 * i;
            const double* d = rays.directions + 3 * i;
            const double tnear = rays.tnear ? std::max(0.0, rays.tnear[i]) : 0.0;
            const double tfar = rays.tfar ? rays.tfar[i] : std::numeric_limits<double>::infinity();
            const Vec3 T = transmittance({o[0], o[1], o[2]}, {d[0], d[1], d[2]}, tnear, tfar);
            result[3 * i] = T.x, result[3 * i + 1] = T.y, result[3 * i + 2] = T.z;
        }
    });
}

}  // namespace bsgi
