#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <stdexcept>

#include "bindings.h"
#include "bsgi/fitting.h"
#include "bsgi/sharpen.h"

namespace py = pybind11;

namespace bsgi::bindings {

namespace {

FitMethod method_of(const std::string& name) {
    if (name == "schoenberg") return FitMethod::Schoenberg;
    if (name == "quadratic") return FitMethod::QuadraticQuasiInterpolant;
    if (name == "cubic") return FitMethod::CubicQuasiInterpolant;
    throw std::invalid_argument("fitting method must be 'schoenberg', 'quadratic' or 'cubic', got '" + name + "'");
}

const char* method_name(FitMethod m) {
    switch (m) {
        case FitMethod::Schoenberg: return "schoenberg";
        case FitMethod::QuadraticQuasiInterpolant: return "quadratic";
        default: return "cubic";
    }
}

// One method name for all axes, or one per axis.
std::vector<FitRule> rules_of(const TensorSpline& s, const py::object& method) {
    std::vector<FitRule> rules;
    if (py::isinstance<py::str>(method)) return make_fit_rules(s, method_of(method.cast<std::string>()));
    const auto names = method.cast<std::vector<std::string>>();
    if (int(names.size()) != s.dims()) throw std::invalid_argument("fitting: one method per dimension, or one for all");
    for (int k = 0; k < s.dims(); ++k) rules.push_back(make_fit_rule(s.axis(k), method_of(names[k])));
    return rules;
}

}  // namespace

void bind_fitting(py::module_& m) {
    py::class_<FitRule>(m, "FitRule",
                        "Local fitting rule of one axis: coefficients = matrix @ f(nodes). Methods: 'schoenberg' (12), "
                        "'quadratic' (the quasi-interpolant of section 2.2.1, degree 2), 'cubic' (Lee-Lyche-Morken "
                        "order-4 quasi-interpolant, degree 3).")
        .def(py::init([](const KnotVector& k, const std::string& method) { return make_fit_rule(k, method_of(method)); }),
             py::arg("knots"), py::arg("method") = "schoenberg")
        .def_property_readonly("method", [](const FitRule& r) { return method_name(r.method); })
        .def_property_readonly("nodes", [](const FitRule& r) { return py::array_t<double>(r.nodes.size(), r.nodes.data()); })
        .def_property_readonly("num_coeffs", &FitRule::num_coeffs)
        .def_property_readonly(
            "matrix",
            [](const FitRule& r) {
                py::array_t<double> out({py::ssize_t(r.num_coeffs()), py::ssize_t(r.nodes.size())});
                std::fill(out.mutable_data(), out.mutable_data() + out.size(), 0.0);
                auto o = out.mutable_unchecked<2>();
                for (int i = 0; i < r.num_coeffs(); ++i)
                    for (size_t t = r.row_start[i]; t < r.row_start[i + 1]; ++t) o(i, r.node_index[t]) += r.weight[t];
                return out;
            },
            "Dense (num_coeffs, len(nodes)) weights.");

    m.def(
        "fitting_nodes",
        [](const TensorSpline& s, const py::object& method) {
            py::list out;
            for (const auto& r : rules_of(s, method)) out.append(py::array_t<double>(r.nodes.size(), r.nodes.data()));
            return out;
        },
        py::arg("spline"), py::arg("method") = "schoenberg", "Per axis, the nodes where the method samples f.");
    m.def(
        "_fit_pointwise",
        [](TensorSpline& s, const py::function& f, const py::object& method) {
            const auto rules = rules_of(s, method);
            const int D = s.dims(), C = s.channels();
            // The core's callback fit, on this thread (the callback is Python: it needs the GIL,
            // which this thread holds).
            fit(s, rules,
                [&](const double* x, double* value) {
                    auto v = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(
                        f(py::array_t<double>(D, x)));
                    if (!v || v.size() != C)
                        throw std::invalid_argument("fit: f must return " + std::to_string(C) + " values per point");
                    std::copy(v.data(), v.data() + C, value);
                },
                1);
        },
        py::arg("spline"), py::arg("f"), py::arg("method") = "schoenberg",
        "Fit from a Python function of one point (dims,) -> (channels,), called once per node.");
    m.def(
        "fit_from_samples",
        [](TensorSpline& s, py::array_t<double, py::array::c_style | py::array::forcecast> samples, const py::object& method) {
            const auto rules = rules_of(s, method);
            bool ok = samples.ndim() == s.dims() + 1 && samples.shape(s.dims()) == s.channels();
            for (int k = 0; ok && k < s.dims(); ++k) ok = size_t(samples.shape(k)) == rules[k].nodes.size();
            if (!ok) {
                std::string want = "(";
                for (const auto& r : rules) want += std::to_string(r.nodes.size()) + ", ";
                throw std::invalid_argument("fit_from_samples: samples must have shape " + want + std::to_string(s.channels()) + ")");
            }
            py::gil_scoped_release release;
            fit_from_samples(s, rules, samples.data());
        },
        py::arg("spline"), py::arg("samples"), py::arg("method") = "schoenberg",
        "Sets the coefficients from f sampled on the grid of fitting_nodes(spline, method), channels last; the "
        "rule is applied dimension by dimension.");
    m.def(
        "sharpen_samples",
        [](TensorSpline& s, int axis, const std::vector<double>& nodes, const std::vector<uint8_t>& keep) {
            py::gil_scoped_release release;
            sharpen_samples(s, axis, nodes, keep);
        },
        py::arg("spline"), py::arg("axis"), py::arg("nodes") = std::vector<double>{},
        py::arg("keep") = std::vector<uint8_t>{},
        "In place along `axis`: coefficients that are samples of f at `nodes` (default: the axis's Schoenberg "
        "nodes) become the limited quadratic correction of Schoenberg's fit (sharpen.h): quadratics reproduced "
        "where f is smooth, no correction where its curvature changes sign (an edge). `keep`: per spatial node "
        "(the first two axes, u slowest), 1 where the coefficients stay their samples (means over a node's support).");
}

}  // namespace bsgi::bindings
