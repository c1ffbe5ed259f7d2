#include "bindings.h"

PYBIND11_MODULE(_core, m) {
    m.doc() = "bsgi compiled core: B-spline radiance, geometry, Embree ray casting, the gathering solver";
    bsgi::bindings::bind_spline(m);
    bsgi::bindings::bind_fitting(m);
    bsgi::bindings::bind_scene(m);
}
