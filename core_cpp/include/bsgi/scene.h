// The scene the solver sees: surfaces with their materials, which of them block light, and the
// world's light.
#pragma once
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bsgi/bsdf.h"
#include "bsgi/environment.h"
#include "bsgi/normal_map.h"
#include "bsgi/surface.h"
#include "bsgi/texture.h"
#include "bsgi/thin_glass.h"

namespace bsgi {

// A spot light's cone (Cycles' convention): emission towards direction w (unit, away from the
// emitter) is scaled by smoothstep((w . axis - cos_half) / ((1 - cos_half) blend)), 0 outside
// the cone of half angle acos(cos_half) and 1 well inside it (a hard edge for blend 0).
struct SpotCone {
    Vec3 axis{0, 0, -1};
    double cos_half = -1;
    double blend = 0;
    double factor(const Vec3& w) const {
        const double t = dot(w, axis) - cos_half;
        if (t <= 0) return 0;
        const double f = t / ((1 - cos_half) * blend);
        if (!(f < 1)) return 1;  // also blend 0
        return f * f * (3 - 2 * f);
    }
};

// How a surface scatters and emits. Without a BSDF the surface is Lambertian with `albedo`.
// Emission is radiance leaving the front side, in every direction or within a spot cone, and
// the back side too where it is two-sided (Cycles' emissive meshes; its area lights are not).
// Textures over the surface's (u, v) replace the constants (which then hold their means): the
// albedo of a Lambertian surface or of the diffuse base of a decomposed (38) one, the emission,
// the f0 of a GGX lobe (the BSDF then has the texture's mean as its f0).
// With thin_glass the surface is a window pane instead: rays cross it (see thin_glass.h).
struct Material {
    Vec3 albedo;
    Vec3 emission;
    std::shared_ptr<const Bsdf> bsdf;
    std::optional<SpotCone> cone;
    std::shared_ptr<const Texture> albedo_texture, emission_texture, specular_texture;
    // A Lambertian surface's bumped normals (normal_map.h): it is then a BumpedLambert.
    std::shared_ptr<const Texture> normal_texture;
    bool bump_correction = true;  // Cycles' Bump Map Correction (the material's setting)
    std::optional<ThinGlass> thin_glass;
    bool two_sided_emission = false;
    bool emits() const { return max_component(emission) > 0; }
    // A layered coat's base (DiffuseGgx layered), for an albedo texture under it.
    std::optional<CoatedBase> coated_base() const {
        const auto* layered = dynamic_cast<const DiffuseGgx*>(bsdf.get());
        return layered ? layered->coated_base() : std::nullopt;
    }
    // Mean emission over the parameter rectangle [u0, u1] x [v0, v1].
    Vec3 emission_over(double u0, double u1, double v0, double v1) const {
        return emission_texture ? emission_texture->mean(u0, u1, v0, v1) : emission;
    }
};

// A light at infinity (Blender's sun): `irradiance` on a surface facing it, arriving from a disc of
// angular diameter `angle` (radians, 0: one direction) around `direction` (unit, towards the
// light), blocked by occluders like any ray.
struct DistantLight {
    std::string name;
    Vec3 direction;
    Vec3 irradiance;
    double angle = 0;
};

// How a surface's radiance is represented: chosen by the solver from the material and the size
// ("model only what the scene requires") unless given here. Decomposed is (38): a 2D diffuse
// part D(u, v) at the full spatial resolution plus a 4D glossy part S on coarser spatial knots,
// for BSDFs that are a Lambertian base plus a glossy lobe.
enum class Representation { Auto = 0, Diffuse = 1, Glossy = 2, Decomposed = 3 };

struct SurfaceOptions {
    Representation representation = Representation::Auto;
    int spatial_coeffs = 0;  // per direction; 0: from the settings and the surface's size
    int angular_coeffs = 0;  // per direction of (alpha, beta); 0: from the BSDF's lobe width
    // Times the final gather's integration nodes per axis for this surface (hemisphere nodes
    // and BSDF samples; 1: the settings'), as refinement sets it where the error estimate's
    // integration part is most of a surface's error.
    int integration_factor = 1;
};

struct SceneSurface {
    std::shared_ptr<const Surface> surface;  // shared: Python may hold the same surface
    Material material;
    bool receiver;  // gets a radiance spline (false for light objects, which only emit)
    bool occluder;  // blocks rays (false for light objects, as in Cycles)
    SurfaceOptions options;
};

class Scene {
public:
    int add(std::shared_ptr<const Surface> surface, const Material& material, bool receiver = true, bool occluder = true,
            const SurfaceOptions& options = {}) {
        if (!surface) throw std::invalid_argument("Scene::add: no surface");
        const std::string& name = surface->name();
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(material.albedo[c]) || material.albedo[c] < 0 || material.albedo[c] > 1)
                throw std::invalid_argument("surface '" + name + "': albedo must be finite and in [0, 1]");
        require_non_negative(material.emission, "surface '" + name + "': emission");
        // Surfaces that exist as geometry but have no area (NURBS control points on a line, a
        // mesh of slivers) would solve to light on nothing: relative to the squared size, as
        // the patches' own check.
        if (!(surface->area() > 1e-12 * surface->size() * surface->size()))
            throw std::invalid_argument("surface '" + name + "': zero area (its points lie on a line or a point)");
        if (options.spatial_coeffs < 0 || options.angular_coeffs < 0)
            throw std::invalid_argument("surface '" + name + "': coefficient counts must be >= 0 (0: automatic)");
        if (dynamic_cast<const BumpedLambert*>(material.bsdf.get()))
            throw std::invalid_argument("surface '" + name + "': a BumpedLambert reads its direction as a bumped normal; "
                                        "give the surface a Lambert and its normal map (set_normal_texture)");
        if (material.thin_glass) {
            // A pane's light is the light crossing it: it gets no spline of its own.
            if (!(std::isfinite(material.thin_glass->eta) && material.thin_glass->eta >= 1))
                throw std::invalid_argument("surface '" + name + "': thin glass needs a finite index of refraction >= 1");
            if (material.emits()) throw std::invalid_argument("surface '" + name + "': thin glass cannot emit");
            const ThinGlass& glass = *material.thin_glass;
            for (const Vec3* c : {&glass.transmission_tint, &glass.reflection_tint, glass.shadow ? &*glass.shadow : nullptr})
                for (int k = 0; c && k < 3; ++k)
                    if (!((*c)[k] >= 0 && (*c)[k] <= 1))
                        throw std::invalid_argument("surface '" + name + "': thin glass tints and shadow transmittance must be "
                                                    "in [0, 1]");
            receiver = false;
        }
        surfaces_.push_back({std::move(surface), material, receiver, occluder, options});
        return static_cast<int>(surfaces_.size()) - 1;
    }
    // Constant radiance arriving from every direction in which no occluder is seen: a distant
    // emitter enclosing the scene (Blender's world background of one colour).
    void set_world_radiance(const Vec3& radiance) {
        require_non_negative(radiance, "world: radiance");
        world_ = radiance;
        world_map_.reset();
    }
    const Vec3& world_radiance() const { return world_; }
    // Radiance arriving from each direction no occluder blocks, as an environment map (a
    // textured world: an HDRI, a sky); replaces the constant. nullptr: no map.
    void set_world_map(std::shared_ptr<const EnvironmentMap> map) {
        world_map_ = std::move(map);
        world_ = {0, 0, 0};
    }
    const EnvironmentMap* world_map() const { return world_map_.get(); }
    bool has_world() const { return world_map_ || max_component(world_) > 0; }
    // The indices of the surfaces that emit. A loop over the whole scene: callers that ask per
    // point or per receiver keep the list (asked at every probed cell, it made the sides probe
    // quadratic in the surfaces).
    std::vector<int> emitters() const {
        std::vector<int> out;
        for (size_t i = 0; i < surfaces_.size(); ++i)
            if (surfaces_[i].material.emits()) out.push_back(int(i));
        return out;
    }

