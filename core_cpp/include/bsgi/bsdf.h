// BSDFs rho of (6)-(8): evaluation, sampling and its density, in the local frame (1)-(3).
//
// Conventions: directions are unit vectors in the local frame (z = surface normal, x along
// s_u), pointing away from the surface. wo looks at the viewer, wi at the light; light flows
// from wi to wo. eval(wo, wi) is the BSDF (radiance leaving along wo per unit irradiance
// arriving from wi), without the cosine. sample(wo, ...) draws wi with density pdf(wo, wi) per
// unit solid angle and returns the weight eval * |cos(theta_i)| / pdf. Reflection models are
// one-sided (zero unless both directions are above the surface); the dielectrics scatter on both
// sides, with `eta` the index inside (below the surface) over the index outside.
#pragma once
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bsgi/microfacet.h"
#include "bsgi/vec3.h"

namespace bsgi {

struct BsdfSample {
    Vec3 wi;
    Vec3 weight;      // eval(wo, wi) |cos theta_i| / pdf; for delta lobes the lobe's throughput
    double pdf = 0;   // solid-angle density; for delta lobes the probability of the lobe chosen
    bool delta = false;
};

class Bsdf {
public:
    virtual ~Bsdf() = default;
    virtual Vec3 eval(const Vec3& wo, const Vec3& wi) const = 0;
    virtual double pdf(const Vec3& wo, const Vec3& wi) const = 0;
    // eval and pdf at once, as multiple importance sampling needs them: a microfacet lobe finds
    // its half vector and D once (the glossy gather calls this for every pair of directions).
    virtual Vec3 eval_pdf(const Vec3& wo, const Vec3& wi, double& pdf_out) const {
        pdf_out = pdf(wo, wi);
        return eval(wo, wi);
    }
    // Draws wi from three uniform numbers in [0, 1); false if this draw scatters nothing
    // (e.g. a lobe direction below the surface): the missing probability.
    virtual bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const = 0;
    // The gather's draws (ScatterTable): a lobe that splits at each microfacet (a dielectric's
    // reflection and transmission) gives every branch of a draw, each with its own branch's
    // density (eval_gather_pdf), instead of one branch chosen by its chance: a glass seen along
    // its normal chose its reflection (F = 0.04) in one of 16 draws. At most kGatherBranches.
    static constexpr int kGatherBranches = 2;
    // Whether the gather draws from this lobe besides its cosine nodes (SolverSettings::bsdf_samples).
    virtual bool gathered_by_draws() const { return true; }
    virtual int gather_branches() const { return 1; }
    // Fills out[0, gather_branches()); a branch that scatters nothing has pdf 0.
    virtual void sample_branches(const Vec3& wo, double u0, double u1, double u2, BsdfSample* out) const {
        if (!sample(wo, u0, u1, u2, out[0])) out[0].pdf = 0;
    }
    // eval, and the density of the gather's draws (summed over branches) at wi.
    virtual Vec3 eval_gather_pdf(const Vec3& wo, const Vec3& wi, double& pdf_out) const { return eval_pdf(wo, wi, pdf_out); }
    // Index of the medium on the side of w (1 above, eta below for dielectrics).
    virtual double index_on_side(const Vec3& /*w*/) const { return 1; }
    virtual std::string name() const = 0;
    // About the angular width (radians) of the narrowest lobe of scattered light: what a
    // view-dependent radiance spline must resolve. pi/2 for diffuse reflection, 0 for delta lobes.
    virtual double lobe_width() const = 0;
    // True if light also leaves through the back side (paper section 4.3).
    virtual bool transmits() const { return false; }
    // The decomposition (38): a Lambertian part of albedo diffuse_albedo() plus glossy_part(),
    // for BSDFs that are such a sum (null otherwise).
    virtual Vec3 diffuse_albedo() const { return {0, 0, 0}; }
    virtual std::shared_ptr<const Bsdf> glossy_part() const { return nullptr; }
    // The same BSDF with its glossy colour (GGX f0) replaced, for a textured glossy colour
    // (Scene::set_specular_texture); null if it has no such colour. Schlick's Fresnel is affine in
    // f0: rho(f0) = f0 rho(1) + (1 - f0) rho(0) per channel.
    virtual std::shared_ptr<const Bsdf> with_specular_colour(const Vec3& /*f0*/) const { return nullptr; }
};

// rho = albedo / pi.
class Lambert final : public Bsdf {
public:
    explicit Lambert(const Vec3& albedo);
    Vec3 eval(const Vec3& wo, const Vec3& wi) const override;
    double pdf(const Vec3& wo, const Vec3& wi) const override;
    bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const override;
    std::string name() const override { return "lambert"; }
    double lobe_width() const override { return kPiD / 2; }
    const Vec3& albedo() const { return albedo_; }
    Vec3 diffuse_albedo() const override { return albedo_; }

private:
    Vec3 albedo_;
};

// Lambertian reflection about a bumped normal (a normal map or a Bump node), as Cycles shades it:
// albedo / pi max(0, n . wi) G1 over the light above the surface's own (smooth) normal z, with
// G1 the bump shadowing term of Conty Estevez et al. (2019) that Cycles applies with Bump Map
// Correction on: GGX's Smith G1 at alpha^2 = min(1, tan^2(theta_n) / 8) along wi.
// Such a surface's radiance does not change with the view but with its bumped normal, so the
// direction argument `wo` of eval, pdf and sample is that normal (unit, above the surface): the
// surface's 4D spline is L(u, v, alpha, beta) over its normal's (alpha, beta), and the normal map
// (normal_map.h) says which normal each point has.
class BumpedLambert final : public Bsdf {
public:
    BumpedLambert(const Vec3& albedo, bool bump_correction = true);
    Vec3 eval(const Vec3& n, const Vec3& wi) const override;
    double pdf(const Vec3& n, const Vec3& wi) const override;
    // Cosine about n; a draw below the surface scatters nothing (Cycles drops it too).
    bool sample(const Vec3& n, double u0, double u1, double u2, BsdfSample& out) const override;
    // The cosine nodes alone: with 16 draws beside them a uniform world came out 3% off its closed
    // form at bumps of 35-60 degrees, the nodes alone within 0.4%.
    bool gathered_by_draws() const override { return false; }
    std::string name() const override { return "lambert under a normal map"; }
    double lobe_width() const override { return kPiD / 2; }
    const Vec3& albedo() const { return albedo_; }
    bool bump_correction() const { return bump_correction_; }
    // Cycles' bump shadowing term for light at cosine cos_i to the surface's own normal and a
    // bumped normal at cosine cos_n to it (1 without Bump Map Correction).
    double shadowing(double cos_n, double cos_i) const;

private:
    Vec3 albedo_;
    bool bump_correction_;
};

// Energy-normalised Phong (Lafortune and Willems 1994):
// rho = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha), alpha the angle between wi and the mirror
// direction of wo. Conserves energy when kd + ks <= 1.
class NormalizedPhong final : public Bsdf {
public:
    NormalizedPhong(const Vec3& kd, const Vec3& ks, double exponent);
    Vec3 eval(const Vec3& wo, const Vec3& wi) const override;
    double pdf(const Vec3& wo, const Vec3& wi) const override;
    bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const override;
    std::string name() const override { return "phong"; }
    // cos^n falls to a half at sqrt(2 ln 2 / n) from the mirror direction.
    double lobe_width() const override { return max_component(ks_) > 0 ? std::sqrt(1.386 / (n_ + 1)) : kPiD / 2; }

private:
    Vec3 kd_, ks_;
    double n_, p_specular_;
};

// Ashikhmin and Shirley's anisotropic Phong BRDF (2000), the paper's default: a specular lobe
// with exponents nu along x (s_u) and nv along y and Schlick's Fresnel with rs at normal
// incidence, over a diffuse term rd that gives way to it.
class AshikhminShirley final : public Bsdf {
public:
    AshikhminShirley(const Vec3& rd, const Vec3& rs, double nu, double nv);
    Vec3 eval(const Vec3& wo, const Vec3& wi) const override;
    double pdf(const Vec3& wo, const Vec3& wi) const override;
    bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const override;
    std::string name() const override { return "ashikhmin_shirley"; }
    // The half vector's lobe, doubled for the reflected direction, along the sharper axis.
    double lobe_width() const override {
        return max_component(rs_) > 0 ? 2 * std::sqrt(1.386 / (std::max(nu_, nv_) + 1)) : kPiD / 2;
    }

private:
    double half_vector_pdf(const Vec3& h) const;
    Vec3 rd_, rs_;
    double nu_, nv_, p_specular_;
};

// The directional albedo E(mu) of a lobe (its largest channel: the integral of rho cos over the
// incoming directions, light leaving at cos theta = mu), tabulated from the lobe's own sampling
// and read linearly between the table's nodes.
class DirectionalAlbedo {
public:
    static constexpr int kNodes = 65;
    explicit DirectionalAlbedo(const Bsdf& lobe);
    // From a table of kNodes values in [0, 1] (as table() gives it: a stored solution's).
    explicit DirectionalAlbedo(std::vector<double> table);
    double operator()(double mu) const;
    const std::vector<double>& table() const { return table_; }

private:
    std::vector<double> table_;  // at mu = (k / (n - 1))^2
};

// Multiple scattering between a GGX lobe's microfacets, put back as Cycles' Multiscatter GGX
// (the default of its Principled, Glossy and Anisotropic BSDFs) puts it back (Kulla and Conty
// 2017): single scattering loses 1 - E(mu_o) of a white lobe's light (E its directional albedo),
// which leaves along the view tinted by the Fresnel's repeated bounces,
// rho_ms = rho (1 + F_ms (1 - E(mu_o)) / E(mu_o)), F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)),
// F_ss the Fresnel's and E_avg E's cosine-weighted means over the hemisphere. A white lobe then
// reflects all of its light at every angle.
class MultipleScattering {
public:
    // E of the isotropic white lobe of alpha sqrt(alpha_x alpha_y) (Cycles reads its table at that
    // roughness) and the lobe's shadowing, made once per alpha and shared; f_ss of the lobe's Fresnel.
    MultipleScattering(double alpha_x, double alpha_y, bool height_correlated, const Vec3& f_ss);
    // Any lobe's: E its directional albedo (a glass's from one side, reflected plus transmitted).
    MultipleScattering(std::shared_ptr<const DirectionalAlbedo> e, const Vec3& f_ss);
    // The factor on the single-scattering lobe along a view of cosine mu_o.
    Vec3 factor(double mu_o) const;

private:
    std::shared_ptr<const DirectionalAlbedo> albedo_;  // E
    Vec3 fms_;
};

// GGX microfacet reflection (Walter et al. 2007) with Smith's masking and shadowing, the model of
// Blender's Principled BSDF and Mitsuba 3's roughconductor:
// rho = F(wi.h) D(h) G(wo, wi, h) / (4 cos theta_o cos theta_i), G separable, G1(wo, h) G1(wi, h)
// (Mitsuba's), or height-correlated (GgxDistribution::G2, Cycles'); Schlick's F with f0
// (f0 = 1: a perfect mirror's Fresnel), as Cycles' metals (the Principled BSDF's F82 tint with
// its default white tint); with `schlick` off F is f0 at every angle, as Cycles' Glossy BSDF (its
// colour times GGX without Fresnel). Either F is affine in f0 (Scene::set_specular_texture).
// Sampled by visible normals. Anisotropic lobes (alpha_x != alpha_y) have their x axis along s_u
// turned by `rotation` radians about the normal towards y, as Blender's Anisotropic Rotation
// turns its tangent.
class GgxReflection final : public Bsdf {
public:
    // Fresnel: Schlick's from f0 (schlick), f0 at every angle (not), or with eta > 1 a dielectric's
    // curve remapped to start at f0 (fresnel_dielectric_remapped; schlick is then not read).
    // multiscatter: the light between microfacets put back (MultipleScattering); height_correlated:
    // Cycles' shadowing (else Mitsuba's separable one).
    GgxReflection(double alpha_x, double alpha_y, const Vec3& f0, double rotation = 0, bool schlick = true, double eta = 0,
                  bool multiscatter = false, bool height_correlated = false);
    Vec3 eval(const Vec3& wo, const Vec3& wi) const override;
    double pdf(const Vec3& wo, const Vec3& wi) const override;
    Vec3 eval_pdf(const Vec3& wo, const Vec3& wi, double& pdf_out) const override;
    bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const override;
    std::string name() const override { return "ggx"; }
    double lobe_width() const override { return 2 * std::min(D_.ax, D_.ay); }
    // The multiple scattering keeps its colour (of this lobe's f0): a texture's blend of the lobes
    // at f0 = 1 and 0 stays affine, their multiple scattering that of the texture's mean.
    std::shared_ptr<const Bsdf> with_specular_colour(const Vec3& f0) const override {
        auto tinted = std::make_shared<GgxReflection>(D_.ax, D_.ay, f0, std::atan2(sin_, cos_), schlick_, eta_, false,
                                                      height_correlated_);
        tinted->multiple_ = multiple_;
        return tinted;
    }
    bool multiscatter() const { return bool(multiple_); }
    bool height_correlated() const { return height_correlated_; }

private:
    Vec3 fresnel(double cos_theta) const {
        if (eta_ > 0) return fresnel_dielectric_remapped(f0_, cos_theta, eta_);
        return schlick_ ? fresnel_schlick(f0_, cos_theta) : f0_;
    }
    // Local frame <-> the lobe's frame (x along the turned tangent).
    Vec3 to_lobe(const Vec3& w) const { return {cos_ * w.x + sin_ * w.y, cos_ * w.y - sin_ * w.x, w.z}; }
    Vec3 from_lobe(const Vec3& w) const { return {cos_ * w.x - sin_ * w.y, sin_ * w.x + cos_ * w.y, w.z}; }
    double shadowing(const Vec3& wo, const Vec3& wi, const Vec3& h) const { return D_.G(wo, wi, h, height_correlated_); }
    GgxDistribution D_;
    Vec3 f0_;
    double cos_ = 1, sin_ = 0;
    bool schlick_ = true;
    double eta_ = 0;
    bool height_correlated_ = false;
    std::shared_ptr<const MultipleScattering> multiple_;  // null: single scattering
};

// An albedo texture under a layered coat (DiffuseGgx layered). D of (38) holds irradiance / pi
// and S the coat less its share E(mu_o) of the base at the BSDF's own albedo, so a texel T of
// the texture shows as T + E(mu_o) (albedo - T) per unit of D: the base's (1 - E(mu_o)) T, with
// S's share at the albedo put back. Exact for any texture: the solve keeps one S per surface.
struct CoatedBase {
    std::shared_ptr<const DirectionalAlbedo> share;  // E of the coat
    Vec3 albedo;                                     // the albedo S took its share at
    Vec3 texel(const Vec3& t, double mu) const { return t + (albedo - t) * (*share)(mu); }
};

// A Lambertian base under a GGX coat (GgxReflection, with its multiple scattering and shadowing),
// the plastic of Blender's Principled BSDF without metal.
// Uncoupled (layered false): rho = albedo / pi + GGX(alpha_x, alpha_y, f0); at grazing angles the
// coat's Fresnel rises while the base stays, so the albedo can pass 1 there. Layered (Cycles'
// Principled BSDF): the base gets what the coat leaves along the view, rho = (1 - E(mu_o))
// albedo / pi + GGX, E the coat's directional albedo: energy is conserved (albedo 1 reflects all
// of the light, at every angle). Sampled by choosing the lobe in proportion to the albedo and
// f0. The sum is what the decomposition (38) of the radiance splits: D the whole base, albedo /
// pi, and glossy_part() the rest, the coat less E(mu_o) albedo / pi where layered (S then goes
// negative where the coat reflects little: D + S is the surface's light).
class DiffuseGgx final : public Bsdf {
public:
    // eta: the coat's Fresnel (GgxReflection's; 0: Schlick's from f0).
    DiffuseGgx(const Vec3& albedo, double alpha_x, double alpha_y, const Vec3& f0, bool layered = false, double eta = 0,
               bool multiscatter = false, bool height_correlated = false);
    Vec3 eval(const Vec3& wo, const Vec3& wi) const override;
    double pdf(const Vec3& wo, const Vec3& wi) const override;
    Vec3 eval_pdf(const Vec3& wo, const Vec3& wi, double& pdf_out) const override;
    bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const override;
    std::string name() const override { return coat_albedo_ ? "layered_diffuse_ggx" : "diffuse_ggx"; }
    double lobe_width() const override { return coat_->lobe_width(); }
    Vec3 diffuse_albedo() const override { return albedo_; }
    std::shared_ptr<const Bsdf> glossy_part() const override { return glossy_; }

