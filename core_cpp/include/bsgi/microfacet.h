// The GGX (Trowbridge-Reitz) microfacet distribution with Smith shadowing, and Fresnel terms.
// Directions are in the local frame of (1)-(3): z is the normal, x along s_u.
#pragma once
#include <algorithm>
#include <cmath>

#include "bsgi/vec3.h"

namespace bsgi {

constexpr double kPiD = 3.14159265358979323846;

// Fresnel reflectance of a smooth dielectric boundary for light arriving at cosine `cos_i`
// (> 0) from the side of index n1, where eta = n2 / n1. Sets cos_t to the cosine of the
// refracted direction (0 under total internal reflection, where the reflectance is 1).
inline double fresnel_dielectric(double cos_i, double eta, double& cos_t) {
    cos_i = std::min(std::abs(cos_i), 1.0);
    const double sin_t2 = (1 - cos_i * cos_i) / (eta * eta);
    if (sin_t2 >= 1) {
        cos_t = 0;
        return 1;
    }
    cos_t = std::sqrt(1 - sin_t2);
    const double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    const double rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// A dielectric's Fresnel curve remapped to start at f0 (per channel) and rise to 1 at grazing:
// f0 + (1 - f0) (F(cos, eta) - F0(eta)) / (1 - F0(eta)), F0(eta) = ((eta - 1) / (eta + 1))^2. With
// f0 = F0(eta) it is the dielectric's own reflectance (Cycles' Principled BSDF: its generalized
// Schlick with the real Fresnel's exponent, which differs from Schlick's by a fifth at 60 degrees).
inline Vec3 fresnel_dielectric_remapped(const Vec3& f0, double cos, double eta) {
    double cos_t;
    const double f0_eta = (eta - 1) * (eta - 1) / ((eta + 1) * (eta + 1));
    const double rise = (fresnel_dielectric(cos, eta, cos_t) - f0_eta) / (1 - f0_eta);
    return f0 + (Vec3{1, 1, 1} - f0) * std::clamp(rise, 0.0, 1.0);
}

// Schlick's approximation F0 + (1 - F0)(1 - cos)^5, per channel.
inline Vec3 fresnel_schlick(const Vec3& f0, double cos) {
    const double c = std::clamp(1 - std::abs(cos), 0.0, 1.0);
    const double c5 = c * c * c * c * c;
    return f0 + (Vec3{1, 1, 1} - f0) * c5;
}

// Anisotropic GGX: roughness alpha_x along x (s_u), alpha_y along y.
struct GgxDistribution {
    double ax, ay;

    // D(m): microfacet normals per unit solid angle per unit macro area (projected), for m in
    // either hemisphere (the distribution seen from below is the mirror image).
    double D(const Vec3& m) const {
        const double cz = m.z;
        if (cz == 0) return 0;
        const double x = m.x / ax, y = m.y / ay;
        const double s = x * x + y * y + cz * cz;
        return 1.0 / (kPiD * ax * ay * s * s);
    }
    // Smith's Lambda(w): its projected-roughness form for GGX.
    double lambda(const Vec3& w) const {
        const double cz2 = w.z * w.z;
        if (cz2 <= 0) return 1e300;
        const double a2t2 = (ax * ax * w.x * w.x + ay * ay * w.y * w.y) / cz2;
        return 0.5 * (std::sqrt(1 + a2t2) - 1);
    }
    // Masking of direction w by facets of normal m: zero when w sees m's back.
    double G1(const Vec3& w, const Vec3& m) const {
        if (dot(w, m) * w.z * m.z <= 0) return 0;
        return 1.0 / (1 + lambda(w));
    }
    // Masking and shadowing together in Smith's height-correlated form (Heitz 2014; Cycles'):
    // 1 / (1 + Lambda(wo) + Lambda(wi)), zero where either direction sees m's back. The
    // separable product G1(wo, m) G1(wi, m) (Mitsuba's) shadows more at grazing angles.
    double G2(const Vec3& wo, const Vec3& wi, const Vec3& m) const {
        if (dot(wo, m) * wo.z * m.z <= 0 || dot(wi, m) * wi.z * m.z <= 0) return 0;
        return 1.0 / (1 + lambda(wo) + lambda(wi));
    }
    // Cycles' G2 (height_correlated) or Mitsuba's separable G1(wo, m) G1(wi, m).
    double G(const Vec3& wo, const Vec3& wi, const Vec3& m, bool height_correlated) const {
        return height_correlated ? G2(wo, wi, m) : G1(wo, m) * G1(wi, m);
    }
    // Density of visible normals seen from w (w.z > 0, m.z > 0): G1(w, m) <w, m> D(m) / w.z.
    double visible_pdf(const Vec3& w, const Vec3& m) const {
        const double wm = dot(w, m);
        if (wm <= 0 || w.z <= 0) return 0;
        return G1(w, m) * wm * D(m) / w.z;
    }
    // A normal drawn with visible_pdf(w, .) from two uniform numbers (Heitz 2018): stretch the
    // view to the unit-roughness configuration, sample the projected hemisphere, unstretch.
    Vec3 sample_visible(const Vec3& w, double u1, double u2) const {
        const Vec3 vh = normalize(Vec3{ax * w.x, ay * w.y, w.z});
        const double len2 = vh.x * vh.x + vh.y * vh.y;
        const Vec3 t1 = len2 > 0 ? Vec3{-vh.y, vh.x, 0} / std::sqrt(len2) : Vec3{1, 0, 0};
        const Vec3 t2 = cross(vh, t1);
        const double r = std::sqrt(u1), phi = 2 * kPiD * u2;
        const double p1 = r * std::cos(phi);
        double p2 = r * std::sin(phi);
        const double s = 0.5 * (1 + vh.z);
        p2 = (1 - s) * std::sqrt(std::max(0.0, 1 - p1 * p1)) + s * p2;
        const Vec3 nh = t1 * p1 + t2 * p2 + vh * std::sqrt(std::max(0.0, 1 - p1 * p1 - p2 * p2));
        return normalize(Vec3{ax * nh.x, ay * nh.y, std::max(1e-12, nh.z)});
    }
};

}  // namespace bsgi
