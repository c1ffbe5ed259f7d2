#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cmath>
#include <stdexcept>

#include "bindings.h"
#include "bsgi/hemisphere_map.h"
#include "bsgi/memory_budget.h"
#include "bsgi/tensor_spline.h"
#include "../src/spline_kernels.h"

namespace py = pybind11;

namespace bsgi::bindings {

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

Precision precision_of(const py::object& p) {
    const std::string name = py::str(py::module_::import("numpy").attr("dtype")(p).attr("name"));
    if (name == "float64") return Precision::Float64;
    if (name == "float32") return Precision::Float32;
    throw std::invalid_argument("precision must be float64 or float32, got " + name);
}

const char* precision_name(Precision p) { return p == Precision::Float32 ? "float32" : "float64"; }

// Points as (N, width) or a single point (width,): returns N and whether it was a single point.
std::pair<size_t, bool> rows(const Array& a, py::ssize_t width, const char* what) {
    if (a.ndim() == 1 && a.shape(0) == width) return {1, true};
    if (a.ndim() == 2 && a.shape(1) == width) return {size_t(a.shape(0)), false};
    throw std::invalid_argument(std::string(what) + " must have shape (N, " + std::to_string(width) + ") or (" +
                                std::to_string(width) + ",)");
}

void require_finite(const Array& a, size_t width, const char* what) {
    const double* p = a.data();
    for (size_t i = 0; i < size_t(a.size()); ++i)
        if (!std::isfinite(p[i]))
            throw std::invalid_argument(std::string(what) + ": row " + std::to_string(i / width) + " is not finite");
}

py::array_t<double> result(size_t n, bool single, int channels) {
    if (single) return py::array_t<double>(channels);
    return py::array_t<double>({py::ssize_t(n), py::ssize_t(channels)});
}

py::array_t<double> to_array(const std::vector<double>& v) { return py::array_t<double>(v.size(), v.data()); }

}  // namespace

