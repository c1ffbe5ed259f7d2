// Embree 3 behind bsgi::RayScene. Embree 4 changes: RTCIntersectContext becomes
// RTCIntersectArguments/RTCOccludedArguments, rtcIntersect1 takes them as an optional pointer.
#include <dlfcn.h>
#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <new>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "bsgi/build_info.h"
#include "bsgi/parallel.h"
#include "bsgi/ray_scene.h"

#ifdef __linux__
#include <sys/mman.h>
#endif

namespace bsgi {

namespace {

// Large per-triangle arrays are read at random, one record per hit: on 2 MB pages the TLB covers
// them (with 4 kB pages a hit costs a page walk on top of the cache miss).
template <typename T>
struct HugePageAllocator {
    using value_type = T;
    HugePageAllocator() = default;
    template <typename U>
    HugePageAllocator(const HugePageAllocator<U>&) {}
    T* allocate(size_t n) {
        constexpr size_t kHuge = size_t(2) << 20;
        const size_t bytes = n * sizeof(T);
        const size_t align = bytes >= kHuge ? kHuge : std::max<size_t>(alignof(T), 64);
        void* p = nullptr;
        if (posix_memalign(&p, align, (bytes + align - 1) / align * align) != 0) throw std::bad_alloc();
#ifdef __linux__
        if (bytes >= kHuge) madvise(p, bytes, MADV_HUGEPAGE);  // a hint: ignored where unsupported
#endif
        return static_cast<T*>(p);
    }
    void deallocate(T* p, size_t) { free(p); }
    template <typename U>
    bool operator==(const HugePageAllocator<U>&) const { return true; }
    template <typename U>
    bool operator!=(const HugePageAllocator<U>&) const { return false; }
};

// Everything a hit needs about its triangle, in one cache line: the corner parameters and the
// triangle's local frame (x along s_u of its linear map from (u, v), z its normal).
struct alignas(64) TriangleRecord {
    float uv[6];
    float tangent[3], normal[3];
    float pad[4];
};
static_assert(sizeof(TriangleRecord) == 64, "one cache line per triangle");

TriangleRecord make_record(const Tessellation& tess, size_t t) {
    TriangleRecord r{};
    const uint32_t* tri = &tess.triangles[3 * t];
    Vec3 P[3];
    for (int c = 0; c < 3; ++c) {
        P[c] = {tess.positions[3 * tri[c]], tess.positions[3 * tri[c] + 1], tess.positions[3 * tri[c] + 2]};
        r.uv[2 * c] = tess.uvs[2 * tri[c]];
        r.uv[2 * c + 1] = tess.uvs[2 * tri[c] + 1];
    }
    const Vec3 E1 = P[1] - P[0], E2 = P[2] - P[0];
    const double du1 = double(r.uv[2]) - r.uv[0], dv1 = double(r.uv[3]) - r.uv[1];
    const double du2 = double(r.uv[4]) - r.uv[0], dv2 = double(r.uv[5]) - r.uv[1];
    const double det = du1 * dv2 - dv1 * du2;
    const double uv_scale = std::max({std::abs(du1), std::abs(dv1), std::abs(du2), std::abs(dv2)});
    Vec3 su{0, 0, 0}, sv{0, 0, 0};
    if (std::abs(det) > 1e-12 * uv_scale * uv_scale && uv_scale > 0) {
        su = (E1 * dv2 - E2 * dv1) / det;
        sv = (E2 * du1 - E1 * du2) / det;
    }
    Vec3 n;
    if (!tess.normals.empty()) {
        n = {tess.normals[3 * t], tess.normals[3 * t + 1], tess.normals[3 * t + 2]};
    } else {
        n = cross(E1, E2);
        const double ln = length(n);
        n = ln > 0 ? n / ln : Vec3{0, 0, 1};
    }
    // Frames are computed once here, not per hit.
    const Frame f = frame_with_normal(n, su, sv);
    for (int a = 0; a < 3; ++a) {
        r.tangent[a] = float(f.x[a]);
        r.normal[a] = float(f.z[a]);
    }
    return r;
}

// Origins go to Embree relative to the scene's centre (see RayScene::commit).
// Embree aborts on a ray whose origin or direction has a component beyond this (its FLT_LARGE,
// checked by an assertion in Debian's build) or a NaN distance.
constexpr double kLargestRayComponent = 1.8e18;

bool representable(const Vec3& o, const Vec3& d, double tnear, double tfar) {
    return std::abs(o.x) <= kLargestRayComponent && std::abs(o.y) <= kLargestRayComponent &&
           std::abs(o.z) <= kLargestRayComponent && std::abs(d.x) <= kLargestRayComponent &&
           std::abs(d.y) <= kLargestRayComponent && std::abs(d.z) <= kLargestRayComponent && !std::isnan(tnear) &&
           !std::isnan(tfar);
}

void init_ray(RTCRay& ray, const Vec3& world_origin, const Vec3& centre, const Vec3& d, double tnear, double tfar) {
    const Vec3 o = world_origin - centre;
    if (!representable(o, d, tnear, tfar)) {  // misses: an empty interval along a harmless ray
        ray.org_x = ray.org_y = ray.org_z = 0.0f;
        ray.dir_x = ray.dir_y = 0.0f, ray.dir_z = 1.0f;
        ray.tnear = 1.0f, ray.tfar = 0.0f;
    } else {
        ray.org_x = float(o.x), ray.org_y = float(o.y), ray.org_z = float(o.z);
        ray.dir_x = float(d.x), ray.dir_y = float(d.y), ray.dir_z = float(d.z);
        ray.tnear = float(std::max(0.0, tnear));
        ray.tfar = tfar >= double(std::numeric_limits<float>::max()) ? std::numeric_limits<float>::infinity() : float(tfar);
    }
    ray.time = 0, ray.mask = 0xFFFFFFFFu, ray.id = 0, ray.flags = 0;
}

void init_rayhit(RTCRayHit& rh, const RayBatch& rays, size_t i, const Vec3& centre) {
    const double* o = rays.origins + 3 * i;
    const double* d = rays.directions + 3 * i;
    init_ray(rh.ray, {o[0], o[1], o[2]}, centre, {d[0], d[1], d[2]}, rays.tnear ? rays.tnear[i] : 0.0,
             rays.tfar ? rays.tfar[i] : std::numeric_limits<double>::infinity());
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
}

}  // namespace

struct RayScene::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    struct GeometryInfo {
        int surface;
        std::vector<TriangleRecord, HugePageAllocator<TriangleRecord>> records;  // per triangle
        RTCGeometry geometry = nullptr;  // until commit(): its vertices wait for the centre
        float* vertices = nullptr;
        std::vector<double> positions;
    };
    std::vector<GeometryInfo> geometries;  // indexed by Embree geometry id
    bool committed = false;
    size_t triangles = 0;
    Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    Vec3 centre{0, 0, 0};

