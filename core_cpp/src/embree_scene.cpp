// Embree 3 behind bsgi::RayScene. Embree 4 changes: RTCIntersectContext becomes
// RTCIntersectArguments/RTCOccludedArguments, rtcIntersect1 takes them as an optional pointer.
#include <embree3/rtcore.h>

#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "bsgi/ray_scene.h"

namespace bsgi {

struct RayScene::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    struct GeometryInfo {
        int surface;
        std::vector<float> uvs;
        std::vector<uint32_t> triangles;
    };
    std::vector<GeometryInfo> geometries;  // indexed by Embree geometry id
    bool committed = false;

    void check(const char* what) const {
        const RTCError err = rtcGetDeviceError(device);
        if (err != RTC_ERROR_NONE) throw std::runtime_error(std::string("Embree error ") + std::to_string(int(err)) + " in " + what);
    }
};

RayScene::RayScene() : impl_(new Impl) {
    impl_->device = rtcNewDevice(nullptr);
    if (!impl_->device) throw std::runtime_error("Embree: cannot create a device");
    impl_->scene = rtcNewScene(impl_->device);
    rtcSetSceneFlags(impl_->scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
}

RayScene::~RayScene() {
    if (impl_->scene) rtcReleaseScene(impl_->scene);
    if (impl_->device) rtcReleaseDevice(impl_->device);
}

void RayScene::add(int surface_id, const Tessellation& tess) {
    if (impl_->committed) throw std::logic_error("RayScene::add after commit");
    const size_t nv = tess.positions.size() / 3, nt = tess.triangles.size() / 3;
    RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vb = static_cast<float*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
    auto* ib = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), nt));
    impl_->check("rtcSetNewGeometryBuffer");
    std::memcpy(vb, tess.positions.data(), tess.positions.size() * sizeof(float));
    std::memcpy(ib, tess.triangles.data(), tess.triangles.size() * sizeof(uint32_t));
    rtcCommitGeometry(geom);
    const unsigned id = rtcAttachGeometry(impl_->scene, geom);
    rtcReleaseGeometry(geom);
    if (id != impl_->geometries.size()) throw std::logic_error("Embree geometry ids are not sequential");
    impl_->geometries.push_back({surface_id, tess.uvs, tess.triangles});
}

void RayScene::commit() {
    rtcCommitScene(impl_->scene);
    impl_->check("rtcCommitScene");
    impl_->committed = true;
}

RayHit RayScene::closest_hit(const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    rh.ray.org_x = float(o.x), rh.ray.org_y = float(o.y), rh.ray.org_z = float(o.z);
    rh.ray.dir_x = float(d.x), rh.ray.dir_y = float(d.y), rh.ray.dir_z = float(d.z);
    rh.ray.tnear = float(tnear), rh.ray.tfar = float(tfar);
    rh.ray.time = 0, rh.ray.mask = 0xFFFFFFFFu, rh.ray.id = 0, rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(impl_->scene, &context, &rh);
    RayHit hit;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    const Impl::GeometryInfo& g = impl_->geometries[rh.hit.geomID];
    const uint32_t* tri = &g.triangles[3 * rh.hit.primID];
    const double b1 = rh.hit.u, b2 = rh.hit.v, b0 = 1.0 - b1 - b2;
    hit.surface = g.surface;
    hit.t = rh.ray.tfar;
    hit.u = b0 * g.uvs[2 * tri[0]] + b1 * g.uvs[2 * tri[1]] + b2 * g.uvs[2 * tri[2]];
    hit.v = b0 * g.uvs[2 * tri[0] + 1] + b1 * g.uvs[2 * tri[1] + 1] + b2 * g.uvs[2 * tri[2] + 1];
    return hit;
}

bool RayScene::occluded(const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray;
    ray.org_x = float(o.x), ray.org_y = float(o.y), ray.org_z = float(o.z);
    ray.dir_x = float(d.x), ray.dir_y = float(d.y), ray.dir_z = float(d.z);
    ray.tnear = float(tnear), ray.tfar = float(tfar);
    ray.time = 0, ray.mask = 0xFFFFFFFFu, ray.id = 0, ray.flags = 0;
    rtcOccluded1(impl_->scene, &context, &ray);
    return ray.tfar == -std::numeric_limits<float>::infinity();
}

}  // namespace bsgi
