// Surfaces (NURBS, mesh charts, patches) and the ray caster.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <type_traits>

#include "bindings.h"
#include "bsgi/mesh_chart.h"
#include "bsgi/nurbs_surface.h"
#include "bsgi/ray_caster.h"
#include "bsgi/split_piece.h"

namespace py = pybind11;

namespace bsgi::bindings {

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

// Checks a float array's trailing shape; returns the number of rows.
size_t rows(const Array& a, std::initializer_list<py::ssize_t> tail, const std::string& what) {
    const size_t nt = tail.size();
    bool ok = size_t(a.ndim()) == nt + 1;
    size_t k = 0;
    for (py::ssize_t t : tail) ok = ok && a.shape(1 + k++) == t;
    if (!ok) {
        std::string shape = "(N";
        for (py::ssize_t t : tail) shape += ", " + std::to_string(t);
        throw std::invalid_argument(what + " must have shape " + shape + ")");
    }
    return size_t(a.shape(0));
}

std::vector<double> flat(const Array& a) { return std::vector<double>(a.data(), a.data() + a.size()); }

py::array_t<double> empty(std::vector<py::ssize_t> shape) { return py::array_t<double>(shape); }

// (N, 2) parameters -> point, derivatives, frame per row.
py::dict evaluate_many(const Surface& s, const Array& uv) {
    const size_t n = rows(uv, {2}, "uv");
    auto p = empty({py::ssize_t(n), 3}), du = empty({py::ssize_t(n), 3}), dv = empty({py::ssize_t(n), 3});
    auto x = empty({py::ssize_t(n), 3}), y = empty({py::ssize_t(n), 3}), z = empty({py::ssize_t(n), 3});
    auto shading = empty({py::ssize_t(n), 3}), shading_x = empty({py::ssize_t(n), 3}), shading_y = empty({py::ssize_t(n), 3});
    auto jac = py::array_t<double>(py::ssize_t(n));
    double *pp = p.mutable_data(), *pdu = du.mutable_data(), *pdv = dv.mutable_data(), *px = x.mutable_data(),
           *py_ = y.mutable_data(), *pz = z.mutable_data(), *ps = shading.mutable_data(), *psx = shading_x.mutable_data(),
           *psy = shading_y.mutable_data(), *pj = jac.mutable_data();
    const double* in = uv.data();
    {
        py::gil_scoped_release release;
        auto put = [](double* dst, const Vec3& v) { dst[0] = v.x, dst[1] = v.y, dst[2] = v.z; };
        for (size_t i = 0; i < n; ++i) {
            const SurfacePoint sp = s.evaluate(in[2 * i], in[2 * i + 1]);
            put(pp + 3 * i, sp.p), put(pdu + 3 * i, sp.dpdu), put(pdv + 3 * i, sp.dpdv);
            put(px + 3 * i, sp.frame.x), put(py_ + 3 * i, sp.frame.y), put(pz + 3 * i, sp.frame.z);
            const Frame rf = radiance_frame(sp);
            put(ps + 3 * i, rf.z), put(psx + 3 * i, rf.x), put(psy + 3 * i, rf.y);
            pj[i] = sp.jacobian;
        }
    }
    py::dict d;
    d["position"] = p, d["dpdu"] = du, d["dpdv"] = dv, d["x"] = x, d["y"] = y, d["normal"] = z, d["shading_normal"] = shading, d["shading_x"] = shading_x,
    d["shading_y"] = shading_y,
    d["jacobian"] = jac;
    return d;
}

// Keeps the Python surfaces alive as long as the caster.
struct PyRayCaster {
    std::vector<std::shared_ptr<const Surface>> surfaces;
    std::unique_ptr<RayCaster> caster;
};

RayBatch batch(const Array& origins, const Array& directions, const std::optional<Array>& tnear,
               const std::optional<Array>& tfar) {
    RayBatch b;
    b.count = rows(origins, {3}, "origins");
    if (rows(directions, {3}, "directions") != b.count) throw std::invalid_argument("origins and directions differ in length");
    // Embree takes single-precision rays and refuses components beyond about 1.8e18.
    for (size_t i = 0; i < 3 * b.count; ++i)
        if (!(std::abs(origins.data()[i]) <= 1e18) || !(std::abs(directions.data()[i]) <= 1e18))
            throw std::invalid_argument("ray origins and directions must be finite and at most 1e18 in magnitude");
    b.origins = origins.data();
    b.directions = directions.data();
    if (tnear) {
        if (size_t(tnear->size()) != b.count) throw std::invalid_argument("tnear must have one value per ray");
        for (size_t i = 0; i < b.count; ++i)
            if (std::isnan(tnear->data()[i])) throw std::invalid_argument("tnear must not be NaN");
        b.tnear = tnear->data();
    }
    if (tfar) {
        if (size_t(tfar->size()) != b.count) throw std::invalid_argument("tfar must have one value per ray");
        for (size_t i = 0; i < b.count; ++i)
            if (std::isnan(tfar->data()[i])) throw std::invalid_argument("tfar must not be NaN");
        b.tfar = tfar->data();
    }
    return b;
}

// (N, 2) parameter pairs through f(x, y, out_x, out_y): a SplitPiece's maps between its (a, b)
// and its parent's (u, v).
template <typename F>
py::array_t<double> map_pairs(const Array& in, const char* what, F&& f) {
    const size_t n = rows(in, {2}, what);
    auto out = empty({py::ssize_t(n), 2});
    for (size_t i = 0; i < n; ++i) f(in.data()[2 * i], in.data()[2 * i + 1], out.mutable_data()[2 * i], out.mutable_data()[2 * i + 1]);
    return out;
}

// N rows of 3 as N points or vectors, the surface named where there are not N.
template <size_t N>
std::array<Vec3, N> corners(const std::string& name, const Array& a, const char* what) {
    if (rows(a, {3}, "surface '" + name + "': " + what) != N)
        throw std::invalid_argument("surface '" + name + "': " + std::to_string(N) + " " + what + " needed");
    std::array<Vec3, N> out;
    for (size_t i = 0; i < N; ++i) out[i] = {a.data()[3 * i], a.data()[3 * i + 1], a.data()[3 * i + 2]};
    return out;
}

}  // namespace

