#include "bindings.h"

PYBIND11_MODULE(_core, m) {
    m.doc() = "bsgi compiled core: B-spline radiance, geometry, Embree ray casting, the gathering solver";
    bsgi::bindings::bind_spline(m);
    bsgi::bindings::bind_fitting(m);
    bsgi::bindings::bind_geometry(m);  // before Scene, whose add_surface takes its surfaces
    bsgi::bindings::bind_scene(m);
    bsgi::bindings::bind_bsdf(m);
    bsgi::bindings::bind_build_info(m);
}
