#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include "bindings.h"
#include "bsgi/solver.h"

namespace py = pybind11;

namespace bsgi::bindings {

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

std::vector<Vec3> points(const Array& a, size_t n, const char* what) {
    if (a.ndim() != 2 || size_t(a.shape(0)) != n || a.shape(1) != 3)
        throw std::invalid_argument(std::string(what) + ": corners must have shape (" + std::to_string(n) + ", 3)");
    std::vector<Vec3> p;
    for (size_t i = 0; i < n; ++i) p.emplace_back(a.at(i, 0), a.at(i, 1), a.at(i, 2));
    return p;
}

Vec3 rgb(const Array& a, const char* what) {
    if (a.size() != 3) throw std::invalid_argument(std::string(what) + " must have 3 values (RGB)");
    return {a.data()[0], a.data()[1], a.data()[2]};
}

py::array_t<double> vec(const Vec3& v) { return py::array_t<double>(3, &v.x); }

}  // namespace

void bind_scene(py::module_& m) {
    py::register_exception<Cancelled>(m, "SolveCancelled", PyExc_RuntimeError);

    py::class_<Scene>(m, "Scene", "Surfaces with Lambertian materials and emission.")
        .def(py::init<>())
        .def(
            "add_bilinear_patch",
            [](Scene& s, const std::string& name, const Array& corners, const Array& albedo, const Array& emission,
               bool receiver, bool occluder) {
                auto p = points(corners, 4, ("surface '" + name + "'").c_str());
                return s.add(std::make_unique<BilinearPatch>(name, p[0], p[1], p[2], p[3]),
                             {rgb(albedo, "albedo"), rgb(emission, "emission")}, receiver, occluder);
            },
            py::arg("name"), py::arg("corners"), py::arg("albedo"), py::arg("emission"), py::arg("receiver") = true,
            py::arg("occluder") = true)
        .def(
            "add_triangle",
            [](Scene& s, const std::string& name, const Array& corners, const Array& albedo, const Array& emission,
               bool receiver, bool occluder) {
                auto p = points(corners, 3, ("surface '" + name + "'").c_str());
                return s.add(std::make_unique<TrianglePatch>(name, p[0], p[1], p[2]),
                             {rgb(albedo, "albedo"), rgb(emission, "emission")}, receiver, occluder);
            },
            py::arg("name"), py::arg("corners"), py::arg("albedo"), py::arg("emission"), py::arg("receiver") = true,
            py::arg("occluder") = true)
        .def(
            "add_surface",
            [](Scene& s, std::shared_ptr<Surface> surface, const Array& albedo, const Array& emission, bool receiver, bool occluder) {
                return s.add(std::move(surface), {rgb(albedo, "albedo"), rgb(emission, "emission")}, receiver, occluder);
            },
            py::arg("surface"), py::arg("albedo"), py::arg("emission"), py::arg("receiver") = true, py::arg("occluder") = true,
            "Adds any bsgi surface (NurbsSurface, MeshChart, patches); the scene shares it.")
        .def("__len__", &Scene::size)
        .def("name", [](const Scene& s, size_t i) { return s[i].surface->name(); })
        .def("area", [](const Scene& s, size_t i) { return s[i].surface->area(); })
        .def(
            "evaluate_surface",
            [](const Scene& s, size_t i, double u, double v) {
                if (i >= s.size()) throw py::index_error("no surface " + std::to_string(i));
                const SurfacePoint p = s[i].surface->evaluate(u, v);
                py::dict d;
                d["position"] = vec(p.p), d["dpdu"] = vec(p.dpdu), d["dpdv"] = vec(p.dpdv);
                d["x"] = vec(p.frame.x), d["y"] = vec(p.frame.y), d["normal"] = vec(p.frame.z);
                d["jacobian"] = p.jacobian;
                return d;
            },
            py::arg("index"), py::arg("u"), py::arg("v"), "Point, derivatives and local frame (1)-(3) of surface index at (u, v).");

    py::class_<SolverSettings>(m, "SolverSettings", "Knots, degrees, integration nodes and bounces of a solve.")
        .def(py::init<>())
        .def_readwrite("spatial_coeffs", &SolverSettings::spatial_coeffs)
        .def_readwrite("spatial_degree", &SolverSettings::spatial_degree)
        .def_readwrite("epsilon", &SolverSettings::epsilon)
        .def_readwrite("adaptive_knots", &SolverSettings::adaptive_knots)
        .def_readwrite("emitter_coeffs", &SolverSettings::emitter_coeffs)
        .def_readwrite("emitter_cell_ratio", &SolverSettings::emitter_cell_ratio)
        .def_readwrite("emitter_max_depth", &SolverSettings::emitter_max_depth)
        .def_readwrite("emitter_degree", &SolverSettings::emitter_degree)
        .def_readwrite("hemisphere_nodes_theta", &SolverSettings::hemisphere_nodes_theta)
        .def_readwrite("hemisphere_nodes_phi", &SolverSettings::hemisphere_nodes_phi)
        .def_readwrite("max_bounces", &SolverSettings::max_bounces)
        .def_readwrite("tolerance", &SolverSettings::tolerance)
        .def_readwrite("extrapolate", &SolverSettings::extrapolate)
        .def_readwrite("threads", &SolverSettings::threads)
        .def_readwrite("memory_budget_mb", &SolverSettings::memory_budget_mb);

    py::class_<Progress>(m, "Progress", "Progress of a solve: poll it from any thread, cancel() stops the solve.")
        .def(py::init<>())
        .def_property_readonly("fraction", &Progress::fraction)
        .def_property_readonly("stage", &Progress::stage)
        .def_property_readonly("cancelled", &Progress::cancelled)
        .def("cancel", &Progress::cancel);

    py::class_<Solution>(m, "Solution")
        .def_property_readonly("radiance", [](const Solution& s) {
            py::list out;
            for (const auto& r : s.radiance) out.append(r ? py::cast(*r) : py::none());
            return out;
        })
        .def_property_readonly("stats", [](const Solution& s) {
            py::dict d;
            d["seconds_direct"] = s.stats.seconds_direct;
            d["seconds_indirect"] = s.stats.seconds_indirect;
            d["bounces"] = s.stats.bounces;
            d["last_increment"] = s.stats.last_increment;
            d["estimated_error"] = s.stats.estimated_error;
            d["extrapolated"] = s.stats.extrapolated;
            d["coefficients"] = s.stats.coefficients;
            d["rays"] = s.stats.rays;
            return d;
        });

    m.def("estimate_solve_bytes", &estimate_solve_bytes, py::arg("scene"), py::arg("settings"));
    m.def(
        "solve",
        [](const Scene& scene, const SolverSettings& settings, Progress& progress) {
            py::gil_scoped_release release;
            return solve(scene, settings, progress);
        },
        py::arg("scene"), py::arg("settings"), py::arg("progress"),
        "Algorithm 1: direct light by the surface integral, indirect bounces by gathering. Releases the GIL.");
}

}  // namespace bsgi::bindings