    void check(const char* what) const {
        const RTCError err = rtcGetDeviceError(device);
        if (err != RTC_ERROR_NONE) throw std::runtime_error(std::string("Embree error ") + std::to_string(int(err)) + " in " + what);
    }

    void fill(RayHit& hit, unsigned geom, unsigned prim, float t, float b1, float b2) const {
        const GeometryInfo& g = geometries[geom];
        const TriangleRecord& r = g.records[prim];
        const double b0 = 1.0 - b1 - b2;
        hit.surface = g.surface;
        hit.triangle = prim;
        hit.t = t;
        hit.u = b0 * r.uv[0] + b1 * r.uv[2] + b2 * r.uv[4];
        hit.v = b0 * r.uv[1] + b1 * r.uv[3] + b2 * r.uv[5];
        hit.tangent = {r.tangent[0], r.tangent[1], r.tangent[2]};
        hit.normal = {r.normal[0], r.normal[1], r.normal[2]};
    }
};

RayScene::RayScene() : impl_(new Impl) {
    // Embree's BVH on 2 MB pages too (madvise), for the same reason as the triangle records.
    impl_->device = rtcNewDevice("hugepages=1");
    if (!impl_->device) throw std::runtime_error("Embree: cannot create a device");
    impl_->scene = rtcNewScene(impl_->device);
    rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
}

