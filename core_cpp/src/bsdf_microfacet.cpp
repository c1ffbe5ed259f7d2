// GGX reflection, smooth and rough dielectrics.
#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "bsgi/bsdf.h"

namespace bsgi {

namespace {

void check_alpha(double a) {
    if (!std::isfinite(a) || a < 1e-4 || a > 10) throw std::invalid_argument("GGX roughness alpha must be in [1e-4, 10]");
}

void check_eta(double eta) {
    // Below 0.01 the relative index's square (eta^2 in the transmitted weight) leaves double range.
    if (!std::isfinite(eta) || eta < 0.01 || eta > 10) throw std::invalid_argument("dielectric eta must be in [0.01, 10]");
}

// A glass's tint passes at most all of the light of its branch.
void check_tint(const Vec3& t, const char* branch) {
    for (double c : {t.x, t.y, t.z})
        if (!(c >= 0 && c <= 1)) throw std::invalid_argument(std::string("dielectric ") + branch + " tint must be in [0, 1] per channel");
}

Vec3 mirror_z(const Vec3& w) { return {w.x, w.y, -w.z}; }

}  // namespace

// ---- GGX reflection ----

GgxReflection::GgxReflection(double alpha_x, double alpha_y, const Vec3& f0, double rotation, bool schlick, double eta,
                             bool multiscatter, bool height_correlated)
    : D_{alpha_x, alpha_y}, f0_(f0), cos_(std::cos(rotation)), sin_(std::sin(rotation)), schlick_(schlick), eta_(eta),
      height_correlated_(height_correlated) {
    if (eta != 0 && !(std::isfinite(eta) && eta > 1 && eta <= 10))
        throw std::invalid_argument("GGX Fresnel eta must be in (1, 10], or 0 for Schlick's");
    check_alpha(alpha_x);
    check_alpha(alpha_y);
    if (!std::isfinite(rotation)) throw std::invalid_argument("GGX rotation must be finite");
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(f0[i]) || f0[i] < 0 || f0[i] > 1) throw std::invalid_argument("GGX f0 must be in [0, 1]");
    if (multiscatter) {
        // F_ss = 2 int_0^1 F(mu) mu dmu, by the midpoint rule (F is smooth: 1e-7 at 512 nodes).
        constexpr int kNodes = 512;
        Vec3 f_ss{0, 0, 0};
        for (int k = 0; k < kNodes; ++k) {
            const double mu = (k + 0.5) / kNodes;
            f_ss += fresnel(mu) * (2 * mu / kNodes);
        }
        multiple_ = std::make_shared<MultipleScattering>(alpha_x, alpha_y, height_correlated, f_ss);
    }
}

Vec3 GgxReflection::eval(const Vec3& wo_local, const Vec3& wi_local) const {
    if (wo_local.z <= 0 || wi_local.z <= 0) return {0, 0, 0};
    const Vec3 wo = to_lobe(wo_local), wi = to_lobe(wi_local);
    const Vec3 h = normalize(wo + wi);
    const Vec3 f = fresnel(dot(wi, h)) * (D_.D(h) * shadowing(wo, wi, h) / (4 * wo.z * wi.z));
    return multiple_ ? f * multiple_->factor(wo.z) : f;
}

double GgxReflection::pdf(const Vec3& wo_local, const Vec3& wi_local) const {
    if (wo_local.z <= 0 || wi_local.z <= 0) return 0;
    const Vec3 wo = to_lobe(wo_local), wi = to_lobe(wi_local);
    const Vec3 h = normalize(wo + wi);
    const double oh = dot(wo, h);
    return oh > 0 ? D_.visible_pdf(wo, h) / (4 * oh) : 0;  // reflection's Jacobian 1 / (4 wo.h)
}

