// BSDFs and emission, batched over numpy arrays of local-frame directions.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <stdexcept>

#include "bindings.h"
#include "bsgi/bsdf.h"

namespace py = pybind11;

namespace bsgi::bindings {

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

size_t vectors(const Array& a, const char* what) {
    if (a.ndim() != 2 || a.shape(1) != 3) throw std::invalid_argument(std::string(what) + " must have shape (N, 3)");
    return size_t(a.shape(0));
}

// Pairs of directions (wo, wi), each (N, 3): N.
size_t direction_pairs(const Array& wo, const Array& wi) {
    const size_t n = vectors(wo, "wo");
    if (vectors(wi, "wi") != n) throw std::invalid_argument("wo and wi differ in length");
    return n;
}

Vec3 at(const Array& a, size_t i) { return {a.data()[3 * i], a.data()[3 * i + 1], a.data()[3 * i + 2]}; }

Vec3 rgb(const Array& a, const char* what) {
    if (a.size() == 1) return {a.data()[0], a.data()[0], a.data()[0]};
    if (a.size() != 3) throw std::invalid_argument(std::string(what) + " must have 1 or 3 values");
    return {a.data()[0], a.data()[1], a.data()[2]};
}

py::tuple rgb_tuple(const Vec3& v) { return py::make_tuple(v.x, v.y, v.z); }

void put(double* dst, const Vec3& v) { dst[0] = v.x, dst[1] = v.y, dst[2] = v.z; }

}  // namespace