RayScene::~RayScene() {
    for (Impl::GeometryInfo& g : impl_->geometries)
        if (g.geometry) rtcReleaseGeometry(g.geometry);  // added, never committed
    if (impl_->scene) rtcReleaseScene(impl_->scene);
    if (impl_->device) rtcReleaseDevice(impl_->device);
}

void RayScene::add(int surface_id, const Tessellation& tess) {
    if (impl_->committed) throw std::logic_error("RayScene::add after commit");
    const size_t nv = tess.positions.size() / 3, nt = tess.triangles.size() / 3;
    if (tess.uvs.size() != 2 * nv) throw std::invalid_argument("RayScene::add: 2 uvs per vertex needed");
    if (!tess.normals.empty() && tess.normals.size() != 3 * nt) throw std::invalid_argument("RayScene::add: 3 normal values per triangle needed");
    for (uint32_t i : tess.triangles)
        if (i >= nv) throw std::invalid_argument("RayScene::add: triangle index out of range");
    RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vb = static_cast<float*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
    auto* ib = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), nt));
    impl_->check("rtcSetNewGeometryBuffer");
    std::memcpy(ib, tess.triangles.data(), tess.triangles.size() * sizeof(uint32_t));
    const unsigned id = rtcAttachGeometry(impl_->scene, geom);
    if (id != impl_->geometries.size()) throw std::logic_error("Embree geometry ids are not sequential");
    Impl::GeometryInfo info{surface_id, std::vector<TriangleRecord, HugePageAllocator<TriangleRecord>>(nt), geom, vb,
                            tess.positions};
    for (size_t t = 0; t < nt; ++t) info.records[t] = make_record(tess, t);
    impl_->geometries.push_back(std::move(info));
    impl_->triangles += nt;
    for (size_t k = 0; k < nv; ++k) {
        const Vec3 p{tess.positions[3 * k], tess.positions[3 * k + 1], tess.positions[3 * k + 2]};
        impl_->lo = {std::min(impl_->lo.x, p.x), std::min(impl_->lo.y, p.y), std::min(impl_->lo.z, p.z)};
        impl_->hi = {std::max(impl_->hi.x, p.x), std::max(impl_->hi.y, p.y), std::max(impl_->hi.z, p.z)};
    }
}

void RayScene::commit() {
    // Embree works in float, whose rounding grows with the distance from the origin: vertices
    // (and ray origins) are given relative to the centre of the scene's box, so a small scene
    // far from the origin keeps the precision of its own size.
    if (impl_->triangles > 0) impl_->centre = (impl_->lo + impl_->hi) * 0.5;
    for (Impl::GeometryInfo& g : impl_->geometries) {
        for (size_t k = 0; k < g.positions.size(); ++k) g.vertices[k] = float(g.positions[k] - impl_->centre[k % 3]);
        rtcCommitGeometry(g.geometry);
        rtcReleaseGeometry(g.geometry);
        g.geometry = nullptr;
        g.vertices = nullptr;
        g.positions = std::vector<double>();
    }
    rtcCommitScene(impl_->scene);
    impl_->check("rtcCommitScene");
    impl_->committed = true;
}

size_t RayScene::triangle_count() const { return impl_->triangles; }

void RayScene::bounds(Vec3& lo, Vec3& hi) const {
    lo = impl_->lo;
    hi = impl_->hi;
}

RayHit RayScene::closest_hit(const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    init_ray(rh.ray, o, impl_->centre, d, tnear, tfar);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(impl_->scene, &context, &rh);
    RayHit hit;
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) impl_->fill(hit, rh.hit.geomID, rh.hit.primID, rh.ray.tfar, rh.hit.u, rh.hit.v);
    return hit;
}