    bool layered() const { return bool(coat_albedo_); }
    // How an albedo texture shows under the coat, if layered.
    std::optional<CoatedBase> coated_base() const {
        return coat_albedo_ ? std::optional<CoatedBase>(CoatedBase{coat_albedo_, albedo_}) : std::nullopt;
    }

private:
    // The base's share along the view: 1 - E(mu_o) if layered, else 1.
    double base_weight(double mu_o) const { return coat_albedo_ ? 1 - (*coat_albedo_)(mu_o) : 1.0; }
    Vec3 albedo_;
    std::shared_ptr<const GgxReflection> coat_;
    std::shared_ptr<const DirectionalAlbedo> coat_albedo_;  // layered only
    std::shared_ptr<const Bsdf> glossy_;
    double p_diffuse_;
};

// A smooth dielectric boundary (glass, water): mirror reflection and Snell refraction, chosen by
// the Fresnel reflectance. Both lobes are delta lobes: eval and pdf are zero, sample() returns
// the direction and throughput (refraction scales radiance by (n_o / n_i)^2). Tints as
// RoughDielectric's.
class SmoothDielectric final : public Bsdf {
public:
    explicit SmoothDielectric(double eta, const Vec3& reflection_tint = {1, 1, 1}, const Vec3& transmission_tint = {1, 1, 1});
    Vec3 eval(const Vec3&, const Vec3&) const override { return {0, 0, 0}; }
    double pdf(const Vec3&, const Vec3&) const override { return 0; }
    bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const override;
    double index_on_side(const Vec3& w) const override { return w.z >= 0 ? 1.0 : eta_; }
    std::string name() const override { return "dielectric"; }
    double lobe_width() const override { return 0; }
    bool transmits() const override { return true; }
    const Vec3& reflection_tint() const { return reflection_tint_; }
    const Vec3& transmission_tint() const { return transmission_tint_; }

private:
    double eta_;
    Vec3 reflection_tint_, transmission_tint_;
};

// A rough dielectric boundary: GGX reflection and transmission (Walter et al. 2007, eq. 21 for
// radiance: f_t = |wi.h||wo.h| n_o^2 (1 - F) D G / (|cos_i cos_o| (n_i wi.h + n_o wo.h)^2)).
// Paper section 4.3: the transmitted light is the second, lower-hemisphere radiance function.
// Cycles' glass differs in three ways, each a choice here (Mitsuba's roughdielectric takes none):
// height_correlated, its shadowing (GgxDistribution::G2, as GgxReflection); scale_radiance off,
// the transmitted light carried across unscaled by (n_o / n_i)^2 (Cycles carries throughput: the
// same through any closed solid, where the factors of the way in and out cancel, and what Cycles
// shows through an open sheet); multiscatter, Multiscatter GGX's light between microfacets put
// back: the lobe scaled by 1 / E(mu_o), E the single-scattering glass's directional albedo
// (reflected plus transmitted energy, from the side of the view), so the lobe keeps all light.
// Tinted glass as Cycles tints it: the reflected branch times reflection_tint, the transmitted
// times transmission_tint (a Glass BSDF's colour is both; a Principled BSDF's transmission the
// square root of its base colour, met on the way in and out), and Multiscatter GGX's light put
// back as MultipleScattering's with the transmission tint as F_ss (Cycles' assumption that the
// transmission makes most of a glass's colour): a tinted glass is darker than its tint.
class RoughDielectric final : public Bsdf {
public:
    RoughDielectric(double eta, double alpha_x, double alpha_y, bool multiscatter = false, bool height_correlated = false,
                    bool scale_radiance = true, const Vec3& reflection_tint = {1, 1, 1},
                    const Vec3& transmission_tint = {1, 1, 1});
    Vec3 eval(const Vec3& wo, const Vec3& wi) const override;
    double pdf(const Vec3& wo, const Vec3& wi) const override;
    bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const override;
    double index_on_side(const Vec3& w) const override { return w.z >= 0 ? 1.0 : eta_; }
    std::string name() const override { return "rough_dielectric"; }
    // Refraction narrows the transmitted lobe: a microfacet tilt of alpha turns the refracted
    // direction by about alpha (eta - 1) / eta on the denser side.
    double lobe_width() const override {
        const double e = std::max(eta_, 1 / eta_);
        return 2 * std::min(D_.ax, D_.ay) * std::min(1.0, (e - 1) / e + 0.1);
    }
    bool transmits() const override { return true; }
    int gather_branches() const override { return 2; }
    void sample_branches(const Vec3& wo, double u0, double u1, double u2, BsdfSample* out) const override;
    Vec3 eval_gather_pdf(const Vec3& wo, const Vec3& wi, double& pdf_out) const override;
    bool multiscatter() const { return bool(outside_); }
    const Vec3& reflection_tint() const { return reflection_tint_; }
    const Vec3& transmission_tint() const { return transmission_tint_; }
    bool height_correlated() const { return height_correlated_; }
    bool scale_radiance() const { return scale_radiance_; }
    // The single-scattering lobe's directional albedo (reflected plus transmitted energy) seen
    // from outside (above) or inside, at a view of cosine mu > 0.
    static double single_scattering_albedo(const GgxDistribution& D, double n_o, double n_t, bool height_correlated,
                                           double mu);

private:
    // With wo mirrored into the upper hemisphere: n_o is the index there, n_t the other.
    double eval_up(const Vec3& wo, const Vec3& wi, double n_o, double n_t) const;
    // The density of wi drawn by sample() (chosen: times the branch's chance) or of its branch alone.
    double pdf_up(const Vec3& wo, const Vec3& wi, double n_o, double n_t, bool chosen = true) const;
    double shadowing(const Vec3& wo, const Vec3& wi, const Vec3& h) const { return D_.G(wo, wi, h, height_correlated_); }
    // The factor on the single-scattering lobe of the branch wi takes: its tint, times
    // Multiscatter GGX's factor on the side of wo.
    Vec3 branch_weight(const Vec3& wo, const Vec3& wi) const;
    double eta_;
    GgxDistribution D_;
    bool height_correlated_ = false, scale_radiance_ = true;
    Vec3 reflection_tint_, transmission_tint_;
    std::optional<MultipleScattering> outside_, inside_;  // none: single scattering
};

// Emitted radiance L_S^emit of (6): uniform over the front (or both) sides. sample() draws
// emission directions with the cosine-weighted density, pdf() is that density.
class Emission {
public:
    Emission(const Vec3& radiance, bool two_sided = false);
    Vec3 eval(const Vec3& w) const;
    double pdf(const Vec3& w) const;
    bool sample(double u0, double u1, double u2, Vec3& w, double& pdf) const;
    const Vec3& radiance() const { return radiance_; }

private:
    Vec3 radiance_;
    bool two_sided_;
};

}  // namespace bsgi
