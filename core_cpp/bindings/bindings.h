// Each file binds one part of the core; module.cpp calls them in order.
#pragma once
#include <pybind11/pybind11.h>

namespace bsgi::bindings {
void bind_spline(pybind11::module_& m);
void bind_fitting(pybind11::module_& m);
void bind_scene(pybind11::module_& m);
void bind_geometry(pybind11::module_& m);
void bind_bsdf(pybind11::module_& m);
void bind_build_info(pybind11::module_& m);
}  // namespace bsgi::bindings