void bind_spline(py::module_& m) {
    py::register_exception<MemoryBudgetExceeded>(m, "MemoryBudgetError", PyExc_MemoryError);
    m.def("_fma_peak_per_second", &detail::measure_fma_rate,
          "Benchmark helper: 256-bit double multiply-adds per second of one thread (a pure FMA loop, timed in "
          "the thread's CPU time).");
    m.def("_kernel_isa", &detail::kernel_isa,
          "Instruction set of the evaluation kernels in use (x86-64-v4, x86-64-v3 or baseline; the "
          "environment variable BSGI_ISA can lower it).");
    m.def("memory_budget", &memory_budget, "Bytes one spline allocation may take (default 2 GiB).");
    m.def("set_memory_budget", &set_memory_budget, py::arg("bytes"),
          "Sets the byte budget; larger splines or fitting grids raise MemoryBudgetError before allocating.");

    py::class_<KnotVector>(m, "KnotVector", "Knot vector of a B-spline space: degree (0..5) and non-decreasing knots.")
        .def(py::init([](const std::vector<double>& knots, int degree) { return KnotVector(knots, degree); }),
             py::arg("knots"), py::arg("degree"),
             "Knots given by the user (e.g. clustered around a highlight): validated, ValueError names the problem.")
        .def_static("clamped_uniform", &KnotVector::clamped_uniform, py::arg("num_coeffs"), py::arg("degree"),
                    py::arg("a") = 0.0, py::arg("b") = 1.0,
                    "Uniform knots on [a, b], degree+1 at each end (19); the spatial knots are [eps, 1 - eps].")
        .def_static("symmetric", &KnotVector::symmetric, py::arg("num_coeffs"), py::arg("degree"), py::arg("R"),
                    "Angular knots (24): clamped uniform on [-R, R], exactly symmetric about 0.")
        .def_static("periodic", &KnotVector::periodic, py::arg("breakpoints"), py::arg("degree"),
                    "Periodic extension of breakpoints b_0..b_m over the period [b_0, b_m]: m coefficients, "
                    "parameters wrap.")
        .def_property_readonly("degree", &KnotVector::degree)
        .def_property_readonly("num_coeffs", &KnotVector::num_coeffs)
        .def_property_readonly("knots", [](const KnotVector& k) { return to_array(k.knots()); },
                               "The stored knots (extended by degree knots on each side when periodic).")
        .def_property_readonly("domain", [](const KnotVector& k) { return py::make_tuple(k.domain_begin(), k.domain_end()); })
        .def_property_readonly("is_periodic", &KnotVector::is_periodic)
        .def_property_readonly("clamped", &KnotVector::clamped)
        .def("find_span", &KnotVector::find_span, py::arg("x"),
             "Index I of the knot span [t_I, t_I+1) holding x (clamped or wrapped into the domain).")
        .def(
            "basis_matrix",
            [](const KnotVector& k, const Array& x) {
                const size_t n = size_t(x.size());
                py::array_t<double> out({py::ssize_t(n), py::ssize_t(k.num_coeffs())});
                auto o = out.mutable_unchecked<2>();
                std::fill(out.mutable_data(), out.mutable_data() + out.size(), 0.0);
                double b[kMaxDegree + 1];
                for (size_t i = 0; i < n; ++i) {
                    const double xi = x.data()[i];
                    if (std::isnan(xi)) {
                        for (int j = 0; j < k.num_coeffs(); ++j) o(i, j) = NAN;
                        continue;
                    }
                    const int span = k.find_span(xi);
                    k.basis(xi, span, b);
                    for (int j = 0; j <= k.degree(); ++j) o(i, k.coeff_index(span - k.degree() + j)) += b[j];
                }
                return out;
            },
            py::arg("x"), "All basis functions at the points x: shape (len(x), num_coeffs).")
        .def("schoenberg_nodes", [](const KnotVector& k) { return to_array(k.schoenberg_nodes()); },
             "Knot averages (12), where Schoenberg's method samples the function.")
        .def("basis_integrals", [](const KnotVector& k) { return to_array(k.basis_integrals()); },
             "Integrals of the basis functions over their support (11): B-spline quadrature weights.")
        .def("basis_integrals_over", [](const KnotVector& k, double a, double b) { return to_array(k.basis_integrals_over(a, b)); },
             py::arg("a"), py::arg("b"), "Integrals of the basis functions over [a, b] inside the domain.")
        .def("__repr__", [](const KnotVector& k) {
            return std::string("KnotVector(degree=") + std::to_string(k.degree()) + ", num_coeffs=" +
                   std::to_string(k.num_coeffs()) + (k.is_periodic() ? ", periodic" : "") + ")";
        });

    py::class_<HemisphereMap>(m, "HemisphereMap",
                              "Disc-to-hemisphere map (20)-(22) with the pull-in to radius R: (alpha, beta) <-> local "
                              "direction. The pole (0, 0) is (0, 0, 1) with phi = 0; directions beyond the cone "
                              "theta <= max_theta (also below the horizon) go to the rim of their azimuth, straight "
                              "down to (R, 0); zero or non-finite input gives NaN.")
        .def(py::init<double>(), py::arg("R"))
        .def_static("for_max_angle", &HemisphereMap::for_max_angle, py::arg("delta"),
                    "R = sqrt(1 - sin(delta)): the cone is exactly theta <= pi/2 - delta.")
        .def_property_readonly("radius", &HemisphereMap::radius)
        .def_property_readonly("max_theta", &HemisphereMap::max_theta)
        .def(
            "to_direction",
            [](const HemisphereMap& h, const Array& ab) {
                auto [n, single] = rows(ab, 2, "(alpha, beta)");
                auto out = result(n, single, 3);
                for (size_t i = 0; i < n; ++i) h.to_direction(ab.data()[2 * i], ab.data()[2 * i + 1], out.mutable_data() + 3 * i);
                return out;
            },
            py::arg("alpha_beta"), "(N, 2) disc points -> (N, 3) unit local directions.")
        .def(
            "to_disc",
            [](const HemisphereMap& h, const Array& d) {
                auto [n, single] = rows(d, 3, "directions");
                auto out = result(n, single, 2);
                const double* p = d.data();
                for (size_t i = 0; i < n; ++i) h.to_disc(p[3 * i], p[3 * i + 1], p[3 * i + 2], out.mutable_data() + 2 * i);
                return out;
            },
            py::arg("directions"), "(N, 3) local directions (any length from 1e-150 to 1e150; others give NaN) -> (N, 2) (alpha, beta).")
        .def(
            "angles",
            [](const HemisphereMap& h, const Array& ab) {
                auto [n, single] = rows(ab, 2, "(alpha, beta)");
                auto out = result(n, single, 2);
                for (size_t i = 0; i < n; ++i) h.angles(ab.data()[2 * i], ab.data()[2 * i + 1], out.mutable_data() + 2 * i);
                return out;
            },
            py::arg("alpha_beta"), "(N, 2) disc points -> (N, 2) local spherical angles (theta, phi).")
        .def("__repr__", [](const HemisphereMap& h) { return "HemisphereMap(R=" + std::to_string(h.radius()) + ")"; });

    py::class_<TensorSpline>(m, "TensorSpline",
                             "Tensor-product B-spline (14) with vector-valued (e.g. RGB) coefficients. Points outside "
                             "the domain are clamped to it (wrapped on periodic axes); a NaN or infinite parameter "
                             "gives NaN (or ValueError with check_finite=True).")
        .def(py::init([](std::vector<KnotVector> axes, int channels, const py::object& precision) {
                 return TensorSpline(std::move(axes), channels, precision_of(precision));
             }),
             py::arg("axes"), py::arg("channels") = 3, py::arg("precision") = "float64",
             "Zero coefficients; the size is checked against the memory budget first (MemoryBudgetError).")
        .def_static(
            "required_bytes",
            [](const std::vector<KnotVector>& axes, int channels, const py::object& precision) {
                return TensorSpline::coefficient_bytes(axes, channels, precision_of(precision));
            },
            py::arg("axes"), py::arg("channels") = 3, py::arg("precision") = "float64",
            "Coefficients x channels x bytes of such a spline, computed without allocating.")
        .def_property_readonly("dims", &TensorSpline::dims)
        .def_property_readonly("channels", &TensorSpline::channels)
        .def_property_readonly("axes", &TensorSpline::axes)
        .def_property_readonly("precision", [](const TensorSpline& s) { return precision_name(s.precision()); })
        .def_property_readonly("shape", [](const TensorSpline& s) {
            py::tuple t(s.shape().size());
            for (size_t i = 0; i < s.shape().size(); ++i) t[i] = s.shape()[i];
            return t;
        })
        .def_property_readonly("nbytes", &TensorSpline::bytes)
        .def_property_readonly("has_fast_kernel", &TensorSpline::has_fast_kernel)
        .def("with_precision", [](const TensorSpline& s, const py::object& p) { return s.with_precision(precision_of(p)); },
             py::arg("precision"), "Copy with float64 or float32 coefficient storage.")
        .def_property(
            "coefficients",
            [](py::object self) -> py::array {
                // A writable view sharing memory with the spline, kept alive by it.
                auto& s = self.cast<TensorSpline&>();
                std::vector<py::ssize_t> shape;
                for (size_t n : s.shape()) shape.push_back(py::ssize_t(n));
                if (s.precision() == Precision::Float32) return py::array_t<float>(shape, s.coeffs_f32(), self);
                return py::array_t<double>(shape, s.coeffs().data(), self);
            },
            [](TensorSpline& s, const py::array& value) {
                const auto shape = s.shape();
                bool ok = size_t(value.ndim()) == shape.size();
                for (size_t i = 0; ok && i < shape.size(); ++i) ok = size_t(value.shape(i)) == shape[i];
                if (!ok) throw std::invalid_argument("coefficients: shape does not match the spline");
                if (s.precision() == Precision::Float32) {
                    auto a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(value);
                    std::copy(a.data(), a.data() + a.size(), s.coeffs_f32());
                } else {
                    auto a = Array::ensure(value);
                    std::copy(a.data(), a.data() + a.size(), s.coeffs().begin());
                }
            },
            "Coefficients, shape (n_0, ..., n_{D-1}, channels), C order; a view that writes through.")
        .def(
            "evaluate",
            [](const TensorSpline& s, const Array& x, int threads, bool check_finite) {
                auto [n, single] = rows(x, s.dims(), "points");
                if (check_finite) require_finite(x, s.dims(), "evaluate");
                auto out = result(n, single, s.channels());
                const double* xp = x.data();
                double* op = out.mutable_data();
                if (single) {
                    s.evaluate(xp, op);  // the single-point path (no batch kernel)
                } else {
                    py::gil_scoped_release release;
                    s.evaluate_batch(xp, n, op, threads);
                }
                return out;
            },
            py::arg("points"), py::arg("threads") = 0, py::arg("check_finite") = false,
            "Values at points (N, dims) -> (N, channels), or one point (dims,) -> (channels,). Releases the GIL; "
            "threads=0 uses all cores.")
        .def(
            "evaluate_directions",
            [](const TensorSpline& s, const Array& uv, const Array& dirs, const HemisphereMap& map, int threads,
               bool check_finite) {
                auto [n, single] = rows(uv, 2, "uv");
                auto [nd, single_d] = rows(dirs, 3, "directions");
                if (nd != n || single != single_d) throw std::invalid_argument("evaluate_directions: uv and directions differ in length");
                if (check_finite) require_finite(uv, 2, "evaluate_directions uv"), require_finite(dirs, 3, "evaluate_directions directions");
                auto out = result(n, single, s.channels());
                const double *up = uv.data(), *dp = dirs.data();
                double* op = out.mutable_data();
                {
                    py::gil_scoped_release release;
                    s.evaluate_directions(up, dp, n, map, op, threads);
                }
                return out;
            },
            py::arg("uv"), py::arg("directions"), py::arg("hemisphere"), py::arg("threads") = 0,
            py::arg("check_finite") = false,
            "Radiance L(u, v, alpha, beta) of a 4D spline at uv (N, 2) along local directions (N, 3), through the "
            "inverse hemisphere map. Releases the GIL.")
        .def(
            "integral",
            [](const TensorSpline& s) {
                py::array_t<double> out(s.channels());
                s.integral(out.mutable_data());
                return out;
            },
            "Integral over the whole domain per channel ((11) on clamped axes).")
        .def(
            "integral_over",
            [](const TensorSpline& s, const Array& lo, const Array& hi) {
                if (lo.size() != s.dims() || hi.size() != s.dims())
                    throw std::invalid_argument("integral_over: lo and hi need one value per dimension");
                py::array_t<double> out(s.channels());
                s.integral_over(lo.data(), hi.data(), out.mutable_data());
                return out;
            },
            py::arg("lo"), py::arg("hi"), "Integral over the box [lo, hi] (inside the domain) per channel.")
        .def("__repr__", [](const TensorSpline& s) {
            std::string r = "TensorSpline(shape=(";
            for (size_t i = 0; i < s.shape().size(); ++i) r += (i ? ", " : "") + std::to_string(s.shape()[i]);
            return r + "), precision=" + precision_name(s.precision()) + ")";
        });
}

}  // namespace bsgi::bindings