Vec3 GgxReflection::eval_pdf(const Vec3& wo_local, const Vec3& wi_local, double& pdf_out) const {
    pdf_out = 0;
    if (wo_local.z <= 0 || wi_local.z <= 0) return {0, 0, 0};
    const Vec3 wo = to_lobe(wo_local), wi = to_lobe(wi_local);
    const Vec3 h = normalize(wo + wi);
    const double d = D_.D(h), g_o = D_.G1(wo, h), oh = dot(wo, h);
    // visible_pdf(wo, h) / (4 wo.h) = G1(wo, h) D(h) / (4 wo.z), for wo.h > 0.
    if (oh > 0) pdf_out = g_o * d / (4 * wo.z);
    const Vec3 f = fresnel(dot(wi, h)) * (d * shadowing(wo, wi, h) / (4 * wo.z * wi.z));
    return multiple_ ? f * multiple_->factor(wo.z) : f;
}

bool GgxReflection::sample(const Vec3& wo, double, double u1, double u2, BsdfSample& out) const {
    if (wo.z <= 0) return false;
    const Vec3 m = from_lobe(D_.sample_visible(to_lobe(wo), u1, u2));
    const double om = dot(wo, m);
    if (om <= 0) return false;
    const Vec3 wi = m * (2 * om) - wo;
    if (wi.z <= 0) return false;
    out.wi = wi;
    out.delta = false;
    const Vec3 f = eval_pdf(wo, wi, out.pdf);
    if (!(out.pdf > 0)) return false;
    out.weight = f * (wi.z / out.pdf);
    return true;
}

// ---- Lambertian base under a GGX coat ----

// ---- directional albedo ----

namespace {

// Nodes of the table, uniform in sqrt(mu) (dense towards grazing, where the Fresnel curve rises
// steeply: uniform in mu, a narrow coat's E was 2% off between nodes there), and each node's
// stratified estimate from the lobe's own sampling (its weight is rho cos / pdf, near constant
// for a GGX lobe): 64 strata in u1, warped u1 = 1 - (1 - t)^2 towards 1 (GGX's long tail of
// steep microfacets, whose light leaves below the horizon: uniform strata missed 0.8% of a
// narrow lobe's loss along the normal), by 32 in u2; within 1e-4 of 4M random samples.
constexpr int kAlbedoNodes = DirectionalAlbedo::kNodes, kAlbedoRadial = 64, kAlbedoAround = 32;

}  // namespace

DirectionalAlbedo::DirectionalAlbedo(const Bsdf& lobe) : table_(kAlbedoNodes) {
    for (int k = 0; k < kAlbedoNodes; ++k) {
        const double x = double(k) / (kAlbedoNodes - 1), mu = std::max(x * x, 1e-4);
        const Vec3 wo{std::sqrt(1 - mu * mu), 0, mu};
        Vec3 sum{0, 0, 0};
        BsdfSample out;
        for (int i = 0; i < kAlbedoRadial; ++i) {
            const double t = 1 - (i + 0.5) / kAlbedoRadial;  // 1 - t of the warp
            for (int j = 0; j < kAlbedoAround; ++j)
                if (lobe.sample(wo, 0.5, 1 - t * t, (j + 0.5) / kAlbedoAround, out) && out.wi.z > 0) sum += out.weight * (2 * t);
        }
        table_[size_t(k)] = std::clamp(max_component(sum) / (kAlbedoRadial * kAlbedoAround), 0.0, 1.0);
    }
}

DirectionalAlbedo::DirectionalAlbedo(std::vector<double> table) : table_(std::move(table)) {
    if (table_.size() != size_t(kNodes))
        throw std::invalid_argument("directional albedo: needs " + std::to_string(kNodes) + " values, got " +
                                    std::to_string(table_.size()));
    for (double e : table_)
        if (!(e >= 0 && e <= 1)) throw std::invalid_argument("directional albedo: values must be in [0, 1]");
}

double DirectionalAlbedo::operator()(double mu) const {
    const double x = std::sqrt(std::clamp(mu, 0.0, 1.0)) * (kAlbedoNodes - 1);
    const int k = std::min(int(x), kAlbedoNodes - 2);
    return table_[size_t(k)] + (x - k) * (table_[size_t(k) + 1] - table_[size_t(k)]);
}

