#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cmath>
#include <stdexcept>

#include "bindings.h"
#include "bsgi/tensor_spline.h"

namespace py = pybind11;

namespace bsgi::bindings {

void bind_spline(py::module_& m) {
    py::class_<KnotVector>(m, "KnotVector", "Knot vector of a B-spline space: degree and non-decreasing knots.")
        .def(py::init([](const std::vector<double>& knots, int degree) { return KnotVector(knots, degree); }),
             py::arg("knots"), py::arg("degree"))
        .def_static("clamped_uniform", &KnotVector::clamped_uniform, py::arg("num_coeffs"), py::arg("degree"),
                    py::arg("a") = 0.0, py::arg("b") = 1.0, "Uniform knots on [a, b], degree+1 at each end (paper (19)).")
        .def_property_readonly("degree", &KnotVector::degree)
        .def_property_readonly("num_coeffs", &KnotVector::num_coeffs)
        .def_property_readonly("knots", [](const KnotVector& k) { return py::array_t<double>(k.knots().size(), k.knots().data()); })
        .def_property_readonly("domain", [](const KnotVector& k) { return py::make_tuple(k.domain_begin(), k.domain_end()); })
        .def("schoenberg_nodes", [](const KnotVector& k) { auto n = k.schoenberg_nodes(); return py::array_t<double>(n.size(), n.data()); },
             "Knot averages (12), where Schoenberg's method samples the function.")
        .def("basis_integrals", [](const KnotVector& k) { auto w = k.basis_integrals(); return py::array_t<double>(w.size(), w.data()); },
             "Integrals of the basis functions (11): B-spline quadrature weights.")
        .def("__repr__", [](const KnotVector& k) {
            return "KnotVector(degree=" + std::to_string(k.degree()) + ", num_coeffs=" + std::to_string(k.num_coeffs()) + ")";
        });

    py::class_<TensorSpline>(m, "TensorSpline", "Tensor-product B-spline with vector-valued coefficients (paper (14)).")
        .def(py::init<std::vector<KnotVector>, int>(), py::arg("axes"), py::arg("channels") = 3)
        .def_property_readonly("dims", &TensorSpline::dims)
        .def_property_readonly("channels", &TensorSpline::channels)
        .def_property_readonly("axes", &TensorSpline::axes)
        .def_property(
            "coefficients",
            [](py::object self) {
                // A writable view sharing memory with the spline, kept alive by it.
                auto& s = self.cast<TensorSpline&>();
                std::vector<py::ssize_t> shape, strides;
                for (size_t n : s.shape()) shape.push_back(py::ssize_t(n));
                py::ssize_t stride = sizeof(double);
                strides.resize(shape.size());
                for (int i = int(shape.size()) - 1; i >= 0; --i) strides[i] = stride, stride *= shape[i];
                return py::array_t<double>(shape, strides, s.coeffs().data(), self);
            },
            [](TensorSpline& s, py::array_t<double, py::array::c_style | py::array::forcecast> a) {
                const auto shape = s.shape();
                bool ok = size_t(a.ndim()) == shape.size();
                for (size_t i = 0; ok && i < shape.size(); ++i) ok = size_t(a.shape(i)) == shape[i];
                if (!ok) throw std::invalid_argument("coefficients: shape does not match the spline");
                std::copy(a.data(), a.data() + a.size(), s.coeffs().begin());
            })
        .def(
            "evaluate",
            [](const TensorSpline& s, py::array_t<double, py::array::c_style | py::array::forcecast> x, int threads) {
                if (x.ndim() != 2 || x.shape(1) != s.dims())
                    throw std::invalid_argument("evaluate: points must have shape (N, " + std::to_string(s.dims()) + ")");
                const size_t n = x.shape(0);
                for (size_t i = 0; i < n * s.dims(); ++i)
                    if (!std::isfinite(x.data()[i])) throw std::invalid_argument("evaluate: parameters must be finite");
                py::array_t<double> out({py::ssize_t(n), py::ssize_t(s.channels())});
                const double* xp = x.data();
                double* op = out.mutable_data();
                {
                    py::gil_scoped_release release;
                    s.evaluate_batch(xp, n, op, threads);
                }
                return out;
            },
            py::arg("points"), py::arg("threads") = 0,
            "Values at points of shape (N, dims), clamped to the domain; returns (N, channels).");
}

}  // namespace bsgi::bindings
