// Lambert (and about a bumped normal), normalised Phong, Ashikhmin-Shirley, emission.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "bsgi/bsdf.h"

namespace bsgi {

namespace {

constexpr double kInvPi = 1.0 / kPiD;

double mean(const Vec3& a) { return (a.x + a.y + a.z) / 3; }

void check_reflectance(const Vec3& c, const char* what) {
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(c[i]) || c[i] < 0 || c[i] > 1)
            throw std::invalid_argument(std::string(what) + " must be finite and in [0, 1]");
}

void check_exponent(double n, const char* what) {
    if (!std::isfinite(n) || n < 0 || n > 1e6) throw std::invalid_argument(std::string(what) + " must be in [0, 1e6]");
}

// Cosine-weighted direction about +z: density cos(theta) / pi.
Vec3 cosine_hemisphere(double u1, double u2) {
    const double r = std::sqrt(u1), phi = 2 * kPiD * u2;
    return {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0, 1 - u1))};
}

bool finish(const Bsdf& b, const Vec3& wo, const Vec3& wi, BsdfSample& out) {
    out.wi = wi;
    out.delta = false;
    out.pdf = b.pdf(wo, wi);
    if (!(out.pdf > 0)) return false;
    out.weight = b.eval(wo, wi) * (std::abs(wi.z) / out.pdf);
    return true;
}

}  // namespace

// ---- Lambert ----

Lambert::Lambert(const Vec3& albedo) : albedo_(albedo) { check_reflectance(albedo, "Lambert albedo"); }

Vec3 Lambert::eval(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return {0, 0, 0};
    return albedo_ * kInvPi;
}

double Lambert::pdf(const Vec3& wo, const Vec3& wi) const { return (wo.z <= 0 || wi.z <= 0) ? 0 : wi.z * kInvPi; }

bool Lambert::sample(const Vec3& wo, double, double u1, double u2, BsdfSample& out) const {
    if (wo.z <= 0) return false;
    return finish(*this, wo, cosine_hemisphere(u1, u2), out);
}

// ---- Lambert about a bumped normal ----

BumpedLambert::BumpedLambert(const Vec3& albedo, bool bump_correction) : albedo_(albedo), bump_correction_(bump_correction) {
    check_reflectance(albedo, "BumpedLambert albedo");
}

double BumpedLambert::shadowing(double cos_n, double cos_i) const {
    // As Cycles' bump_shadowing_term (closure/bsdf.h), its float thresholds included.
    if (!bump_correction_ || cos_n >= 1 || cos_i >= 1) return 1;
    if (cos_i < 1e-6) return 0;
    const double alpha2 = std::clamp(0.125 * (1 / (cos_n * cos_n) - 1), 0.0, 1.0);
    const double lambda = 0.5 * (std::sqrt(1 + alpha2 * (1 / (cos_i * cos_i) - 1)) - 1);
    return 1 / (1 + lambda);
}

Vec3 BumpedLambert::eval(const Vec3& n, const Vec3& wi) const {
    const double cos_bumped = dot(n, wi);
    if (n.z <= 0 || wi.z <= 0 || cos_bumped <= 0) return {0, 0, 0};
    // Without the cosine to z that the gather multiplies by: the bumped normal's instead.
    return albedo_ * (kInvPi * cos_bumped / wi.z * shadowing(n.z, wi.z));
}

double BumpedLambert::pdf(const Vec3& n, const Vec3& wi) const {
    return (n.z <= 0 || wi.z <= 0) ? 0 : std::max(dot(n, wi), 0.0) * kInvPi;
}

bool BumpedLambert::sample(const Vec3& n, double, double u1, double u2, BsdfSample& out) const {
    if (n.z <= 0) return false;
    const Vec3 wi = Frame::from_normal(n).to_world(cosine_hemisphere(u1, u2));
    if (wi.z <= 0) return false;
    return finish(*this, n, wi, out);
}

// ---- normalised Phong ----

NormalizedPhong::NormalizedPhong(const Vec3& kd, const Vec3& ks, double exponent) : kd_(kd), ks_(ks), n_(exponent) {
    check_reflectance(kd, "Phong kd");
    check_reflectance(ks, "Phong ks");
    check_reflectance(kd + ks, "Phong kd + ks");
    check_exponent(exponent, "Phong exponent");
    const double total = mean(kd) + mean(ks);
    p_specular_ = total > 0 ? mean(ks) / total : 0.5;
}

Vec3 NormalizedPhong::eval(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return {0, 0, 0};
    const Vec3 mirror{-wo.x, -wo.y, wo.z};
    const double c = std::max(0.0, dot(wi, mirror));
    return kd_ * kInvPi + ks_ * ((n_ + 2) / (2 * kPiD) * std::pow(c, n_));
}

double NormalizedPhong::pdf(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return 0;
    const Vec3 mirror{-wo.x, -wo.y, wo.z};
    const double c = std::max(0.0, dot(wi, mirror));
    return (1 - p_specular_) * wi.z * kInvPi + p_specular_ * (n_ + 1) / (2 * kPiD) * std::pow(c, n_);
}