    void add_distant_light(DistantLight light) {
        const std::string what = "distant light '" + light.name + "': ";
        light.direction = unit_direction(light.direction, what + "direction");
        require_non_negative(light.irradiance, what + "irradiance");
        if (!(light.angle >= 0 && light.angle < kPi)) throw std::invalid_argument(what + "angle must be in [0, pi) radians");
        distant_.push_back(std::move(light));
    }
    const std::vector<DistantLight>& distant_lights() const { return distant_; }

    // Makes emitter i a spot light: its emission limited to a cone of full angle `spot_size`
    // (radians) around `axis`, softened over the fraction `blend` of it (Blender's spot light).
    void set_spot_cone(size_t i, const Vec3& axis, double spot_size, double blend) {
        if (i >= surfaces_.size()) throw std::out_of_range("set_spot_cone: no surface " + std::to_string(i));
        const std::string what = "spot light '" + surfaces_[i].surface->name() + "': ";
        if (!surfaces_[i].material.emits()) throw std::invalid_argument(what + "emits no light");
        const Vec3 unit_axis = unit_direction(axis, what + "axis");
        if (!(spot_size > 0 && spot_size <= kPi)) throw std::invalid_argument(what + "spot size must be in (0, pi] radians");
        if (!(blend >= 0 && blend <= 1)) throw std::invalid_argument(what + "blend must be in [0, 1]");
        surfaces_[i].material.cone = SpotCone{unit_axis, std::cos(0.5 * spot_size), blend};
    }