// ---- multiple scattering ----

namespace {

// E of the white isotropic lobe per alpha and shadowing: every surface of a material (an
// anisotropic one is made per surface) and the tints of a textured one share it (10 ms to tabulate).
std::shared_ptr<const DirectionalAlbedo> white_lobe_albedo(double alpha, bool height_correlated) {
    static std::mutex mutex;
    static std::map<std::pair<double, bool>, std::shared_ptr<const DirectionalAlbedo>> made;
    std::lock_guard<std::mutex> lock(mutex);
    auto& e = made[{alpha, height_correlated}];
    if (!e) e = std::make_shared<DirectionalAlbedo>(GgxReflection(alpha, alpha, {1, 1, 1}, 0, false, 0, false, height_correlated));
    return e;
}

}  // namespace

MultipleScattering::MultipleScattering(double alpha_x, double alpha_y, bool height_correlated, const Vec3& f_ss)
    : MultipleScattering(white_lobe_albedo(std::sqrt(alpha_x * alpha_y), height_correlated), f_ss) {}

MultipleScattering::MultipleScattering(std::shared_ptr<const DirectionalAlbedo> e, const Vec3& f_ss) : albedo_(std::move(e)) {
    // E_avg = 2 int_0^1 E(mu) mu dmu (midpoint rule over the table's linear pieces).
    constexpr int kNodes = 1024;
    double e_avg = 0;
    for (int k = 0; k < kNodes; ++k) {
        const double mu = (k + 0.5) / kNodes;
        e_avg += (*albedo_)(mu) * 2 * mu / kNodes;
    }
    auto fms = [e_avg](double f) { return f * e_avg / (1 - f * (1 - e_avg)); };
    fms_ = {fms(f_ss.x), fms(f_ss.y), fms(f_ss.z)};
}

Vec3 MultipleScattering::factor(double mu_o) const {
    // (A GGX lobe's E > 0.3 down to grazing, even at alpha 1; a glass's from inside > 0.1.)
    const double e = std::max((*albedo_)(mu_o), 1e-3);
    return Vec3{1, 1, 1} + fms_ * ((1 - e) / e);
}

// ---- diffuse base under a GGX coat ----

namespace {

// The glossy part S of a layered DiffuseGgx in (38): the coat less what it takes from the base
// along the view, E(mu_o) albedo / pi (the base, D, is the whole albedo / pi). Sampled as the coat.
class LayeredCoat final : public Bsdf {
public:
    LayeredCoat(std::shared_ptr<const GgxReflection> coat, std::shared_ptr<const DirectionalAlbedo> e, const Vec3& albedo)
        : coat_(std::move(coat)), e_(std::move(e)), albedo_(albedo) {}
    Vec3 eval(const Vec3& wo, const Vec3& wi) const override {
        if (wo.z <= 0 || wi.z <= 0) return {0, 0, 0};
        return coat_->eval(wo, wi) - loss(wo);
    }
    double pdf(const Vec3& wo, const Vec3& wi) const override { return coat_->pdf(wo, wi); }
    Vec3 eval_pdf(const Vec3& wo, const Vec3& wi, double& pdf_out) const override {
        const Vec3 f = coat_->eval_pdf(wo, wi, pdf_out);
        return wo.z <= 0 || wi.z <= 0 ? f : f - loss(wo);
    }
    bool sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const override {
        if (!coat_->sample(wo, u0, u1, u2, out)) return false;
        out.weight = eval(wo, out.wi) * (out.wi.z / out.pdf);
        return true;
    }
    std::string name() const override { return "layered_coat"; }
    double lobe_width() const override { return coat_->lobe_width(); }

private:
    Vec3 loss(const Vec3& wo) const { return albedo_ * ((*e_)(wo.z) / kPiD); }
    std::shared_ptr<const GgxReflection> coat_;
    std::shared_ptr<const DirectionalAlbedo> e_;
    Vec3 albedo_;
};

}  // namespace

