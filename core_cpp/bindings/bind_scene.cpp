#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include "bindings.h"
#include "bsgi/disk_patch.h"
#include "bsgi/normal_map.h"
#include "bsgi/radiance.h"
#include "bsgi/sides.h"
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

Vec3 rgb(const Array& a, const std::string& what) {
    if (a.size() != 3) throw std::invalid_argument(what + " must have 3 values");
    return {a.data()[0], a.data()[1], a.data()[2]};
}

py::array_t<double> vec(const Vec3& v) { return py::array_t<double>(3, &v.x); }

using Image = py::array_t<float, py::array::c_style | py::array::forcecast>;

// An (height, width, 3) array over the surface's (u, v): rows along v, columns along u.
std::shared_ptr<const Texture> texture(const Image& a, const std::string& what, bool at_most_one) {
    if (a.ndim() != 3 || a.shape(2) != 3) throw std::invalid_argument(what + " must be an array of shape (height, width, 3)");
    return std::make_shared<Texture>(int(a.shape(1)), int(a.shape(0)), std::vector<float>(a.data(), a.data() + a.size()), what,
                                     at_most_one);
}

py::object image(const std::shared_ptr<const Texture>& t) {
    if (!t) return py::none();
    py::array_t<float> out({py::ssize_t(t->height()), py::ssize_t(t->width()), py::ssize_t(3)});
    std::copy(t->rgb().begin(), t->rgb().end(), out.mutable_data());
    return std::move(out);
}

Material material(const std::string& name, const Array& albedo, const Array& emission, std::shared_ptr<const Bsdf> bsdf) {
    return {rgb(albedo, "surface '" + name + "': albedo"), rgb(emission, "surface '" + name + "': emission"), std::move(bsdf)};
}

// One of surface i's options, as Scene.set_... set it.
template <int SurfaceOptions::*option>
int surface_option(const Scene& s, size_t i) {
    if (i >= s.size()) throw py::index_error("no surface " + std::to_string(i));
    return s[i].options.*option;
}

SurfaceOptions options(const std::string& name, const std::string& representation, int spatial, int angular) {
    SurfaceOptions o;
    if (representation == "auto") o.representation = Representation::Auto;
    else if (representation == "diffuse") o.representation = Representation::Diffuse;
    else if (representation == "glossy") o.representation = Representation::Glossy;
    else if (representation == "decomposed") o.representation = Representation::Decomposed;
    else throw std::invalid_argument("surface '" + name + "': representation must be 'auto', 'diffuse', 'glossy' or 'decomposed', got '" +
                                     representation + "'");
    o.spatial_coeffs = spatial;
    o.angular_coeffs = angular;
    return o;
}

const char* phase_name(SolveSteps::Phase p) {
    switch (p) {
        case SolveSteps::Phase::Direct: return "direct";
        case SolveSteps::Phase::Bounce: return "bounce";
        case SolveSteps::Phase::Final: return "final";
        case SolveSteps::Phase::Regather: return "regather";
        case SolveSteps::Phase::LateBounce: return "late bounce";
        case SolveSteps::Phase::EstimateChecks: return "estimate checks";
        case SolveSteps::Phase::EstimateInput: return "estimate input";
    }
    return "";
}

SolveSteps::Phase phase_of(const std::string& name) {
    if (name == "direct") return SolveSteps::Phase::Direct;
    if (name == "bounce") return SolveSteps::Phase::Bounce;
    if (name == "final") return SolveSteps::Phase::Final;
    if (name == "regather") return SolveSteps::Phase::Regather;
    if (name == "late bounce") return SolveSteps::Phase::LateBounce;
    if (name == "estimate checks") return SolveSteps::Phase::EstimateChecks;
    if (name == "estimate input") return SolveSteps::Phase::EstimateInput;
    throw std::invalid_argument("solve phase must be 'direct', 'bounce', 'late bounce', 'final', 'regather', 'estimate checks' or "
                                "'estimate input', got '" + name + "'");
}

// Sides travel to Python as (front solved, back solved, why, why, encloses its emission) per surface.
py::list sides_to_list(const std::vector<SurfaceSides>& sides) {
    py::list out;
    for (const SurfaceSides& s : sides) out.append(py::make_tuple(s.live[0], s.live[1], s.why[0], s.why[1], s.encloses_emission));
    return out;
}

std::optional<std::vector<SurfaceSides>> sides_from_list(const std::optional<py::list>& sides) {
    if (!sides) return std::nullopt;
    std::vector<SurfaceSides> out;
    for (const auto& item : *sides) {
        const auto t = item.cast<std::tuple<bool, bool, std::string, std::string, bool>>();
        out.push_back({{std::get<0>(t), std::get<1>(t)}, {std::get<2>(t), std::get<3>(t)}, std::get<4>(t)});
    }
    return out;
}

// A sides probe with its own rays' scene (a worker's part of the probe).
struct OwnedSidesProbe {
    RayCaster caster;
    SidesProbe probe;
    OwnedSidesProbe(const Scene& scene, const SolverSettings& settings, int part, int parts)
        : caster(ray_caster_of(scene)), probe(scene, caster, settings, part, parts) {}
};

const char* kind_name(Representation r) {
    return r == Representation::Glossy ? "glossy" : (r == Representation::Decomposed ? "decomposed" : "diffuse");
}

}  // namespace