bool NormalizedPhong::sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const {
    if (wo.z <= 0) return false;
    Vec3 wi;
    if (u0 < p_specular_) {
        // cos(alpha) has density (n + 1) cos^n about the mirror direction.
        const double ca = std::pow(u1, 1 / (n_ + 1)), sa = std::sqrt(std::max(0.0, 1 - ca * ca)), phi = 2 * kPiD * u2;
        wi = Frame::from_normal(Vec3{-wo.x, -wo.y, wo.z}).to_world({sa * std::cos(phi), sa * std::sin(phi), ca});
        if (wi.z <= 0) return false;
    } else {
        wi = cosine_hemisphere(u1, u2);
    }
    return finish(*this, wo, wi, out);
}

// ---- Ashikhmin-Shirley ----

AshikhminShirley::AshikhminShirley(const Vec3& rd, const Vec3& rs, double nu, double nv) : rd_(rd), rs_(rs), nu_(nu), nv_(nv) {
    check_reflectance(rd, "Ashikhmin-Shirley rd");
    check_reflectance(rs, "Ashikhmin-Shirley rs");
    check_exponent(nu, "Ashikhmin-Shirley nu");
    check_exponent(nv, "Ashikhmin-Shirley nv");
    // Pick lobes roughly by their albedo (the specular one grows to 1 at grazing angles).
    const double s = mean(rs), d = mean(rd) * (1 - s);
    p_specular_ = std::clamp(s + d > 0 ? s / (s + d) : 0.5, 0.1, 0.9);
}

double AshikhminShirley::half_vector_pdf(const Vec3& h) const {
    // sqrt((nu + 1)(nv + 1)) / (2 pi) (n.h)^((nu h_x^2 + nv h_y^2) / (1 - (n.h)^2))
    if (h.z <= 0) return 0;
    const double s2 = 1 - h.z * h.z;
    const double e = s2 > 1e-14 ? (nu_ * h.x * h.x + nv_ * h.y * h.y) / s2 : 0.0;
    return std::sqrt((nu_ + 1) * (nv_ + 1)) / (2 * kPiD) * (s2 > 1e-14 ? std::pow(h.z, e) : 1.0);
}

Vec3 AshikhminShirley::eval(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return {0, 0, 0};
    const Vec3 h = normalize(wo + wi);
    const double kh = dot(wi, h);
    // rho_s = p_h(h) F(k.h) / (4 (k.h) max(cos_i, cos_o)), p_h the half-vector density.
    const Vec3 specular = fresnel_schlick(rs_, kh) * (half_vector_pdf(h) / (4 * kh * std::max(wi.z, wo.z)));
    auto lobe = [](double c) {
        const double x = 1 - 0.5 * c;
        return 1 - x * x * x * x * x;
    };
    const Vec3 diffuse = rd_ * (Vec3{1, 1, 1} - rs_) * (28.0 / (23.0 * kPiD) * lobe(wi.z) * lobe(wo.z));
    return specular + diffuse;
}

double AshikhminShirley::pdf(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return 0;
    const Vec3 h = normalize(wo + wi);
    return p_specular_ * half_vector_pdf(h) / (4 * dot(wo, h)) + (1 - p_specular_) * wi.z * kInvPi;
}

bool AshikhminShirley::sample(const Vec3& wo, double u0, double u1, double u2, BsdfSample& out) const {
    if (wo.z <= 0) return false;
    Vec3 wi;
    if (u0 < p_specular_) {
        // Half vector: tan(phi) = sqrt((nu+1)/(nv+1)) tan(pi xi / 2) in each quadrant,
        // cos(theta) = (1 - xi')^(1 / (nu cos^2 phi + nv sin^2 phi + 1)).
        const double q = std::floor(4 * u1), r = 4 * u1 - q;
        double phi = std::atan(std::sqrt((nu_ + 1) / (nv_ + 1)) * std::tan(0.5 * kPiD * r));
        if (q == 1) phi = kPiD - phi;
        else if (q == 2) phi = kPiD + phi;
        else if (q >= 3) phi = 2 * kPiD - phi;
        const double c = std::cos(phi), s = std::sin(phi);
        const double e = nu_ * c * c + nv_ * s * s;
        const double ct = std::pow(1 - u2, 1 / (e + 1)), st = std::sqrt(std::max(0.0, 1 - ct * ct));
        const Vec3 h{st * c, st * s, ct};
        const double oh = dot(wo, h);
        if (oh <= 0) return false;
        wi = h * (2 * oh) - wo;
        if (wi.z <= 0) return false;
    } else {
        wi = cosine_hemisphere(u1, u2);
    }
    return finish(*this, wo, wi, out);
}

// ---- emission ----

Emission::Emission(const Vec3& radiance, bool two_sided) : radiance_(radiance), two_sided_(two_sided) {
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(radiance[i]) || radiance[i] < 0) throw std::invalid_argument("emitted radiance must be finite and >= 0");
}

Vec3 Emission::eval(const Vec3& w) const {
    return (w.z > 0 || (two_sided_ && w.z < 0)) ? radiance_ : Vec3{0, 0, 0};
}

double Emission::pdf(const Vec3& w) const {
    if (w.z > 0) return (two_sided_ ? 0.5 : 1.0) * w.z * kInvPi;
    if (two_sided_ && w.z < 0) return -0.5 * w.z * kInvPi;
    return 0;
}

bool Emission::sample(double u0, double u1, double u2, Vec3& w, double& p) const {
    w = cosine_hemisphere(u1, u2);
    if (two_sided_ && u0 < 0.5) w.z = -w.z;
    p = pdf(w);
    return p > 0;
}

}  // namespace bsgi