DiffuseGgx::DiffuseGgx(const Vec3& albedo, double alpha_x, double alpha_y, const Vec3& f0, bool layered, double eta,
                       bool multiscatter, bool height_correlated)
    : albedo_(albedo),
      coat_(std::make_shared<GgxReflection>(alpha_x, alpha_y, f0, 0.0, true, eta, multiscatter, height_correlated)) {
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(albedo[i]) || albedo[i] < 0 || albedo[i] > 1) throw std::invalid_argument("albedo must be in [0, 1]");
    const double d = (albedo.x + albedo.y + albedo.z) / 3, c = (f0.x + f0.y + f0.z) / 3;
    p_diffuse_ = d + c > 0 ? std::clamp(d / (d + c), 0.05, 0.95) : 0.5;
    glossy_ = coat_;
    if (layered) {
        coat_albedo_ = std::make_shared<DirectionalAlbedo>(*coat_);
        glossy_ = std::make_shared<LayeredCoat>(coat_, coat_albedo_, albedo_);
    }
}

Vec3 DiffuseGgx::eval(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return {0, 0, 0};
    return albedo_ * (base_weight(wo.z) / kPiD) + coat_->eval(wo, wi);
}

double DiffuseGgx::pdf(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return 0;
    return p_diffuse_ * wi.z / kPiD + (1 - p_diffuse_) * coat_->pdf(wo, wi);
}

Vec3 DiffuseGgx::eval_pdf(const Vec3& wo, const Vec3& wi, double& pdf_out) const {
    pdf_out = 0;
    if (wo.z <= 0 || wi.z <= 0) return {0, 0, 0};
    double coat_pdf;
    const Vec3 coat = coat_->eval_pdf(wo, wi, coat_pdf);
    pdf_out = p_diffuse_ * wi.z / kPiD + (1 - p_diffuse_) * coat_pdf;
    return albedo_ * (base_weight(wo.z) / kPiD) + coat;
}

bool DiffuseGgx::sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const {
    if (wo.z <= 0) return false;
    if (u0 < p_diffuse_) {  // cosine-weighted
        const double r = std::sqrt(u1), phi = 2 * kPiD * u2;
        out.wi = {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0, 1 - u1))};
    } else if (!coat_->sample(wo, 0, u1, u2, out)) {
        return false;
    }
    out.delta = false;
    const Vec3 f = eval_pdf(wo, out.wi, out.pdf);
    if (!(out.pdf > 0) || out.wi.z <= 0) return false;
    out.weight = f * (out.wi.z / out.pdf);
    return true;
}

// ---- smooth dielectric ----

SmoothDielectric::SmoothDielectric(double eta, const Vec3& reflection_tint, const Vec3& transmission_tint)
    : eta_(eta), reflection_tint_(reflection_tint), transmission_tint_(transmission_tint) {
    check_eta(eta);
    check_tint(reflection_tint, "reflection");
    check_tint(transmission_tint, "transmission");
}

bool SmoothDielectric::sample(const Vec3& wo, double u0, double, double, BsdfSample& out) const {
    if (wo.z == 0) return false;
    const double n_o = index_on_side(wo), n_t = wo.z > 0 ? eta_ : 1.0;
    double cos_t;
    const double c = std::abs(wo.z);
    const double F = fresnel_dielectric(c, n_t / n_o, cos_t);
    out.delta = true;
    if (u0 < F) {
        out.wi = {-wo.x, -wo.y, wo.z};
        out.pdf = F;
        out.weight = reflection_tint_;
    } else {
        const double e = n_o / n_t, side = wo.z > 0 ? 1.0 : -1.0;
        out.wi = -wo * e + Vec3{0, 0, side} * (e * c - cos_t);
        out.pdf = 1 - F;
        out.weight = transmission_tint_ * (e * e);  // radiance scales by (n_o / n_i)^2 across the boundary
    }
    return true;
}