    // Surface i's albedo (of its Lambertian base) varies over its (u, v) as `texture`; the solve
    // keeps irradiance / pi in its spline and multiplies by the texture where it is seen.
    void set_albedo_texture(size_t i, std::shared_ptr<const Texture> texture) {
        SceneSurface& s = at(i, "set_albedo_texture");
        const std::string what = "surface '" + s.surface->name() + "': albedo texture";
        if (!texture) throw std::invalid_argument(what + ": no image");
        if (s.material.bsdf && max_component(s.material.bsdf->diffuse_albedo()) <= 0)
            throw std::invalid_argument(what + ": its " + s.material.bsdf->name() +
                                        " BSDF has no diffuse base for the texture to colour");
        if (s.options.representation == Representation::Glossy)
            throw std::invalid_argument(what + ": needs a diffuse or decomposed representation, not 'glossy'");
        s.material.albedo = texture->mean();
        s.material.albedo_texture = std::move(texture);
    }
    // Surface i's emission varies over its (u, v) as `texture` (front side, every direction).
    void set_emission_texture(size_t i, std::shared_ptr<const Texture> texture) {
        SceneSurface& s = at(i, "set_emission_texture");
        if (!texture) throw std::invalid_argument("surface '" + s.surface->name() + "': emission texture: no image");
        s.material.emission = texture->mean();
        s.material.emission_texture = std::move(texture);
    }
    // Surface i's glossy colour (a metal's f0) varies over its (u, v) as `texture`. Schlick's
    // Fresnel is affine in f0, so the surface's radiance is exactly T L1 + (1 - T) L0 with L1, L0
    // its radiance at f0 = 1 and f0 = 0: the solve keeps both splines and the texture T blends
    // them where the surface is seen (its BSDF here takes the texture's mean as f0).
    void set_specular_texture(size_t i, std::shared_ptr<const Texture> texture) {
        SceneSurface& s = at(i, "set_specular_texture");
        const std::string what = "surface '" + s.surface->name() + "': specular texture";
        if (!texture) throw std::invalid_argument(what + ": no image");
        std::shared_ptr<const Bsdf> tinted = s.material.bsdf ? s.material.bsdf->with_specular_colour(texture->mean()) : nullptr;
        if (!tinted)
            throw std::invalid_argument(what + ": its " + (s.material.bsdf ? s.material.bsdf->name() : std::string("lambert")) +
                                        " BSDF has no glossy colour for the texture to tint");
        if (s.options.representation == Representation::Diffuse)
            throw std::invalid_argument(what + ": needs the glossy representation, not 'diffuse'");
        s.material.bsdf = std::move(tinted);
        s.material.specular_texture = std::move(texture);
    }
    // Surface i's shading normal is bumped as `map` says (normal_map.h, from Scene's bindings):
    // a Lambertian surface only (Cycles bumps any closure; the solve models the diffuse one).
    void set_normal_texture(size_t i, std::shared_ptr<const Texture> map, bool bump_correction) {
        SceneSurface& s = at(i, "set_normal_texture");
        const std::string what = "surface '" + s.surface->name() + "': normal map";
        if (!map) throw std::invalid_argument(what + ": no image");
        if (s.material.bsdf && !dynamic_cast<const Lambert*>(s.material.bsdf.get()))
            throw std::invalid_argument(what + ": is solved on Lambertian surfaces only, not under a " +
                                        s.material.bsdf->name() + " BSDF");
        if (s.material.thin_glass) throw std::invalid_argument(what + ": a thin pane has no shading to bump");
        if (s.options.representation == Representation::Diffuse || s.options.representation == Representation::Decomposed)
            throw std::invalid_argument(what + ": needs the glossy representation (4D over the bumped normal)");
        bumped_tilt_ = std::max(bumped_tilt_, largest_tilt(*map));
        s.material.normal_texture = std::move(map);
        s.material.bump_correction = bump_correction;
    }
    // The largest tilt of any normal map's normal from its surface's own (radians): the bumped
    // surfaces' radiance splines span the normals within it (one cap for all, so that an object's
    // surfaces bake on one disc).
    double bumped_tilt() const { return bumped_tilt_; }
    // Albedo or specular textures, or panes that colour the light crossing them: their colour
    // cannot ride on scalar form-factor weights.
    bool has_coloured_transport() const {
        for (const auto& s : surfaces_)
            if (s.material.albedo_texture || s.material.specular_texture || (s.material.thin_glass && s.material.thin_glass->coloured()))
                return true;
        return false;
    }
    // Makes emitter i emit its radiance from its back side too, as Cycles' Emission shader does
    // on a mesh.
    void set_two_sided_emission(size_t i, bool two_sided = true) {
        if (i >= surfaces_.size()) throw std::out_of_range("set_two_sided_emission: no surface " + std::to_string(i));
        if (!surfaces_[i].material.emits())
            throw std::invalid_argument("surface '" + surfaces_[i].surface->name() + "': emits no light");
        surfaces_[i].material.two_sided_emission = two_sided;
    }

