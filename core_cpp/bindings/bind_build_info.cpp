#include <pybind11/stl.h>

#include "bindings.h"
#include "bsgi/build_info.h"

namespace bsgi::bindings {

void bind_build_info(pybind11::module_& m) {
    m.def("embree_version", &bsgi::embree_version,
          "Version of the Embree library the core's ray casting reaches at run time, e.g. '3.13.5'.");
    m.def("embree_library", &bsgi::embree_library,
          "Path of the shared library that provides the core's Embree entry points.");
}

}  // namespace bsgi::bindings