// ---- rough dielectric ----

// Stratified over the visible normals as DirectionalAlbedo (its warp towards GGX's tail), both
// branches of each normal weighed by their Fresnel share: F G / G1(wo) reflected, (1 - F) G /
// G1(wo) transmitted in energy (a smooth boundary's F + (1 - F) = 1). 256 x 64 strata: the
// total internal reflection's edge crosses them (64 x 32 left 0.45% at 78 degrees inside; now
// within 2e-4 of 2M random samples). 0.13 s for a material's two tables.
double RoughDielectric::single_scattering_albedo(const GgxDistribution& D, double n_o, double n_t,
                                                 bool height_correlated, double mu) {
    constexpr int kRadial = 256, kAround = 64;
    mu = std::clamp(mu, 1e-4, 1.0);
    const Vec3 wo{std::sqrt(1 - mu * mu), 0, mu};
    const double g_o = 1 / (1 + D.lambda(wo)), e = n_o / n_t;
    double sum = 0;
    for (int i = 0; i < kRadial; ++i) {
        const double t = 1 - (i + 0.5) / kRadial;
        for (int j = 0; j < kAround; ++j) {
            const Vec3 m = D.sample_visible(wo, 1 - t * t, (j + 0.5) / kAround);
            const double c = dot(wo, m);
            if (c <= 0) continue;
            double cos_t;
            const double F = fresnel_dielectric(c, n_t / n_o, cos_t);
            double weight = 0;
            const Vec3 reflected = m * (2 * c) - wo;
            if (reflected.z > 0) weight += F * D.G(wo, reflected, m, height_correlated);
            if (F < 1) {
                const Vec3 refracted = -wo * e + m * (e * c - cos_t);
                if (refracted.z < 0) weight += (1 - F) * D.G(wo, refracted, m, height_correlated);
            }
            sum += weight / g_o * (2 * t);
        }
    }
    return std::clamp(sum / (kRadial * kAround), 0.0, 1.0);
}

namespace {

// The glass's E from one side per (alpha, indices, shadowing), shared by every surface of a material.
std::shared_ptr<const DirectionalAlbedo> glass_albedo(double alpha, double n_o, double n_t, bool height_correlated) {
    static std::mutex mutex;
    static std::map<std::tuple<double, double, double, bool>, std::shared_ptr<const DirectionalAlbedo>> made;
    std::lock_guard<std::mutex> lock(mutex);
    auto& e = made[{alpha, n_o, n_t, height_correlated}];
    if (!e) {
        std::vector<double> table(DirectionalAlbedo::kNodes);
        for (int k = 0; k < DirectionalAlbedo::kNodes; ++k) {
            const double x = double(k) / (DirectionalAlbedo::kNodes - 1);
            table[size_t(k)] = RoughDielectric::single_scattering_albedo(GgxDistribution{alpha, alpha}, n_o, n_t,
                                                                         height_correlated, x * x);
        }
        e = std::make_shared<DirectionalAlbedo>(std::move(table));
    }
    return e;
}

}  // namespace

RoughDielectric::RoughDielectric(double eta, double alpha_x, double alpha_y, bool multiscatter, bool height_correlated,
                                 bool scale_radiance, const Vec3& reflection_tint, const Vec3& transmission_tint)
    : eta_(eta), D_{alpha_x, alpha_y}, height_correlated_(height_correlated), scale_radiance_(scale_radiance),
      reflection_tint_(reflection_tint), transmission_tint_(transmission_tint) {
    check_eta(eta);
    check_alpha(alpha_x);
    check_alpha(alpha_y);
    check_tint(reflection_tint, "reflection");
    check_tint(transmission_tint, "transmission");
    if (multiscatter) {
        // Cycles reads its table at the isotropic roughness sqrt(alpha_x alpha_y).
        const double alpha = std::sqrt(alpha_x * alpha_y);
        outside_.emplace(glass_albedo(alpha, 1.0, eta, height_correlated), transmission_tint);
        inside_.emplace(glass_albedo(alpha, eta, 1.0, height_correlated), transmission_tint);
    }
}