void bind_bsdf(py::module_& m) {
    py::class_<Bsdf, std::shared_ptr<Bsdf>>(m, "Bsdf",
                                            "A BSDF in the local frame (z = normal): wo towards the viewer, wi towards the light.")
        .def_property_readonly("name", &Bsdf::name)
        .def(
            "eval",
            [](const Bsdf& b, const Array& wo, const Array& wi) {
                const size_t n = direction_pairs(wo, wi);
                py::array_t<double> out({py::ssize_t(n), py::ssize_t(3)});
                double* o = out.mutable_data();
                {
                    py::gil_scoped_release release;
                    for (size_t i = 0; i < n; ++i) put(o + 3 * i, b.eval(at(wo, i), at(wi, i)));
                }
                return out;
            },
            py::arg("wo"), py::arg("wi"), "BSDF values (N, 3) RGB, without the cosine.")
        .def(
            "pdf",
            [](const Bsdf& b, const Array& wo, const Array& wi) {
                const size_t n = direction_pairs(wo, wi);
                py::array_t<double> out(static_cast<py::ssize_t>(n));
                double* o = out.mutable_data();
                {
                    py::gil_scoped_release release;
                    for (size_t i = 0; i < n; ++i) o[i] = b.pdf(at(wo, i), at(wi, i));
                }
                return out;
            },
            py::arg("wo"), py::arg("wi"), "Solid-angle density of sample() drawing wi given wo.")
        .def(
            "eval_pdf",
            [](const Bsdf& b, const Array& wo, const Array& wi) {
                const size_t n = direction_pairs(wo, wi);
                py::array_t<double> values({py::ssize_t(n), py::ssize_t(3)});
                py::array_t<double> pdf(static_cast<py::ssize_t>(n));
                double *v = values.mutable_data(), *p = pdf.mutable_data();
                {
                    py::gil_scoped_release release;
                    for (size_t i = 0; i < n; ++i) put(v + 3 * i, b.eval_pdf(at(wo, i), at(wi, i), p[i]));
                }
                return py::make_tuple(values, pdf);
            },
            py::arg("wo"), py::arg("wi"), "(eval, pdf) at once, as the gather's multiple importance sampling takes them.")
        .def(
            "sample",
            [](const Bsdf& b, const Array& wo, const Array& u) {
                const size_t n = vectors(wo, "wo");
                if (vectors(u, "u") != n) throw std::invalid_argument("wo and u differ in length");
                py::array_t<double> wi({py::ssize_t(n), py::ssize_t(3)}), weight({py::ssize_t(n), py::ssize_t(3)});
                py::array_t<double> pdf(static_cast<py::ssize_t>(n));
                py::array_t<bool> valid(static_cast<py::ssize_t>(n)), delta(static_cast<py::ssize_t>(n));
                double *pw = wi.mutable_data(), *pt = weight.mutable_data(), *pp = pdf.mutable_data();
                bool *pv = valid.mutable_data(), *pd = delta.mutable_data();
                {
                    py::gil_scoped_release release;
                    for (size_t i = 0; i < n; ++i) {
                        const Vec3 r = at(u, i);
                        BsdfSample s;
                        pv[i] = b.sample(at(wo, i), r.x, r.y, r.z, s);
                        if (!pv[i]) s = BsdfSample{};
                        put(pw + 3 * i, s.wi), put(pt + 3 * i, s.weight);
                        pp[i] = s.pdf;
                        pd[i] = s.delta;
                    }
                }
                py::dict d;
                d["wi"] = wi, d["weight"] = weight, d["pdf"] = pdf, d["valid"] = valid, d["delta"] = delta;
                return d;
            },
            py::arg("wo"), py::arg("u"),
            "Draws wi for each wo from three uniform numbers per row: wi, weight = eval |cos| / pdf, pdf, valid, delta.")
        .def(
            "index_on_side",
            [](const Bsdf& b, const Array& w) {
                const size_t n = vectors(w, "w");
                py::array_t<double> out(static_cast<py::ssize_t>(n));
                for (size_t i = 0; i < n; ++i) out.mutable_data()[i] = b.index_on_side(at(w, i));
                return out;
            },
            py::arg("w"), "Refractive index of the medium on the side of each direction.");

    py::class_<Lambert, Bsdf, std::shared_ptr<Lambert>>(m, "Lambert")
        .def(py::init([](const Array& albedo) { return std::make_shared<Lambert>(rgb(albedo, "Lambert: albedo")); }), py::arg("albedo"));
    py::class_<BumpedLambert, Bsdf, std::shared_ptr<BumpedLambert>>(
        m, "BumpedLambert",
        "Lambertian reflection about a bumped normal, as Cycles shades a Diffuse BSDF under a normal map: albedo / pi "
        "max(0, n . wi) G1(wi) over the light above the surface, G1 Cycles' bump shadowing term (with "
        "bump_correction, the material's Bump Map Correction). Its direction argument wo is the bumped normal n.")
        .def(py::init([](const Array& albedo, bool bump_correction) {
                 return std::make_shared<BumpedLambert>(rgb(albedo, "BumpedLambert: albedo"), bump_correction);
             }),
             py::arg("albedo"), py::arg("bump_correction") = true)
        .def("shadowing", &BumpedLambert::shadowing, py::arg("cos_n"), py::arg("cos_i"),
             "Cycles' bump shadowing term: a bumped normal at cosine cos_n to the surface's, light at cos_i to it.");
    py::class_<NormalizedPhong, Bsdf, std::shared_ptr<NormalizedPhong>>(m, "NormalizedPhong")
        .def(py::init([](const Array& kd, const Array& ks, double n) {
                 return std::make_shared<NormalizedPhong>(rgb(kd, "NormalizedPhong: kd"), rgb(ks, "NormalizedPhong: ks"), n);
             }),
             py::arg("kd"), py::arg("ks"), py::arg("exponent"));
    py::class_<AshikhminShirley, Bsdf, std::shared_ptr<AshikhminShirley>>(m, "AshikhminShirley")
        .def(py::init([](const Array& rd, const Array& rs, double nu, double nv) {
                 return std::make_shared<AshikhminShirley>(rgb(rd, "AshikhminShirley: rd"), rgb(rs, "AshikhminShirley: rs"), nu, nv);
             }),
             py::arg("rd"), py::arg("rs"), py::arg("nu"), py::arg("nv"));
    py::class_<GgxReflection, Bsdf, std::shared_ptr<GgxReflection>>(
        m, "GgxReflection",
        "GGX reflection; rotation (radians) turns the alpha_x axis from s_u towards s_v about the normal. schlick: "
        "Schlick's Fresnel from f0 (Cycles' metals); off: f0 at every angle (Cycles' Glossy BSDF, its colour). "
        "multiscatter: the light scattered between microfacets put back, as Cycles' Multiscatter GGX. height_correlated: "
        "Smith's height-correlated shadowing, as Cycles' (else the separable form, as Mitsuba's roughconductor).")
        .def(py::init([](double ax, double ay, const Array& f0, double rotation, bool schlick, double eta, bool multiscatter,
                         bool height_correlated) {
                 return std::make_shared<GgxReflection>(ax, ay, rgb(f0, "GgxReflection: f0"), rotation, schlick, eta,
                                                        multiscatter, height_correlated);
             }),
             py::arg("alpha_x"), py::arg("alpha_y"), py::arg("f0"), py::arg("rotation") = 0.0, py::arg("schlick") = true,
             py::arg("eta") = 0.0, py::arg("multiscatter") = false, py::arg("height_correlated") = false)
        .def_property_readonly("multiscatter", &GgxReflection::multiscatter)
        .def_property_readonly("height_correlated", &GgxReflection::height_correlated);
    py::class_<DiffuseGgx, Bsdf, std::shared_ptr<DiffuseGgx>>(
        m, "DiffuseGgx",
        "Lambertian base under a GGX coat: albedo / pi + GGX; layered (Cycles' Principled BSDF): (1 - E(mu_o)) albedo / "
        "pi + GGX, E the coat's directional albedo along the view (energy conserved). multiscatter: the coat's (as "
        "GgxReflection's), height_correlated: the coat's shadowing (as GgxReflection's).")
        .def(py::init([](const Array& albedo, double ax, double ay, const Array& f0, bool layered, double eta, bool multiscatter,
                         bool height_correlated) {
                 return std::make_shared<DiffuseGgx>(rgb(albedo, "DiffuseGgx: albedo"), ax, ay, rgb(f0, "DiffuseGgx: f0"), layered,
                                                     eta, multiscatter, height_correlated);
             }),
             py::arg("albedo"), py::arg("alpha_x"), py::arg("alpha_y"), py::arg("f0"), py::arg("layered") = false,
             py::arg("eta") = 0.0, py::arg("multiscatter") = false, py::arg("height_correlated") = false)
        .def_property_readonly("layered", &DiffuseGgx::layered)
        .def_property_readonly("glossy_part", [](const DiffuseGgx& b) { return std::const_pointer_cast<Bsdf>(b.glossy_part()); },
                               "The glossy part S of (38): the coat, less E(mu_o) albedo / pi where layered.");
    py::class_<SmoothDielectric, Bsdf, std::shared_ptr<SmoothDielectric>>(
        m, "SmoothDielectric", "A smooth dielectric boundary, index eta below its surface; its mirror reflection times "
        "reflection_tint, its refraction times transmission_tint.")
        .def(py::init([](double eta, const Array& reflection_tint, const Array& transmission_tint) {
                 return std::make_shared<SmoothDielectric>(eta, rgb(reflection_tint, "SmoothDielectric: reflection_tint"),
                                                           rgb(transmission_tint, "SmoothDielectric: transmission_tint"));
             }),
             py::arg("eta"), py::arg("reflection_tint") = py::make_tuple(1.0, 1.0, 1.0), py::arg("transmission_tint") = py::make_tuple(1.0, 1.0, 1.0))
        .def_property_readonly("reflection_tint", [](const SmoothDielectric& b) { return rgb_tuple(b.reflection_tint()); })
        .def_property_readonly("transmission_tint", [](const SmoothDielectric& b) { return rgb_tuple(b.transmission_tint()); });
    py::class_<RoughDielectric, Bsdf, std::shared_ptr<RoughDielectric>>(
        m, "RoughDielectric",
        "A rough dielectric boundary (GGX reflection and transmission), index eta below its surface. As Cycles' glass: "
        "height_correlated (its shadowing), scale_radiance=False (transmitted light carried without the radiance's "
        "(n_o / n_i)^2: the same through a closed solid, Cycles' through an open sheet), multiscatter (Multiscatter GGX: "
        "the lobe over the single-scattering glass's directional albedo from the side of the view). The defaults are "
        "Mitsuba 3's roughdielectric. Tinted as Cycles tints glass: the reflected branch times reflection_tint, the "
        "transmitted times transmission_tint (Multiscatter GGX's light put back with the transmission tint's repeated "
        "bounces).")
        .def(py::init([](double eta, double ax, double ay, bool multiscatter, bool height_correlated, bool scale_radiance,
                         const Array& reflection_tint, const Array& transmission_tint) {
                 return std::make_shared<RoughDielectric>(eta, ax, ay, multiscatter, height_correlated, scale_radiance,
                                                          rgb(reflection_tint, "RoughDielectric: reflection_tint"),
                                                          rgb(transmission_tint, "RoughDielectric: transmission_tint"));
             }),
             py::arg("eta"), py::arg("alpha_x"), py::arg("alpha_y"), py::arg("multiscatter") = false,
             py::arg("height_correlated") = false, py::arg("scale_radiance") = true, py::arg("reflection_tint") = py::make_tuple(1.0, 1.0, 1.0),
             py::arg("transmission_tint") = py::make_tuple(1.0, 1.0, 1.0))
        .def_property_readonly("reflection_tint", [](const RoughDielectric& b) { return rgb_tuple(b.reflection_tint()); })
        .def_property_readonly("transmission_tint", [](const RoughDielectric& b) { return rgb_tuple(b.transmission_tint()); })
        .def_property_readonly("multiscatter", &RoughDielectric::multiscatter)
        .def_property_readonly("height_correlated", &RoughDielectric::height_correlated)
        .def_property_readonly("scale_radiance", &RoughDielectric::scale_radiance)
        .def_static("single_scattering_albedo", [](double eta, double alpha, bool inside, bool height_correlated, double mu) {
                 return RoughDielectric::single_scattering_albedo(GgxDistribution{alpha, alpha}, inside ? eta : 1.0, inside ? 1.0 : eta, height_correlated, mu);
             }, py::arg("eta"), py::arg("alpha"), py::arg("inside"), py::arg("height_correlated"), py::arg("mu"),
             "E(mu) of the single-scattering glass (reflected plus transmitted energy) viewed from outside or inside.");

    py::class_<Emission>(m, "Emission", "Uniform emitted radiance over the front (or both) sides.")
        .def(py::init([](const Array& radiance, bool two_sided) { return Emission(rgb(radiance, "Emission: radiance"), two_sided); }),
             py::arg("radiance"), py::arg("two_sided") = false)
        .def("eval",
             [](const Emission& e, const Array& w) {
                 const size_t n = vectors(w, "w");
                 py::array_t<double> out({py::ssize_t(n), py::ssize_t(3)});
                 for (size_t i = 0; i < n; ++i) put(out.mutable_data() + 3 * i, e.eval(at(w, i)));
                 return out;
             },
             py::arg("w"))
        .def("pdf",
             [](const Emission& e, const Array& w) {
                 const size_t n = vectors(w, "w");
                 py::array_t<double> out(static_cast<py::ssize_t>(n));
                 for (size_t i = 0; i < n; ++i) out.mutable_data()[i] = e.pdf(at(w, i));
                 return out;
             },
             py::arg("w"))
        .def("sample",
             [](const Emission& e, const Array& u) {
                 const size_t n = vectors(u, "u");
                 py::array_t<double> w({py::ssize_t(n), py::ssize_t(3)}), pdf(static_cast<py::ssize_t>(n));
                 for (size_t i = 0; i < n; ++i) {
                     const Vec3 r = at(u, i);
                     Vec3 d;
                     double p = 0;
                     if (!e.sample(r.x, r.y, r.z, d, p)) d = {0, 0, 0}, p = 0;
                     put(w.mutable_data() + 3 * i, d);
                     pdf.mutable_data()[i] = p;
                 }
                 return py::make_tuple(w, pdf);
             },
             py::arg("u"), "Emission directions (cosine-weighted) and their density.");
}

}  // namespace bsgi::bindings