void RayScene::closest_hit_block(const RayBatch& rays, size_t begin, size_t end, RayHit* hits) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    struct Found {
        unsigned geom, prim;
        float t, b1, b2;
    };
    constexpr size_t kBlock = 32;
    Found found[kBlock];
    for (size_t start = begin; start < end; start += kBlock) {
        const size_t n = std::min(kBlock, end - start);
        for (size_t k = 0; k < n; ++k) {
            RTCRayHit rh;
            init_rayhit(rh, rays, start + k, impl_->centre);
            rtcIntersect1(impl_->scene, &context, &rh);
            found[k] = {rh.hit.geomID, rh.hit.primID, rh.ray.tfar, rh.hit.u, rh.hit.v};
            // The record is needed only after the whole block is traced: fetch it meanwhile.
            if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) __builtin_prefetch(&impl_->geometries[rh.hit.geomID].records[rh.hit.primID]);
        }
        for (size_t k = 0; k < n; ++k) {
            RayHit& h = hits[start - begin + k];
            h = RayHit{};
            if (found[k].geom != RTC_INVALID_GEOMETRY_ID) impl_->fill(h, found[k].geom, found[k].prim, found[k].t, found[k].b1, found[k].b2);
        }
    }
}

void RayScene::closest_hits_from(const Vec3& origin, const Vec3* dirs, size_t n, RayHit* hits) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    const Vec3 o = origin - impl_->centre;
    constexpr size_t kPacket = 16;
    for (size_t start = 0; start < n; start += kPacket) {
        const size_t m = std::min(kPacket, n - start);
        alignas(64) int valid[kPacket];
        alignas(64) RTCRayHit16 rh;
        for (size_t k = 0; k < kPacket; ++k) {
            const Vec3 d = k < m ? dirs[start + k] : Vec3{0, 0, 1};
            valid[k] = k < m && representable(o, d, 0.0, 0.0) ? -1 : 0;  // others miss
            rh.ray.org_x[k] = float(o.x), rh.ray.org_y[k] = float(o.y), rh.ray.org_z[k] = float(o.z);
            rh.ray.dir_x[k] = float(d.x), rh.ray.dir_y[k] = float(d.y), rh.ray.dir_z[k] = float(d.z);
            rh.ray.tnear[k] = 0.0f, rh.ray.tfar[k] = std::numeric_limits<float>::infinity();
            rh.ray.time[k] = 0, rh.ray.mask[k] = 0xFFFFFFFFu, rh.ray.id[k] = 0, rh.ray.flags[k] = 0;
            rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect16(valid, impl_->scene, &context, &rh);
        for (size_t k = 0; k < m; ++k) {
            RayHit& h = hits[start + k];
            h = RayHit{};
            if (valid[k] && rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID)
                impl_->fill(h, rh.hit.geomID[k], rh.hit.primID[k], rh.ray.tfar[k], rh.hit.u[k], rh.hit.v[k]);
        }
    }
}

void RayScene::raw_closest_hit_batch(const RayBatch& rays, float* t, int32_t* surface, int threads) const {
    parallel_for(rays.count, 4096, threads, [&](size_t begin, size_t end) {
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        for (size_t i = begin; i < end; ++i) {
            RTCRayHit rh;
            init_rayhit(rh, rays, i, impl_->centre);
            rtcIntersect1(impl_->scene, &context, &rh);
            const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
            t[i] = hit ? rh.ray.tfar : std::numeric_limits<float>::infinity();
            surface[i] = hit ? impl_->geometries[rh.hit.geomID].surface : -1;
        }
    });
}

bool RayScene::occluded(const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray;
    init_ray(ray, o, impl_->centre, d, tnear, tfar);
    rtcOccluded1(impl_->scene, &context, &ray);
    return ray.tfar == -std::numeric_limits<float>::infinity();
}

std::string embree_version() {
    RTCDevice device = rtcNewDevice(nullptr);
    if (!device) return "unavailable";
    const long v = long(rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION));  // e.g. 31305
    rtcReleaseDevice(device);
    return std::to_string(v / 10000) + "." + std::to_string(v / 100 % 100) + "." + std::to_string(v % 100);
}

std::string embree_library() {
    // The address goes through this module's GOT, so it names the library the symbol was bound to.
    Dl_info info;
    if (dladdr(reinterpret_cast<void*>(&rtcNewDevice), &info) == 0 || !info.dli_fname) return "";
    return info.dli_fname;
}

}  // namespace bsgi