Vec3 RoughDielectric::branch_weight(const Vec3& wo, const Vec3& wi) const {
    const Vec3& tint = wo.z * wi.z > 0 ? reflection_tint_ : transmission_tint_;
    if (!outside_) return tint;
    return tint * (wo.z > 0 ? *outside_ : *inside_).factor(std::abs(wo.z));
}

// The microfacet normal that refracts wi (below, index n_i) into wo (above, index n_o), facing
// up; false where no facet does (wi in the tangent plane, or not a refraction pair through h).
static bool refraction_half_vector(const Vec3& wo, const Vec3& wi, double n_o, double n_i, Vec3& h) {
    if (wi.z == 0) return false;
    h = -(wo * n_o + wi * n_i);
    const double lh = length(h);
    if (!(lh > 0)) return false;
    h = h / lh;
    if (h.z < 0) h = -h;
    return dot(wo, h) > 0 && dot(wi, h) < 0;
}

double RoughDielectric::eval_up(const Vec3& wo, const Vec3& wi, double n_o, double n_t) const {
    double cos_t;
    if (wi.z > 0) {
        const Vec3 h = normalize(wo + wi);
        const double F = fresnel_dielectric(dot(wo, h), n_t / n_o, cos_t);
        return F * D_.D(h) * shadowing(wo, wi, h) / (4 * wo.z * wi.z);
    }
    const double n_i = n_t;
    Vec3 h;
    if (!refraction_half_vector(wo, wi, n_o, n_i, h)) return 0;
    const double oh = dot(wo, h), ih = dot(wi, h);
    const double F = fresnel_dielectric(oh, n_i / n_o, cos_t);
    const double denom = n_i * ih + n_o * oh;
    // Radiance (n_o^2) or, unscaled by (n_o / n_i)^2, throughput (n_i^2).
    const double n2 = scale_radiance_ ? n_o * n_o : n_i * n_i;
    return std::abs(ih) * oh * n2 * (1 - F) * D_.D(h) * shadowing(wo, wi, h) / (std::abs(wi.z) * wo.z * denom * denom);
}

double RoughDielectric::pdf_up(const Vec3& wo, const Vec3& wi, double n_o, double n_t, bool chosen) const {
    double cos_t;
    if (wi.z > 0) {
        const Vec3 h = normalize(wo + wi);
        const double oh = dot(wo, h);
        if (oh <= 0) return 0;
        const double F = chosen ? fresnel_dielectric(oh, n_t / n_o, cos_t) : 1.0;
        return F * D_.visible_pdf(wo, h) / (4 * oh);
    }
    const double n_i = n_t;
    Vec3 h;
    if (!refraction_half_vector(wo, wi, n_o, n_i, h)) return 0;
    const double oh = dot(wo, h), ih = dot(wi, h);
    const double F = fresnel_dielectric(oh, n_i / n_o, cos_t);
    const double denom = n_i * ih + n_o * oh;
    // Jacobian of refraction: d omega_h / d omega_i = n_i^2 |wi.h| / (n_i wi.h + n_o wo.h)^2.
    return (chosen ? 1 - F : 1.0) * D_.visible_pdf(wo, h) * n_i * n_i * std::abs(ih) / (denom * denom);
}

// Below the surface the microstructure is the mirror image: mirror both directions and swap the
// indices.
Vec3 RoughDielectric::eval(const Vec3& wo, const Vec3& wi) const {
    if (wo.z > 0) return branch_weight(wo, wi) * eval_up(wo, wi, 1.0, eta_);
    if (wo.z < 0) return branch_weight(wo, wi) * eval_up(mirror_z(wo), mirror_z(wi), eta_, 1.0);
    return {0, 0, 0};
}