    // Sets surface i's spatial coefficients per direction (0: from the settings), as the
    // refinement of bsgi.solve does where the error estimate is over its target.
    void set_spatial_coeffs(size_t i, int spatial_coeffs) {
        if (i >= surfaces_.size()) throw std::out_of_range("set_spatial_coeffs: no surface " + std::to_string(i));
        if (spatial_coeffs < 0)
            throw std::invalid_argument("surface '" + surfaces_[i].surface->name() + "': coefficient counts must be >= 0 (0: automatic)");
        surfaces_[i].options.spatial_coeffs = spatial_coeffs;
    }

    // Sets surface i's factor on the final gather's integration nodes per axis (1: the
    // settings'), as the refinement of bsgi.solve does where the estimate's integration part
    // is over its target.
    void set_integration_factor(size_t i, int factor) {
        if (i >= surfaces_.size()) throw std::out_of_range("set_integration_factor: no surface " + std::to_string(i));
        if (factor < 1 || factor > kMaxIntegrationFactor)
            throw std::invalid_argument("surface '" + surfaces_[i].surface->name() + "': the integration factor must be from 1 to " +
                                        std::to_string(kMaxIntegrationFactor) + ", not " + std::to_string(factor));
        surfaces_[i].options.integration_factor = factor;
    }
    // 8 times the nodes per axis: 64 times the rays of the surface's final gather.
    static constexpr int kMaxIntegrationFactor = 8;

    size_t size() const { return surfaces_.size(); }
    const SceneSurface& operator[](size_t i) const { return surfaces_[i]; }
    const std::vector<SceneSurface>& surfaces() const { return surfaces_; }

private:
    static constexpr double kPi = 3.14159265358979323846;
    SceneSurface& at(size_t i, const char* what) {
        if (i >= surfaces_.size()) throw std::out_of_range(std::string(what) + ": no surface " + std::to_string(i));
        return surfaces_[i];
    }
    // The checks of the scene's inputs, `what` naming the object and the quantity.
    static void require_non_negative(const Vec3& v, const std::string& what) {
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(v[c]) || v[c] < 0) throw std::invalid_argument(what + " must be finite and >= 0");
    }
    static Vec3 unit_direction(const Vec3& v, const std::string& what) {
        const double n = length(v);
        if (!(n > 0) || !std::isfinite(n)) throw std::invalid_argument(what + " must be finite and non-zero");
        return v / n;
    }

    std::vector<SceneSurface> surfaces_;
    double bumped_tilt_ = 0;  // (kept as normal maps are set: largest_tilt reads every texel)
    Vec3 world_{0, 0, 0};
    std::shared_ptr<const EnvironmentMap> world_map_;
    std::vector<DistantLight> distant_;
};

}  // namespace bsgi