void bind_geometry(py::module_& m) {
    m.def(
        "blender_knots",
        [](int points, int order, bool endpoint, bool bezier, bool cyclic) {
            const NurbsDirection d{points, order, endpoint, bezier, cyclic};
            const std::vector<double> k = blender_knots(d);
            return py::make_tuple(py::array_t<double>(k.size(), k.data()), blender_range(d, k));
        },
        py::arg("points"), py::arg("order"), py::arg("endpoint") = false, py::arg("bezier") = false, py::arg("cyclic") = false,
        "Blender's knot vector for one NURBS direction (calcknots) and its evaluation range (a, b).");
    m.def(
        "blender_nurbs_problem",
        [](int points, int order, bool endpoint, bool bezier, bool cyclic) {
            return blender_nurbs_problem({points, order, endpoint, bezier, cyclic});
        },
        py::arg("points"), py::arg("order"), py::arg("endpoint") = false, py::arg("bezier") = false, py::arg("cyclic") = false,
        "Why Blender would draw nothing for this NURBS direction, or '' if it is valid.");

    py::class_<Surface, std::shared_ptr<Surface>>(m, "Surface", "A parametric surface s(u, v) on [0, 1]^2 (paper section 2.1).")
        .def_property_readonly("name", &Surface::name)
        .def_property_readonly("area", &Surface::area)
        .def_property_readonly("size", &Surface::size)
        .def_property_readonly("tessellation_is_exact", &Surface::tessellation_is_exact)
        .def("evaluate", &evaluate_many, py::arg("uv"),
             "Position, s_u, s_v, local frame (x, y, normal) of (1)-(3), the radiance frame (shading_x, shading_y, "
             "shading_normal: the frame but on smooth-shaded faces, where its normal is the interpolated one that the "
             "light's cosine and a glossy lobe read, and its splines' directions are in it) and |s_u x s_v| at (N, 2) "
             "parameters.")
        .def(
            "in_domain",
            [](const Surface& s, const Array& uv) {
                const size_t n = rows(uv, {2}, "uv");
                py::array_t<bool> out(static_cast<py::ssize_t>(n));
                for (size_t i = 0; i < n; ++i) out.mutable_data()[i] = s.in_domain(uv.data()[2 * i], uv.data()[2 * i + 1]);
                return out;
            },
            py::arg("uv"), "The parameter-domain mask chi of (8) at (N, 2) parameters.")
        .def("tessellate", [](const Surface& s, bool for_rays) {
            const Tessellation t = for_rays ? s.tessellate_for_rays() : s.tessellate();
            py::dict d;
            d["positions"] = py::array_t<double>({py::ssize_t(t.positions.size() / 3), py::ssize_t(3)}, t.positions.data());
            d["uvs"] = py::array_t<float>({py::ssize_t(t.uvs.size() / 2), py::ssize_t(2)}, t.uvs.data());
            d["triangles"] = py::array_t<uint32_t>({py::ssize_t(t.triangles.size() / 3), py::ssize_t(3)}, t.triangles.data());
            return d;
        }, py::arg("for_rays") = false, "Triangles with (u, v) per vertex; for_rays: the ray caster's (possibly lifted) ones.");

    py::class_<NurbsSurface, Surface, std::shared_ptr<NurbsSurface>>(
        m, "NurbsSurface", "A rational NURBS surface evaluated exactly as Blender does (knots by Blender's rule).")
        .def(py::init([](const std::string& name, const Array& points, int count_u, int count_v, int order_u, int order_v,
                         bool endpoint_u, bool endpoint_v, bool bezier_u, bool bezier_v, bool cyclic_u, bool cyclic_v,
                         int subdivisions, const std::string& front) {
                 if (points.ndim() != 2 || points.shape(1) != 4)
                     throw std::invalid_argument("surface '" + name + "': points must have shape (count_u * count_v, 4): x, y, z, weight");
                 if (front != "blender" && front != "su_x_sv")
                     throw std::invalid_argument("surface '" + name + "': front must be 'blender' or 'su_x_sv'");
                 return std::make_shared<NurbsSurface>(name, flat(points), NurbsDirection{count_u, order_u, endpoint_u, bezier_u, cyclic_u},
                                                       NurbsDirection{count_v, order_v, endpoint_v, bezier_v, cyclic_v}, subdivisions,
                                                       front == "blender" ? NurbsFront::Blender : NurbsFront::SuCrossSv);
             }),
             py::arg("name"), py::arg("points"), py::arg("count_u"), py::arg("count_v"), py::arg("order_u") = 4, py::arg("order_v") = 4,
             py::arg("endpoint_u") = false, py::arg("endpoint_v") = false, py::arg("bezier_u") = false, py::arg("bezier_v") = false,
             py::arg("cyclic_u") = false, py::arg("cyclic_v") = false, py::arg("subdivisions") = 0, py::arg("front") = "blender",
             "points: Blender's spline.points[].co, u fastest (x, y, z, weight). subdivisions: tessellation steps per knot "
             "span (0: automatic). front: 'blender' (the frame's z is Blender's face normal, -(s_u x s_v)) or 'su_x_sv' "
             "(paper (2) literally).")
        .def_property_readonly("knots_u", [](const NurbsSurface& s) { return py::array_t<double>(s.knots_u().size(), s.knots_u().data()); })
        .def_property_readonly("knots_v", [](const NurbsSurface& s) { return py::array_t<double>(s.knots_v().size(), s.knots_v().data()); })
        .def_property_readonly("range_u", &NurbsSurface::range_u)
        .def_property_readonly("range_v", &NurbsSurface::range_v)
        .def(
            "mixed_derivative",
            [](const NurbsSurface& s, double u, double v) {
                Vec3 p, su, sv, suv;
                s.derivatives(u, v, p, su, sv, suv);
                return py::make_tuple(suv.x, suv.y, suv.z);
            },
            py::arg("u"), py::arg("v"), "s_uv at one point.");

    py::class_<MeshChart, Surface, std::shared_ptr<MeshChart>>(
        m, "MeshChart", "A triangle mesh with a UV map as one surface; chi of (8) masks the area outside the UV triangles.")
        .def(py::init([](const std::string& name, const Array& positions, py::array_t<int64_t, py::array::c_style | py::array::forcecast> triangles,
                         const Array& corner_uvs, const std::optional<Array>& corner_normals) {
                 if (positions.ndim() != 2 || positions.shape(1) != 3)
                     throw std::invalid_argument("surface '" + name + "': positions must have shape (N, 3)");
                 if (triangles.ndim() != 2 || triangles.shape(1) != 3)
                     throw std::invalid_argument("surface '" + name + "': triangles must have shape (M, 3)");
                 std::vector<uint32_t> tris(triangles.size());
                 for (size_t i = 0; i < tris.size(); ++i) {
                     const int64_t t = triangles.data()[i];
                     if (t < 0 || t > int64_t(UINT32_MAX)) throw std::invalid_argument("surface '" + name + "': negative or huge vertex index");
                     tris[i] = uint32_t(t);
                 }
                 std::vector<double> uvs(corner_uvs.data(), corner_uvs.data() + corner_uvs.size());
                 const std::vector<double> normals = corner_normals ? flat(*corner_normals) : std::vector<double>{};
                 std::shared_ptr<MeshChart> chart;
                 {
                     py::gil_scoped_release release;
                     chart = std::make_shared<MeshChart>(name, flat(positions), std::move(tris), std::move(uvs), normals);
                 }
                 return chart;
             }),
             py::arg("name"), py::arg("positions"), py::arg("triangles"), py::arg("corner_uvs"), py::arg("corner_normals") = py::none(),
             "corner_uvs: (M, 3, 2) or (3M, 2), one UV per triangle corner, in [0, 1]^2. corner_normals: None (flat faces) "
             "or (M, 3, 3) / (3M, 3), one normal per triangle corner (smooth shading, interpolated as Cycles does).")
        .def_property_readonly("triangle_count", &MeshChart::triangle_count)
        .def_property_readonly("degenerate_uv_triangles", &MeshChart::degenerate_uv_triangles);

    py::class_<BilinearPatch, Surface, std::shared_ptr<BilinearPatch>>(m, "BilinearPatch", "Quads and parallelograms.")
        .def(py::init([](const std::string& name, const Array& c, const std::optional<Array>& normals) {
                 const std::array<Vec3, 4> p = corners<4>(name, c, "corners");
                 if (!normals) return std::make_shared<BilinearPatch>(name, p[0], p[1], p[2], p[3]);
                 return std::make_shared<BilinearPatch>(name, p[0], p[1], p[2], p[3], corners<4>(name, *normals, "normals"));
             }),
             py::arg("name"), py::arg("corners"), py::arg("normals") = py::none(),
             "corners p00, p10, p11, p01; normals: None (flat) or the corners' normals (smooth shading, interpolated "
             "bilinearly).");
    py::class_<TrianglePatch, Surface, std::shared_ptr<TrianglePatch>>(m, "TrianglePatch", "A triangle as the unit square with u = 0 collapsed.")
        .def(py::init([](const std::string& name, const Array& c, const std::optional<Array>& normals) {
                 const std::array<Vec3, 3> p = corners<3>(name, c, "corners");
                 if (!normals) return std::make_shared<TrianglePatch>(name, p[0], p[1], p[2]);
                 return std::make_shared<TrianglePatch>(name, p[0], p[1], p[2], corners<3>(name, *normals, "normals"));
             }),
             py::arg("name"), py::arg("corners"), py::arg("normals") = py::none(),
             "normals: None (flat) or the corners' normals (smooth shading, interpolated barycentrically).");

    py::class_<SplitPiece, Surface, std::shared_ptr<SplitPiece>>(
        m, "SplitPiece",
        "A piece of a surface between two curves of its domain (paper section 5.1: surfaces split along the "
        "discontinuities of their light): v = lower(u), v = upper(u) over t0 <= u <= t1, s(a, b) = parent(u, lower(u) + "
        "b (upper(u) - lower(u))), u = t0 + a (t1 - t0); along_v: u = lower(v), u = upper(v) over t0 <= v <= t1, "
        "s(a, b) = parent(lower(v) + a (upper(v) - lower(v)), v), v = t0 + b (t1 - t0).")
        .def(py::init([](const std::string& name, std::shared_ptr<Surface> parent, double t0, double t1, const Array& lower,
                         const Array& upper, bool along_v) {
                 return std::make_shared<SplitPiece>(name, std::move(parent), t0, t1, flat(lower), flat(upper), along_v);
             }),
             py::arg("name"), py::arg("parent"), py::arg("t0"), py::arg("t1"), py::arg("lower"), py::arg("upper"),
             py::arg("along_v") = false,
             "lower, upper: each curve's value at equal steps from t0 to t1 (a cubic through them), or one value: a "
             "constant.")
        .def_property_readonly("range", [](const SplitPiece& s) { return py::make_tuple(s.t0(), s.t1()); })
        .def_property_readonly("along_v", &SplitPiece::along_v)
        .def(
            "parent_parameters",
            [](const SplitPiece& s, const Array& ab) {
                return map_pairs(ab, "ab", [&](double a, double b, double& u, double& v) { s.parent_parameters(a, b, u, v); });
            },
            py::arg("ab"), "The parent's (u, v) at (N, 2) parameters of the piece.")
        .def(
            "piece_parameters",
            [](const SplitPiece& s, const Array& uv) {
                return map_pairs(uv, "uv", [&](double u, double v, double& a, double& b) { s.piece_parameters(u, v, a, b); });
            },
            py::arg("uv"), "The piece's (a, b) at (N, 2) parameters of the parent (clamped onto the band).");

    m.def(
        "split_band_parameters",
        [](double t0, double t1, const Array& lower, const Array& upper, bool along_v, const Array& uv) {
            if (lower.size() == 0 || upper.size() == 0) throw std::invalid_argument("a boundary curve has no samples");
            const BoundaryCurve lo(t0, t1, flat(lower)), hi(t0, t1, flat(upper));
            return map_pairs(uv, "uv", [&](double u, double v, double& a, double& b) {
                SplitPiece::band_parameters(lo, hi, t0, t1, along_v, u, v, a, b);
            });
        },
        py::arg("t0"), py::arg("t1"), py::arg("lower"), py::arg("upper"), py::arg("along_v"), py::arg("uv"),
        "A SplitPiece's (a, b) at (N, 2) parent parameters, from its band alone and not clamped: outside the band, a or "
        "b leaves [0, 1].");

    py::class_<PyRayCaster>(m, "RayCaster",
                            "Embree ray queries answering with surface id, (u, v), point and local frame; surface i is surfaces[i].")
        .def(py::init([](std::vector<std::shared_ptr<Surface>> surfaces, std::map<int, double> panes) {
                 auto rc = std::make_unique<PyRayCaster>();
                 std::vector<const Surface*> raw;
                 for (auto& s : surfaces) {
                     rc->surfaces.push_back(s);
                     raw.push_back(s.get());
                 }
                 std::vector<std::optional<ThinGlass>> glass(raw.size());
                 for (const auto& [i, eta] : panes) {
                     if (i < 0 || size_t(i) >= raw.size()) throw std::invalid_argument("panes: no surface " + std::to_string(i));
                     if (!(std::isfinite(eta) && eta >= 1)) throw std::invalid_argument("panes: index of refraction must be >= 1");
                     glass[i] = ThinGlass{eta, false};
                 }
                 py::gil_scoped_release release;
                 rc->caster = std::make_unique<RayCaster>(raw, glass);
                 return rc;
             }),
             py::arg("surfaces"), py::arg("panes") = std::map<int, double>{},
             "panes: {surface index: index of refraction} of window panes (thin glass), which transmittance() sees through.")
        .def_property_readonly("offset", [](const PyRayCaster& r) { return r.caster->offset(); },
                               "Self-intersection offset: scales with the scene's magnitude.")
        .def_property_readonly("triangle_count", [](const PyRayCaster& r) { return r.caster->triangle_count(); })
        .def(
            "spawn",
            [](const PyRayCaster& r, const Array& points, const Array& normals, const Array& directions) {
                const size_t n = rows(points, {3}, "points");
                if (rows(normals, {3}, "normals") != n || rows(directions, {3}, "directions") != n)
                    throw std::invalid_argument("points, normals and directions differ in length");
                auto out = empty({py::ssize_t(n), 3});
                for (size_t i = 0; i < n; ++i) {
                    const double *p = points.data() + 3 * i, *nn = normals.data() + 3 * i, *d = directions.data() + 3 * i;
                    const Vec3 o = r.caster->spawn({p[0], p[1], p[2]}, {nn[0], nn[1], nn[2]}, {d[0], d[1], d[2]});
                    out.mutable_data()[3 * i] = o.x, out.mutable_data()[3 * i + 1] = o.y, out.mutable_data()[3 * i + 2] = o.z;
                }
                return out;
            },
            py::arg("points"), py::arg("normals"), py::arg("directions"),
            "Ray origins leaving surface points: lifted by offset to the side each direction goes.")
        .def(
            "closest_hit",
            [](const PyRayCaster& r, const Array& origins, const Array& directions, std::optional<Array> tnear,
               std::optional<Array> tfar, int threads, std::optional<py::dict> out) {
                const RayBatch b = batch(origins, directions, tnear, tfar);
                const py::ssize_t n = py::ssize_t(b.count);
                py::dict d;
                if (out) {
                    d = *out;
                } else {
                    d["surface"] = py::array_t<int32_t>(n), d["t"] = py::array_t<double>(n), d["uv"] = empty({n, 2});
                    d["position"] = empty({n, 3}), d["frame"] = empty({n, 3, 3}), d["leaving"] = empty({n, 3});
                }
                // Writable C-contiguous arrays of the right shape, or the key is skipped.
                auto target = [&](const char* key, std::vector<py::ssize_t> shape, auto* tag) {
                    using T = std::remove_pointer_t<decltype(tag)>;
                    if (!d.contains(key)) return static_cast<T*>(nullptr);
                    auto a = py::array::ensure(d[key]);
                    bool ok = a && a.dtype().is(py::dtype::of<T>()) && (a.flags() & py::array::c_style) && a.writeable() &&
                              size_t(a.ndim()) == shape.size();
                    for (size_t i = 0; ok && i < shape.size(); ++i) ok = a.shape(i) == shape[i];
                    if (!ok) throw std::invalid_argument(std::string("out['") + key + "'] must be a writable C-contiguous array of the right shape and dtype");
                    return static_cast<T*>(a.mutable_data());
                };
                HitArrays arrays{target("surface", {n}, (int32_t*)nullptr), target("t", {n}, (double*)nullptr),
                                 target("uv", {n, 2}, (double*)nullptr), target("position", {n, 3}, (double*)nullptr),
                                 target("frame", {n, 3, 3}, (double*)nullptr), target("leaving", {n, 3}, (double*)nullptr)};
                {
                    py::gil_scoped_release release;
                    r.caster->closest_hit_batch(b, arrays, threads);
                }
                return d;
            },
            py::arg("origins"), py::arg("directions"), py::arg("tnear") = py::none(), py::arg("tfar") = py::none(),
            py::arg("threads") = 0, py::arg("out") = py::none(),
            "Closest hits of rays origin + t dir: surface (-1: none), t (inf: none), uv, position, frame (N, 3, 3) with rows "
            "x, y, normal, and leaving: -dir as the hit surface's radiance evaluate() takes it (in its radiance frame: the "
            "shading frame on smooth-shaded faces, the side the geometric one). `out`: a dict of preallocated arrays to fill instead (keys left out are not computed). "
            "Releases the GIL; threads=0 uses all.")
        .def(
            "closest_hits_from",
            [](const PyRayCaster& r, const Array& origin, const Array& directions) {
                if (rows(origin, {3}, "origin") != 1) throw std::invalid_argument("origin must be one point, shape (1, 3)");
                const size_t n = rows(directions, {3}, "directions");
                std::vector<Vec3> dirs(n);
                for (size_t i = 0; i < n; ++i) {
                    const double* d = directions.data() + 3 * i;
                    dirs[i] = {d[0], d[1], d[2]};
                    if (!std::isfinite(d[0]) || !std::isfinite(d[1]) || !std::isfinite(d[2]) || dot(dirs[i], dirs[i]) == 0)
                        throw std::invalid_argument("directions: row " + std::to_string(i) + " is not a finite non-zero vector");
                }
                std::vector<SurfaceHit> hits(n);
                {
                    py::gil_scoped_release release;
                    const double* o = origin.data();
                    r.caster->closest_hits_from({o[0], o[1], o[2]}, dirs.data(), n, hits.data());
                }
                py::array_t<int32_t> surface{py::ssize_t(n)};
                py::array_t<double> t{py::ssize_t(n)};
                auto uv = empty({py::ssize_t(n), 2});
                for (size_t i = 0; i < n; ++i) {
                    surface.mutable_data()[i] = hits[i].surface;
                    t.mutable_data()[i] = hits[i].surface >= 0 ? hits[i].t : std::numeric_limits<double>::infinity();
                    uv.mutable_data()[2 * i] = hits[i].u, uv.mutable_data()[2 * i + 1] = hits[i].v;
                }
                py::dict d;
                d["surface"] = surface, d["t"] = t, d["uv"] = uv;
                return d;
            },
            py::arg("origin"), py::arg("directions"),
            "Closest hits of rays leaving one origin, traced together in packets (as a gather traces a hemisphere's): "
            "surface (-1: none), t (inf: none), uv.")
        .def(
            "occluded",
            [](const PyRayCaster& r, const Array& origins, const Array& directions, std::optional<Array> tnear,
               std::optional<Array> tfar, int threads) {
                const RayBatch b = batch(origins, directions, tnear, tfar);
                py::array_t<uint8_t> out(py::ssize_t(b.count));
                uint8_t* o = out.mutable_data();
                {
                    py::gil_scoped_release release;
                    r.caster->occluded_batch(b, o, threads);
                }
                return out.attr("astype")("bool");
            },
            py::arg("origins"), py::arg("directions"), py::arg("tnear") = py::none(), py::arg("tfar") = py::none(),
            py::arg("threads") = 0, "Whether anything blocks each ray within (tnear, tfar).")
        .def(
            "transmittance",
            [](const PyRayCaster& r, const Array& origins, const Array& directions, std::optional<Array> tnear,
               std::optional<Array> tfar, int threads) {
                const RayBatch b = batch(origins, directions, tnear, tfar);
                py::array_t<double> out({py::ssize_t(b.count), py::ssize_t(3)});
                double* o = out.mutable_data();
                {
                    py::gil_scoped_release release;
                    r.caster->transmittance_batch(b, o, threads);
                }
                return out;
            },
            py::arg("origins"), py::arg("directions"), py::arg("tnear") = py::none(), py::arg("tfar") = py::none(),
            py::arg("threads") = 0,
            "Fraction of light passing along each ray within (tnear, tfar), (N, 3) RGB: the product of the panes' "
            "thin-sheet transmittance times their tints, 0 if an opaque surface is in the way.")
        .def(
            "raw_closest_hit",
            [](const PyRayCaster& r, const Array& origins, const Array& directions, int threads) {
                const RayBatch b = batch(origins, directions, std::nullopt, std::nullopt);
                py::array_t<float> t(py::ssize_t(b.count));
                py::array_t<int32_t> surface(py::ssize_t(b.count));
                float* pt = t.mutable_data();
                int32_t* ps = surface.mutable_data();
                {
                    py::gil_scoped_release release;
                    r.caster->ray_scene().raw_closest_hit_batch(b, pt, ps, threads);
                }
                return py::make_tuple(t, surface);
            },
            py::arg("origins"), py::arg("directions"), py::arg("threads") = 0,
            "Benchmark baseline: plain Embree closest hits (t, surface), no parameters or frames.");
}

}  // namespace bsgi::bindings