double RoughDielectric::pdf(const Vec3& wo, const Vec3& wi) const {
    if (wo.z > 0) return pdf_up(wo, wi, 1.0, eta_);
    if (wo.z < 0) return pdf_up(mirror_z(wo), mirror_z(wi), eta_, 1.0);
    return 0;
}

bool RoughDielectric::sample(const Vec3& wo_in, double u0, double u1, double u2, BsdfSample& out) const {
    if (wo_in.z == 0) return false;
    const bool below = wo_in.z < 0;
    const Vec3 wo = below ? mirror_z(wo_in) : wo_in;
    const double n_o = below ? eta_ : 1.0, n_t = below ? 1.0 : eta_;
    const Vec3 m = D_.sample_visible(wo, u1, u2);
    const double c = dot(wo, m);
    if (c <= 0) return false;
    double cos_t;
    const double F = fresnel_dielectric(c, n_t / n_o, cos_t);
    Vec3 wi;
    if (u0 < F) {
        wi = m * (2 * c) - wo;
        if (wi.z <= 0) return false;
    } else {
        const double e = n_o / n_t;
        wi = -wo * e + m * (e * c - cos_t);
        if (wi.z >= 0) return false;
    }
    const double p = pdf_up(wo, wi, n_o, n_t);
    if (!(p > 0)) return false;
    out.wi = below ? mirror_z(wi) : wi;
    out.pdf = p;
    out.delta = false;
    out.weight = branch_weight(wo_in, out.wi) * (eval_up(wo, wi, n_o, n_t) * std::abs(wi.z) / p);
    return true;
}


// Both branches of one microfacet drawn by visible normals: the reflected direction with the
// reflection's density alone, the refracted one with the transmission's (Fresnel's F and 1 - F
// stay in eval, the weights carry them).
void RoughDielectric::sample_branches(const Vec3& wo_in, double, double u1, double u2, BsdfSample* out) const {
    out[0].pdf = out[1].pdf = 0;
    if (wo_in.z == 0) return;
    const bool below = wo_in.z < 0;
    const Vec3 wo = below ? mirror_z(wo_in) : wo_in;
    const double n_o = below ? eta_ : 1.0, n_t = below ? 1.0 : eta_;
    const Vec3 m = D_.sample_visible(wo, u1, u2);
    const double c = dot(wo, m);
    if (c <= 0) return;
    double cos_t;
    const double F = fresnel_dielectric(c, n_t / n_o, cos_t), e = n_o / n_t;
    const Vec3 branch[2] = {m * (2 * c) - wo, -wo * e + m * (e * c - cos_t)};
    for (int k = 0; k < 2; ++k) {
        const Vec3& wi = branch[k];
        if (k == 0 ? wi.z <= 0 : (F >= 1 || wi.z >= 0)) continue;
        const double p = pdf_up(wo, wi, n_o, n_t, false);
        if (!(p > 0)) continue;
        out[k].wi = below ? mirror_z(wi) : wi;
        out[k].pdf = p;
        out[k].delta = false;
        out[k].weight = branch_weight(wo_in, out[k].wi) * (eval_up(wo, wi, n_o, n_t) * std::abs(wi.z) / p);
    }
}

Vec3 RoughDielectric::eval_gather_pdf(const Vec3& wo, const Vec3& wi, double& pdf_out) const {
    pdf_out = 0;
    if (wo.z == 0) return {0, 0, 0};
    const bool below = wo.z < 0;
    const Vec3 o = below ? mirror_z(wo) : wo, i = below ? mirror_z(wi) : wi;
    const double n_o = below ? eta_ : 1.0, n_t = below ? 1.0 : eta_;
    pdf_out = pdf_up(o, i, n_o, n_t, false);
    return branch_weight(wo, wi) * eval_up(o, i, n_o, n_t);
}

}  // namespace bsgi