void bind_scene(py::module_& m) {
    py::register_exception<Cancelled>(m, "SolveCancelled", PyExc_RuntimeError);

    py::class_<Scene>(m, "Scene", "Surfaces with their materials (Lambertian albedo or a BSDF) and emission.")
        .def(py::init<>())
        .def(
            "add_bilinear_patch",
            [](Scene& s, const std::string& name, const Array& corners, const Array& albedo, const Array& emission,
               bool receiver, bool occluder, std::shared_ptr<const Bsdf> bsdf, const std::string& representation,
               int spatial_coeffs, int angular_coeffs) {
                auto p = points(corners, 4, ("surface '" + name + "'").c_str());
                return s.add(std::make_shared<BilinearPatch>(name, p[0], p[1], p[2], p[3]),
                             material(name, albedo, emission, std::move(bsdf)), receiver, occluder,
                             options(name, representation, spatial_coeffs, angular_coeffs));
            },
            py::arg("name"), py::arg("corners"), py::arg("albedo"), py::arg("emission"), py::arg("receiver") = true,
            py::arg("occluder") = true, py::arg("bsdf") = nullptr, py::arg("representation") = "auto",
            py::arg("spatial_coeffs") = 0, py::arg("angular_coeffs") = 0,
            "A quad (p00, p10, p11, p01), front where (p10 - p00) x (p01 - p00) points. Without a BSDF it is "
            "Lambertian with `albedo`; representation 'auto' lets the solver choose 2D or 4D, or force "
            "'diffuse' / 'glossy'; coefficient counts 0 are chosen by the solver.")
        .def(
            "add_triangle",
            [](Scene& s, const std::string& name, const Array& corners, const Array& albedo, const Array& emission,
               bool receiver, bool occluder, std::shared_ptr<const Bsdf> bsdf, const std::string& representation,
               int spatial_coeffs, int angular_coeffs) {
                auto p = points(corners, 3, ("surface '" + name + "'").c_str());
                return s.add(std::make_shared<TrianglePatch>(name, p[0], p[1], p[2]), material(name, albedo, emission, std::move(bsdf)),
                             receiver, occluder, options(name, representation, spatial_coeffs, angular_coeffs));
            },
            py::arg("name"), py::arg("corners"), py::arg("albedo"), py::arg("emission"), py::arg("receiver") = true,
            py::arg("occluder") = true, py::arg("bsdf") = nullptr, py::arg("representation") = "auto",
            py::arg("spatial_coeffs") = 0, py::arg("angular_coeffs") = 0)
        .def(
            "add_disk",
            [](Scene& s, const std::string& name, const Array& center, const Array& axis_a, const Array& axis_b,
               const Array& albedo, const Array& emission, bool receiver, bool occluder, std::shared_ptr<const Bsdf> bsdf,
               const std::string& representation, int spatial_coeffs, int angular_coeffs) {
                return s.add(std::make_shared<DiskPatch>(name, rgb(center, "surface '" + name + "': center"), rgb(axis_a, "surface '" + name + "': axis_a"),
                                                        rgb(axis_b, "surface '" + name + "': axis_b")),
                             material(name, albedo, emission, std::move(bsdf)), receiver, occluder,
                             options(name, representation, spatial_coeffs, angular_coeffs));
            },
            py::arg("name"), py::arg("center"), py::arg("axis_a"), py::arg("axis_b"), py::arg("albedo"), py::arg("emission"),
            py::arg("receiver") = true, py::arg("occluder") = true, py::arg("bsdf") = nullptr,
            py::arg("representation") = "auto", py::arg("spatial_coeffs") = 0, py::arg("angular_coeffs") = 0,
            "A disc or ellipse c + u (cos(2 pi v) a + sin(2 pi v) b), front along a x b (disk and ellipse area lights).")
        .def(
            "add_surface",
            [](Scene& s, std::shared_ptr<Surface> surface, const Array& albedo, const Array& emission, bool receiver,
               bool occluder, std::shared_ptr<const Bsdf> bsdf, const std::string& representation, int spatial_coeffs,
               int angular_coeffs, std::optional<double> thin_glass, bool one_interface, std::optional<Array> shadow,
               std::optional<Array> transmission_tint, std::optional<Array> reflection_tint) {
                const std::string name = surface ? surface->name() : "";
                Material m = material(name, albedo, emission, std::move(bsdf));
                // A grey (one number) or RGB colour of the pane's.
                auto colour = [&](const Array& a, const char* what) -> Vec3 {
                    if (a.ndim() == 0) return Vec3{1, 1, 1} * a.data()[0];
                    return rgb(a, "surface '" + name + "': " + what);
                };
                if (thin_glass) {
                    ThinGlass glass{*thin_glass, one_interface};
                    if (shadow) glass.shadow = colour(*shadow, "shadow_transmittance");
                    if (transmission_tint) glass.transmission_tint = colour(*transmission_tint, "transmission_tint");
                    if (reflection_tint) glass.reflection_tint = colour(*reflection_tint, "reflection_tint");
                    m.thin_glass = glass;
                } else if (one_interface || shadow || transmission_tint || reflection_tint) {
                    throw std::invalid_argument("surface '" + name + "': one_interface, shadow_transmittance and the tints are "
                                                "for thin glass (give thin_glass)");
                }
                return s.add(std::move(surface), m, receiver, occluder, options(name, representation, spatial_coeffs, angular_coeffs));
            },
            py::arg("surface"), py::arg("albedo"), py::arg("emission"), py::arg("receiver") = true, py::arg("occluder") = true,
            py::arg("bsdf") = nullptr, py::arg("representation") = "auto", py::arg("spatial_coeffs") = 0,
            py::arg("angular_coeffs") = 0, py::arg("thin_glass") = py::none(), py::arg("one_interface") = false,
            py::arg("shadow_transmittance") = py::none(), py::arg("transmission_tint") = py::none(),
            py::arg("reflection_tint") = py::none(),
            "Adds any bsgi surface (NurbsSurface, MeshChart, patches); the scene shares it. thin_glass=eta makes it a "
            "window pane of smooth glass of that index: rays pass straight through it with the thin sheet's Fresnel "
            "transmittance (one_interface: one face of a thin closed slab, 1 - R per crossing) times "
            "transmission_tint, it reflects specularly (times reflection_tint) and gets no spline (not a receiver); "
            "the tints (RGB or one grey, in [0, 1]) per crossing, as Cycles tints each glass event. "
            "shadow_transmittance (RGB or grey): what visibility rays get instead of the Fresnel factor and the tint "
            "(Cycles' Light Path trick: the Transparent BSDF's colour).")
        .def(
            "is_thin_glass", [](const Scene& s, size_t i) {
                if (i >= s.size()) throw py::index_error("no surface " + std::to_string(i));
                return bool(s[i].material.thin_glass);
            },
            py::arg("index"))
        .def("set_two_sided_emission", &Scene::set_two_sided_emission, py::arg("index"), py::arg("two_sided") = true,
             "Makes emitter `index` emit from its back side too (Cycles' Emission shader on a mesh; its area "
             "lights emit from the front only).")
        .def("set_spatial_coeffs", &Scene::set_spatial_coeffs, py::arg("index"), py::arg("spatial_coeffs"),
             "Spatial coefficients per direction of surface `index` (0: from the settings and its size).")
        .def("spatial_coeffs", &surface_option<&SurfaceOptions::spatial_coeffs>, py::arg("index"),
             "The spatial coefficients per direction set on surface `index` (0: automatic).")
        .def("set_integration_factor", &Scene::set_integration_factor, py::arg("index"), py::arg("factor"),
             "Times the final gather's integration nodes per axis for surface `index` (1: the settings').")
        .def("integration_factor", &surface_option<&SurfaceOptions::integration_factor>, py::arg("index"),
             "The factor on the final gather's integration nodes set on surface `index` (1: the settings').")
        .def_readonly_static("MAX_INTEGRATION_FACTOR", &Scene::kMaxIntegrationFactor,
                             "The largest factor set_integration_factor takes.")
        .def_property(
            "world_radiance", [](const Scene& s) { return vec(s.world_radiance()); },
            [](Scene& s, const Array& radiance) { s.set_world_radiance(rgb(radiance, "world_radiance")); },
            "RGB radiance arriving from every direction no occluder blocks (a constant world background; "
            "default black).")
        .def_property(
            "world_map",
            [](const Scene& s) -> py::object {
                const EnvironmentMap* map = s.world_map();
                if (!map) return py::none();
                py::array_t<double> out({map->height(), map->width(), 3});
                std::copy(map->pixels().begin(), map->pixels().end(), out.mutable_data());
                return std::move(out);
            },
            [](Scene& s, const py::object& image) {
                if (image.is_none()) return s.set_world_map(nullptr);
                const Array a = Array::ensure(image);
                if (!a || a.ndim() != 3 || a.shape(2) != 3)
                    throw std::invalid_argument("world map: expected an image of shape (height, width, 3)");
                std::vector<double> rgb(a.data(), a.data() + a.size());
                auto map = std::make_shared<const EnvironmentMap>(int(a.shape(0)), int(a.shape(1)), std::move(rgb));
                s.set_world_map(std::move(map));
            },
            "RGB radiance arriving from each direction no occluder blocks, as an equirectangular image (height, "
            "width, 3) in Cycles' Environment Texture layout: row 0 at the zenith (+Z), azimuth atan2(y, x) = "
            "pi (1 - 2 u) at column centre u = (c + 1/2) / width (+X at the centre). Replaces world_radiance "
            "(and setting world_radiance removes it); None: no map.")
        .def(
            "set_spot_cone",
            [](Scene& s, size_t i, const Array& axis, double spot_size, double blend) {
                if (i >= s.size()) throw py::index_error("set_spot_cone: no surface " + std::to_string(i));
                s.set_spot_cone(i, rgb(axis, "spot light '" + s[i].surface->name() + "': axis"), spot_size, blend);
            },
            py::arg("index"), py::arg("axis"), py::arg("spot_size"), py::arg("blend") = 0.0,
            "Limits emitter `index`'s light to a cone of full angle `spot_size` (radians) around `axis`, "
            "softened over the fraction `blend` of it: Blender's spot light (Cycles' smoothstep falloff).")
        .def(
            "set_albedo_texture",
            [](Scene& s, size_t i, const Image& albedo) {
                if (i >= s.size()) throw py::index_error("set_albedo_texture: no surface " + std::to_string(i));
                s.set_albedo_texture(i, texture(albedo, "surface '" + s[i].surface->name() + "': albedo texture", true));
            },
            py::arg("index"), py::arg("albedo"),
            "Gives surface `index` a spatially varying albedo: an (height, width, 3) image over its (u, v) in [0, 1]^2 "
            "(columns along u, rows along v, row 0 at v = 0; bilinear), values in [0, 1]. It colours a Lambertian "
            "surface or the diffuse base of a decomposed one: the spline holds irradiance / pi and the outgoing "
            "radiance is albedo(u, v) times it.")
        .def(
            "set_normal_texture",
            [](Scene& s, size_t i, const Image& normals, bool bump_correction) {
                if (i >= s.size()) throw py::index_error("set_normal_texture: no surface " + std::to_string(i));
                const std::string what = "surface '" + s[i].surface->name() + "': normal map";
                if (normals.ndim() != 3 || normals.shape(2) != 3)
                    throw std::invalid_argument(what + " must be an array of shape (height, width, 3)");
                auto map = normal_map(*s[i].surface, int(normals.shape(1)), int(normals.shape(0)),
                                      std::vector<float>(normals.data(), normals.data() + normals.size()), what);
                s.set_normal_texture(i, std::move(map), bump_correction);
            },
            py::arg("index"), py::arg("normals"), py::arg("bump_correction") = true,
            "Bumps the shading normal of Lambertian surface `index`: an (height, width, 3) image of world-space "
            "normals over its (u, v), laid out as for set_albedo_texture (a Normal Map or Bump node's normals). "
            "The surface is then solved as a BumpedLambert: a 4D spline over its bumped normal, read where it is "
            "seen at the normal the map gives there. bump_correction: the material's Bump Map Correction.")
        .def(
            "set_specular_texture",
            [](Scene& s, size_t i, const Image& specular) {
                if (i >= s.size()) throw py::index_error("set_specular_texture: no surface " + std::to_string(i));
                s.set_specular_texture(i, texture(specular, "surface '" + s[i].surface->name() + "': specular texture", true));
            },
            py::arg("index"), py::arg("specular"),
            "Gives surface `index` (GGX reflection) a spatially varying f0 (a metal's colour): an (height, width, 3) "
            "image laid out as for set_albedo_texture, values in [0, 1]. Schlick's Fresnel is affine in f0: the solve "
            "keeps the radiance at f0 = 1 (upper, lower) and at f0 = 0 (tint_zero, lower_tint_zero) and the outgoing "
            "radiance is specular(u, v) times the first plus (1 - specular(u, v)) times the second.")
        .def(
            "set_emission_texture",
            [](Scene& s, size_t i, const Image& emission) {
                if (i >= s.size()) throw py::index_error("set_emission_texture: no surface " + std::to_string(i));
                s.set_emission_texture(i, texture(emission, "surface '" + s[i].surface->name() + "': emission texture", false));
            },
            py::arg("index"), py::arg("emission"),
            "Gives surface `index` a spatially varying emitted radiance (front side): an (height, width, 3) image over "
            "its (u, v) laid out as for set_albedo_texture, values >= 0. It replaces the constant emission.")
        .def(
            "add_distant_light",
            [](Scene& s, const std::string& name, const Array& direction, const Array& irradiance, double angle) {
                const std::string what = "distant light '" + name + "': ";
                s.add_distant_light({name, rgb(direction, what + "direction"), rgb(irradiance, what + "irradiance"), angle});
            },
            py::arg("name"), py::arg("direction"), py::arg("irradiance"), py::arg("angle") = 0.0,
            "A light at infinity (a sun): RGB `irradiance` on a surface facing it, from a disc of angular diameter "
            "`angle` (radians) around `direction` (towards the light); occluders cast its shadows.")
        .def_property_readonly("distant_lights", [](const Scene& s) {
            py::list out;
            for (const DistantLight& l : s.distant_lights()) {
                py::dict d;
                d["name"] = l.name, d["direction"] = vec(l.direction), d["irradiance"] = vec(l.irradiance);
                d["angle"] = l.angle;
                out.append(d);
            }
            return out;
        })
        .def("__len__", &Scene::size)
        .def(
            "surface",
            [](const Scene& s, size_t i) {
                if (i >= s.size()) throw py::index_error("surface index " + std::to_string(i) + " out of range");
                // Surfaces have no mutators in Python: sharing the scene's own is safe.
                return std::const_pointer_cast<Surface>(s[i].surface);
            },
            py::arg("i"), "Surface i as the scene holds it (e.g. for a RayCaster whose ids are scene indices).")
        .def("name", [](const Scene& s, size_t i) {
            if (i >= s.size()) throw py::index_error("no surface " + std::to_string(i));
            return s[i].surface->name();
        })
        .def("area", [](const Scene& s, size_t i) {
            if (i >= s.size()) throw py::index_error("no surface " + std::to_string(i));
            return s[i].surface->area();
        })
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

    py::class_<SolverSettings>(m, "SolverSettings", "Knots, degrees, integration nodes and bounces of a solve (see solver.h).")
        .def(py::init<>())
        .def_static("preset", &SolverSettings::preset, py::arg("name"), "Settings of the 'draft', 'preview' or 'final' preset.")
        .def_readwrite("spatial_coeffs", &SolverSettings::spatial_coeffs)
        .def_readwrite("spatial_degree", &SolverSettings::spatial_degree)
        .def_readwrite("epsilon", &SolverSettings::epsilon)
        .def_readwrite("coeffs_from_size", &SolverSettings::coeffs_from_size)
        .def_readwrite("spatial_coeffs_min", &SolverSettings::spatial_coeffs_min)
        .def_readwrite("detail_tolerance", &SolverSettings::detail_tolerance)
        .def_readwrite("detail_density_max", &SolverSettings::detail_density_max)
        .def_readwrite("adaptive_knots", &SolverSettings::adaptive_knots)
        .def_readwrite("hidden_nodes_to_contact", &SolverSettings::hidden_nodes_to_contact)
        .def_readwrite("discontinuity_knots", &SolverSettings::discontinuity_knots)
        .def_readwrite("near_contact_knots", &SolverSettings::near_contact_knots)
        .def_readwrite("knot_detail_share", &SolverSettings::knot_detail_share)
        .def_readwrite("split_crossings", &SolverSettings::split_crossings)
        .def_readwrite("distant_support_means", &SolverSettings::distant_support_means)
        .def_readwrite("sharpen_fit", &SolverSettings::sharpen_fit)
        .def_readwrite("angular_degree", &SolverSettings::angular_degree)
        .def_readwrite("angular_delta", &SolverSettings::angular_delta)
        .def_readwrite("angular_resolution", &SolverSettings::angular_resolution)
        .def_readwrite("angular_albedo_tolerance", &SolverSettings::angular_albedo_tolerance)
        .def_readwrite("angular_coeffs_min", &SolverSettings::angular_coeffs_min)
        .def_readwrite("angular_coeffs_max", &SolverSettings::angular_coeffs_max)
        .def_readwrite("emitter_coeffs", &SolverSettings::emitter_coeffs)
        .def_readwrite("emitter_degree", &SolverSettings::emitter_degree)
        .def_readwrite("emitter_cell_ratio", &SolverSettings::emitter_cell_ratio)
        .def_readwrite("emitter_max_depth", &SolverSettings::emitter_max_depth)
        .def_readwrite("emitter_shadow_depth", &SolverSettings::emitter_shadow_depth)
        .def_readwrite("hemisphere_nodes_theta", &SolverSettings::hemisphere_nodes_theta)
        .def_readwrite("hemisphere_nodes_phi", &SolverSettings::hemisphere_nodes_phi)
        .def_readwrite("bsdf_samples", &SolverSettings::bsdf_samples)
        .def_readwrite("world_bright_factor", &SolverSettings::world_bright_factor)
        .def_readwrite("world_bright_samples", &SolverSettings::world_bright_samples)
        .def_readwrite("max_bounces", &SolverSettings::max_bounces)
        .def_readwrite("late_bounces_after", &SolverSettings::late_bounces_after)
        .def_readwrite("settle_factor", &SolverSettings::settle_factor)
        .def_readwrite("form_factors", &SolverSettings::form_factors)
        .def_readwrite("tolerance", &SolverSettings::tolerance)
        .def_readwrite("extrapolate", &SolverSettings::extrapolate)
        .def_readwrite("final_gather", &SolverSettings::final_gather)
        .def_readwrite("final_spatial_factor", &SolverSettings::final_spatial_factor)
        .def_readwrite("final_integration_factor", &SolverSettings::final_integration_factor)
        .def_readwrite("final_passes", &SolverSettings::final_passes)
        .def_readwrite("final_correction_bounces", &SolverSettings::final_correction_bounces)
        .def_readwrite("two_sided", &SolverSettings::two_sided)
        .def_readwrite("estimate_error", &SolverSettings::estimate_error)
        .def_readwrite("error_checks", &SolverSettings::error_checks)
        .def_readwrite("error_checks_seed", &SolverSettings::error_checks_seed)
        .def_readwrite("refine_to_error", &SolverSettings::refine_to_error)
        .def_readwrite("refine_passes", &SolverSettings::refine_passes)
        .def_readwrite("refine_factor", &SolverSettings::refine_factor)
        .def_readwrite("refine_seconds", &SolverSettings::refine_seconds)
        .def_readwrite("refine_cost", &SolverSettings::refine_cost)
        .def_readwrite("threads", &SolverSettings::threads)
        .def_readwrite("memory_budget_mb", &SolverSettings::memory_budget_mb)
        .def("__repr__", [](const SolverSettings& s) {
            return "SolverSettings(spatial_coeffs=" + std::to_string(s.spatial_coeffs) + ", max_bounces=" +
                   std::to_string(s.max_bounces) + ", final_gather=" + (s.final_gather ? "True" : "False") + ", ...)";
        });

    py::class_<Progress>(m, "Progress", "Progress of a solve: poll it from any thread, cancel() stops the solve.")
        .def(py::init<>())
        .def_property_readonly("fraction", &Progress::fraction)
        .def_property_readonly("stage", &Progress::stage)
        .def_property_readonly("cancelled", &Progress::cancelled)
        .def("cancel", &Progress::cancel)
        .def("begin_stage", &Progress::begin_stage, py::arg("name"), py::arg("index"), py::arg("count"), py::arg("total"),
             "Starts stage `index` of `count` equal parts of the whole, with `total` units of work.")
        .def("advance", &Progress::advance, py::arg("units"), "Counts `units` of the stage's work as done.")
        .def("begin_pass", &Progress::begin_pass, py::arg("label"),
             "Names the whole solve the following stages belong to (a refinement pass): stage reads 'label: stage' "
             "until an empty label.");

    py::class_<SurfaceRadiance>(m, "SurfaceRadiance",
                                "A surface's outgoing radiance: 2D spline (diffuse) or 4D over the hemisphere map "
                                "(glossy), a second spline for the back side (lower hemisphere) where it transmits or "
                                "where light reaches an opaque surface's back; decomposed surfaces have their 2D parts "
                                "apart (diffuse, lower_diffuse).")
        .def(py::init([](const std::string& kind, double disc_radius, const TensorSpline& upper,
                         std::optional<TensorSpline> lower, std::optional<TensorSpline> diffuse,
                         std::optional<TensorSpline> lower_diffuse, std::optional<Image> albedo,
                         std::optional<Image> emission, bool two_sided_emission, std::optional<Image> specular,
                         std::optional<TensorSpline> tint_zero, std::optional<TensorSpline> lower_tint_zero,
                         std::optional<Array> coat_share, std::optional<Array> coat_albedo, std::optional<Image> normals) {
                 const Representation r = kind == "glossy" ? Representation::Glossy
                                          : kind == "decomposed" ? Representation::Decomposed
                                          : kind == "diffuse" ? Representation::Diffuse
                                                              : Representation::Auto;
                 if (r == Representation::Auto)
                     throw std::invalid_argument("SurfaceRadiance: kind must be 'diffuse', 'glossy' or 'decomposed', got '" +
                                                 kind + "'");
                 const int dims = r == Representation::Diffuse ? 2 : 4;
                 auto rgb_of = [](const std::optional<TensorSpline>& s, int d) { return !s || (s->dims() == d && s->channels() == 3); };
                 if (!rgb_of(upper, dims) || !rgb_of(lower, dims) || !rgb_of(diffuse, 2) || !rgb_of(lower_diffuse, 2) ||
                     (r == Representation::Decomposed) != bool(diffuse) ||
                     (r == Representation::Decomposed && bool(lower) != bool(lower_diffuse)) ||
                     (r != Representation::Decomposed && lower_diffuse))
                     throw std::invalid_argument("SurfaceRadiance: a " + kind + " surface needs RGB splines of " +
                                                 std::to_string(dims) + " dimensions" +
                                                 (r == Representation::Decomposed
                                                      ? " and a 2D diffuse part (and one for the back side with lower)"
                                                      : ""));
                 if (albedo && r == Representation::Glossy && !normals)
                     throw std::invalid_argument("SurfaceRadiance: an albedo texture needs a diffuse or decomposed surface "
                                                 "(or a glossy one with normals)");
                 if (normals && r != Representation::Glossy)
                     throw std::invalid_argument("SurfaceRadiance: normals (a normal map) need a glossy surface (4D over the "
                                                 "bumped normal)");
                 SurfaceRadiance out{r, HemisphereMap(disc_radius), upper, std::move(lower), std::move(diffuse),
                                     std::move(lower_diffuse)};
                 if (albedo) out.albedo = texture(*albedo, "SurfaceRadiance: albedo", true);
                 if (normals) out.normals = texture(*normals, "SurfaceRadiance: normals", true);
                 if (emission) out.emission = texture(*emission, "SurfaceRadiance: emission", false);
                 if (specular && (r != Representation::Glossy || !tint_zero || !rgb_of(tint_zero, 4) ||
                                  !rgb_of(lower_tint_zero, 4) || bool(lower) != bool(lower_tint_zero)))
                     throw std::invalid_argument("SurfaceRadiance: a specular texture needs a glossy surface with "
                                                 "4D RGB tint_zero splines (and lower_tint_zero with lower)");
                 if (!specular && (tint_zero || lower_tint_zero))
                     throw std::invalid_argument("SurfaceRadiance: tint_zero splines need a specular texture");
                 if (specular) {
                     out.specular = texture(*specular, "SurfaceRadiance: specular", true);
                     out.tint_zero = std::move(tint_zero);
                     out.lower_tint_zero = std::move(lower_tint_zero);
                 }
                 out.two_sided_emission = two_sided_emission;
                 if (bool(coat_share) != bool(coat_albedo) || (coat_share && (!albedo || r != Representation::Decomposed)))
                     throw std::invalid_argument("SurfaceRadiance: a coat's base (coat_share with coat_albedo) needs an "
                                                 "albedo texture on a decomposed surface");
                 if (coat_share) {
                     if (coat_share->ndim() != 1) throw std::invalid_argument("SurfaceRadiance: coat_share must be 1D");
                     const double* e = coat_share->data();
                     out.coat = CoatedBase{std::make_shared<DirectionalAlbedo>(std::vector<double>(e, e + coat_share->shape(0))),
                                           rgb(*coat_albedo, "SurfaceRadiance: coat_albedo")};
                 }
                 return out;
             }),
             py::arg("kind"), py::arg("disc_radius"), py::arg("upper"), py::arg("lower") = std::nullopt,
             py::arg("diffuse") = std::nullopt, py::arg("lower_diffuse") = std::nullopt, py::arg("albedo") = std::nullopt,
             py::arg("emission") = std::nullopt, py::arg("two_sided_emission") = false, py::arg("specular") = std::nullopt,
             py::arg("tint_zero") = std::nullopt, py::arg("lower_tint_zero") = std::nullopt,
             py::arg("coat_share") = std::nullopt, py::arg("coat_albedo") = std::nullopt, py::arg("normals") = std::nullopt,
             "Rebuilds a solved surface's radiance (as a solution file stores it).")
        .def_property_readonly("normals", [](const SurfaceRadiance& r) { return image(r.normals); },
                               "A normal map's bumped normals in the surface's radiance frame, as (n + 1) / 2 "
                               "(height, width, 3), or None: the 4D splines are over the bumped normal.")
        .def_property_readonly("coat_share", [](const SurfaceRadiance& r) -> py::object {
                                   if (!r.coat) return py::none();
                                   const auto& t = r.coat->share->table();
                                   return py::array_t<double>(py::ssize_t(t.size()), t.data());
                               },
                               "An albedo texture under a layered coat: the coat's directional albedo E at "
                               "mu = (k / (n - 1))^2 (its texels show as T + E(mu_o) (coat_albedo - T)), or None.")
        .def_property_readonly("coat_albedo", [](const SurfaceRadiance& r) -> py::object {
                                   return r.coat ? py::object(vec(r.coat->albedo)) : py::none();
                               },
                               "The albedo at which the coat's S took its share of the base, or None.")
        .def(
            "coated_texels",
            [](const SurfaceRadiance& r, const Array& texels, const Array& mu) {
                if (!r.coat) throw std::invalid_argument("coated_texels: the surface has no albedo texture under a layered coat");
                if (texels.ndim() != 2 || texels.shape(1) != 3 || mu.ndim() != 1 || mu.shape(0) != texels.shape(0))
                    throw std::invalid_argument("coated_texels: texels must be (N, 3) and mu (N,)");
                py::array_t<double> out({texels.shape(0), py::ssize_t(3)});
                for (py::ssize_t i = 0; i < texels.shape(0); ++i) {
                    const double* t = texels.data() + 3 * i;
                    const Vec3 c = r.coat->texel({t[0], t[1], t[2]}, mu.data()[i]);
                    out.mutable_data()[3 * i] = c.x, out.mutable_data()[3 * i + 1] = c.y, out.mutable_data()[3 * i + 2] = c.z;
                }
                return out;
            },
            py::arg("texels"), py::arg("mu"),
            "Albedo texels (N, 3) as the surface shows them along directions of cosine mu (N,) (CoatedBase).")
        .def_property_readonly("albedo", [](const SurfaceRadiance& r) { return image(r.albedo); },
                               "The albedo texture (height, width, 3) multiplying the diffuse spline (irradiance / pi), or None.")
        .def_property_readonly("emission", [](const SurfaceRadiance& r) { return image(r.emission); },
                               "The emission texture (height, width, 3) added to the front side, or None (emission in the spline).")
        .def_property_readonly("specular", [](const SurfaceRadiance& r) { return image(r.specular); },
                               "The specular texture (height, width, 3): the GGX f0 over (u, v) blending upper (f0 = 1) "
                               "and tint_zero (f0 = 0), or None.")
        .def_readonly("tint_zero", &SurfaceRadiance::tint_zero, "With a specular texture: the front's radiance at f0 = 0.")
        .def_readonly("lower_tint_zero", &SurfaceRadiance::lower_tint_zero,
                      "With a specular texture: the back's radiance at f0 = 0, where the back side was solved.")
        .def_readonly("two_sided_emission", &SurfaceRadiance::two_sided_emission,
                      "Whether the emission texture leaves the back side too.")
        .def_property_readonly("kind", [](const SurfaceRadiance& r) { return kind_name(r.kind); })
        .def_readonly("upper", &SurfaceRadiance::upper)
        .def_readonly("lower", &SurfaceRadiance::lower)
        .def_readonly("diffuse", &SurfaceRadiance::diffuse)
        .def_readonly("lower_diffuse", &SurfaceRadiance::lower_diffuse)
        .def_property_readonly("disc_radius", [](const SurfaceRadiance& r) { return r.map.radius(); })
        .def(
            "evaluate",
            [](const SurfaceRadiance& r, const Array& uv, const Array& directions) {
                if (uv.ndim() != 2 || uv.shape(1) != 2 || directions.ndim() != 2 || directions.shape(1) != 3 ||
                    uv.shape(0) != directions.shape(0))
                    throw std::invalid_argument("evaluate: uv must be (N, 2) and directions (N, 3)");
                const size_t n = uv.shape(0);
                py::array_t<double> out({py::ssize_t(n), py::ssize_t(3)});
                const double* u = uv.data();
                const double* d = directions.data();
                double* o = out.mutable_data();
                {
                    py::gil_scoped_release release;
                    for (size_t i = 0; i < n; ++i) {
                        const Vec3 L = r.evaluate(u[2 * i], u[2 * i + 1], {d[3 * i], d[3 * i + 1], d[3 * i + 2]});
                        o[3 * i] = L.x, o[3 * i + 1] = L.y, o[3 * i + 2] = L.z;
                    }
                }
                return out;
            },
            py::arg("uv"), py::arg("directions"),
            "Radiance leaving (u, v) along local directions (frame (1)-(3): z the surface normal), (N, 3) each.");

    py::class_<Solution>(m, "Solution", py::dynamic_attr())
        // Both lists hold views into the solution, which they keep alive: no copy of every
        // surface's splines at each access (sol.surfaces[i] in a loop over 2,000 points copied
        // the rough glass's 4D splines 2,000 times, 5.4 s).
        .def_property_readonly("radiance", [](py::object self) {
            // The upper-hemisphere spline of each surface (2D or 4D), None for pure emitters.
            py::list out;
            for (const auto& r : self.cast<const Solution&>().radiance)
                out.append(r ? py::cast(&r->upper, py::return_value_policy::reference_internal, self) : py::none());
            return out;
        })
        .def_property_readonly("surfaces", [](py::object self) {
            py::list out;
            for (const auto& r : self.cast<const Solution&>().radiance)
                out.append(r ? py::cast(&*r, py::return_value_policy::reference_internal, self) : py::none());
            return out;
        })
        .def_property_readonly("reports", [](const Solution& s) {
            py::list out;
            for (const auto& r : s.reports) {
                py::dict d;
                d["name"] = r.name, d["representation"] = r.representation, d["shape"] = r.shape, d["reason"] = r.reason;
                d["estimated_error"] = r.estimated_error;
                py::dict parts;
                parts["fit"] = r.error_parts[0], parts["input"] = r.error_parts[1];
                parts["integration"] = r.error_parts[2], parts["tail"] = r.error_parts[3];
                d["error_parts"] = parts;
                out.append(d);
            }
            return out;
        })
        .def_property_readonly("stats", [](const Solution& s) {
            py::dict d;
            d["seconds_direct"] = s.stats.seconds_direct;
            d["seconds_indirect"] = s.stats.seconds_indirect;
            d["seconds_final"] = s.stats.seconds_final;
            d["bounces"] = s.stats.bounces;
            d["last_increment"] = s.stats.last_increment;
            d["estimated_error"] = s.stats.estimated_error;
            d["extrapolated"] = s.stats.extrapolated;
            d["coefficients"] = s.stats.coefficients;
            d["rays"] = s.stats.rays;
            d["bytes"] = s.stats.bytes;
            d["transport_terms"] = s.stats.transport_terms;
            d["seconds_estimate"] = s.stats.seconds_estimate;
            d["estimate_rays"] = s.stats.estimate_rays;
            d["final_rays"] = s.stats.final_rays;
            d["settled_nodes"] = s.stats.settled_nodes;
            return d;
        });

    m.def(
        "estimate_solve_bytes",
        [](const Scene& scene, const SolverSettings& settings, std::optional<py::list> sides) {
            const std::optional<std::vector<SurfaceSides>> probed = sides_from_list(sides);
            py::gil_scoped_release release;
            return estimate_solve_bytes(scene, settings, probed ? &*probed : nullptr);
        },
        py::arg("scene"), py::arg("settings"), py::arg("sides") = py::none(),
        "Bytes the solve allocates at its peak. `sides`: probed already (probe_sides()[0], SolveSteps.sides) for a "
        "solve given them, not probed again; none: probed here (the probe's peak counted). Releases the GIL.");
    m.def(
        "probe_sides",
        [](const Scene& scene, const SolverSettings& settings) {
            size_t bytes = 0;
            std::vector<SurfaceSides> sides;
            {
                py::gil_scoped_release release;
                sides = probe_sides(scene, settings, &bytes);
            }
            return py::make_tuple(sides_to_list(sides), bytes);
        },
        py::arg("scene"), py::arg("settings"),
        "The sides probe alone (bsgi/sides.h): per surface (front solved, back solved, why, why, encloses its emission) "
        "as SolveSteps.sides, and the bytes the probe held at its peak. Releases the GIL.");
    py::class_<OwnedSidesProbe>(m, "SidesProbe",
                                "The sides probe in parts (bsgi/sides.h), for a solve split over workers: part `part` "
                                "of `parts` probes its surfaces' cells (SidesProbe.owner) and the parts exchange the "
                                "cells they light (settle) until none lights more; then each one's sides() are right "
                                "for the surfaces it owns. With its own rays' scene of `scene`.")
        .def(py::init([](const Scene& scene, const SolverSettings& settings, int part, int parts) {
                 py::gil_scoped_release release;
                 return std::make_unique<OwnedSidesProbe>(scene, settings, part, parts);
             }),
             py::arg("scene"), py::arg("settings"), py::arg("part") = 0, py::arg("parts") = 1, py::keep_alive<1, 2>(),
             "Probes the views of its part's cells (on settings.threads threads). Releases the GIL.")
        .def_static("owner", &SidesProbe::owner, py::arg("surface"), py::arg("parts"), py::arg("surfaces"),
                    "The part of `parts` that probes surface `surface` of a scene of `surfaces`.")
        .def(
            "lit_directly",
            [](OwnedSidesProbe& self) {
                const std::vector<uint32_t> lit = self.probe.lit_directly();
                return py::array_t<uint32_t>(py::ssize_t(lit.size()), lit.data());
            },
            "Its cells lit directly or emitting (ids as settle's), not returned before.")
        .def(
            "settle",
            [](OwnedSidesProbe& self, py::array_t<uint32_t, py::array::c_style | py::array::forcecast> lit_elsewhere) {
                const std::vector<uint32_t> cells(lit_elsewhere.data(), lit_elsewhere.data() + lit_elsewhere.size());
                std::vector<uint32_t> lit;
                {
                    py::gil_scoped_release release;
                    lit = self.probe.settle(cells);
                }
                return py::array_t<uint32_t>(py::ssize_t(lit.size()), lit.data());
            },
            py::arg("lit_elsewhere"),
            "Marks the cells other parts lit (ids (surface * 2 + side) * 36 + cell), settles its own cells and returns "
            "those it lit since the last call (of this or lit_directly). Releases the GIL.")
        .def("sides", [](const OwnedSidesProbe& self) { return sides_to_list(self.probe.sides()); },
             "Per surface as probe_sides()[0], right for the surfaces this part owns (and those not probed).")
        .def_property_readonly("peak_bytes", [](const OwnedSidesProbe& self) { return self.probe.peak_bytes(); },
                               "The bytes the probe has held at its peak.");
    m.def(
        "solve",
        [](const Scene& scene, const SolverSettings& settings, Progress& progress, std::optional<py::list> sides) {
            const std::optional<std::vector<SurfaceSides>> probed = sides_from_list(sides);
            py::gil_scoped_release release;
            return solve(scene, settings, progress, probed ? &*probed : nullptr);
        },
        py::arg("scene"), py::arg("settings"), py::arg("progress"), py::arg("sides") = py::none(),
        "Algorithm 1: direct light by the surface integral, indirect bounces by gathering. `sides`: probed already "
        "(probe_sides()[0], SolveSteps.sides), not probed again. Releases the GIL.");

    py::class_<SolveSteps>(m, "SolveSteps",
                           "Algorithm 1 in phases for a solve split over workers: each worker holds SolveSteps of the "
                           "same scene and settings (the same receivers and knots) and gathers groups of receivers.")
        .def(py::init([](const Scene& scene, const SolverSettings& settings, Progress& progress, std::optional<py::list> sides) {
                 const std::optional<std::vector<SurfaceSides>> probed = sides_from_list(sides);
                 py::gil_scoped_release release;
                 return std::make_unique<SolveSteps>(scene, settings, progress, probed ? &*probed : nullptr);
             }),
             py::arg("scene"), py::arg("settings"), py::arg("progress"), py::arg("sides") = py::none(), py::keep_alive<1, 2>(),
             "Probes the sides (or takes `sides`, another SolveSteps' of the scene and settings), plans the receivers "
             "and places their knots (the scene is kept alive with the steps). Releases the GIL.")
        .def_property_readonly(
            "sides",
            [](const SolveSteps& steps) { return sides_to_list(steps.sides()); },
            "Per surface: (front solved, back solved, why, why, encloses its emission), as the constructor takes them.")
        .def(
            "solve",
            [](SolveSteps& steps, Progress& progress, std::optional<py::function> runner) {
                if (!runner) {
                    py::gil_scoped_release release;
                    return steps.solve(progress);
                }
                // The runner gathers each phase wherever it likes (a Ray cluster): called with the GIL.
                SolveSteps::Runner run = [&runner](SolveSteps::Phase phase, const std::vector<double>& input,
                                                   const std::vector<size_t>& nodes, size_t& rays) {
                    py::gil_scoped_acquire acquire;
                    py::tuple result = (*runner)(phase_name(phase), py::array_t<double>(input.size(), input.data()), nodes);
                    if (result.size() != 2) throw std::invalid_argument("solve runner: must return (coefficients, rays)");
                    rays += result[1].cast<size_t>();
                    const Array out = Array::ensure(result[0]);
                    if (!out || out.ndim() != 1) throw std::invalid_argument("solve runner: coefficients must be a 1D array");
                    return std::vector<double>(out.data(), out.data() + out.size());
                };
                py::gil_scoped_release release;
                return steps.solve(progress, run);
            },
            py::arg("progress"), py::arg("runner") = py::none(),
            "The whole solve, once. runner(phase, input, nodes) -> (coefficients, rays), if given, gathers each phase "
            "('direct', 'bounce', 'late bounce', 'final', 'regather', and the error estimate's 'estimate checks' and 'estimate "
            "input') for all receivers, wherever it likes (called with the GIL); a receiver "
            "of 0 nodes has settled and does not gather (its coefficients are not read). The bookkeeping between phases "
            "stays here. Releases the GIL.")
        .def(
            "nodes",
            [](SolveSteps& steps, const std::string& phase, Progress& progress) {
                py::gil_scoped_release release;
                return steps.nodes(phase_of(phase), progress);
            },
            py::arg("phase"), py::arg("progress"),
            "Spatial nodes of each receiver of a phase (for the error estimate's passes, its checks).")
        .def(
            "gather",
            [](SolveSteps& steps, const std::string& phase, size_t begin, size_t end, const Array& input, Progress& progress,
               const std::vector<size_t>& settled, bool unpacked) {
                const SolveSteps::Phase p = phase_of(phase);
                size_t rays = 0;
                std::vector<double> out;
                {
                    // `input` stays alive (its caller holds it) and is read in place.
                    py::gil_scoped_release release;
                    out = steps.gather(p, begin, end, {input.data(), size_t(input.size())}, progress, rays, settled, unpacked);
                }
                return py::make_tuple(py::array_t<double>(out.size(), out.data()), rays);
            },
            py::arg("phase"), py::arg("begin"), py::arg("end"), py::arg("input"), py::arg("progress"),
            py::arg("settled") = std::vector<size_t>{}, py::arg("unpacked") = false,
            "The gather of a phase for receivers [begin, end) given all receivers' coefficients of the previous step "
            "(empty for 'direct', the increment L for 'bounce', the cumulative Le for 'final', the finals' Le of the "
            "final gather followed by the coarse Le it read for 'regather'; for the error estimate's passes, SolveSteps::gather "
            "in bsgi/solver.h says what): (their new "
            "coefficients, for 'regather' the correction the solve adds to the first final gather's, rays cast). `settled`: receivers of a bounce that do not gather (the runner's 0 nodes; their "
            "coefficients come back as they were). `unpacked`: these steps gathered a group of this phase from this very "
            "input already (a worker's earlier group), so their splines hold it and it is not unpacked again. Releases the "
            "GIL; raises SolveCancelled if progress is cancelled.");
}

}  // namespace bsgi::bindings
