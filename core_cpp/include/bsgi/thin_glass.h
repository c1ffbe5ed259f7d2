// A window pane: a thin sheet of smooth glass. Light passes straight through it (the sheet's
// two refractions cancel, its offset is negligible), attenuated by Fresnel reflection at its
// faces, and a little is reflected specularly. It needs no radiance spline: rays cross it.
#pragma once
#include <algorithm>
#include <cmath>

namespace bsgi {

// Fresnel reflectance of unpolarised light at a smooth interface, for cos_i = |cos| of the
// angle of incidence and the relative index eta (> 1: entering the denser medium).
inline double fresnel_dielectric(double cos_i, double eta) {
    cos_i = std::clamp(std::abs(cos_i), 0.0, 1.0);
    const double sin_t2 = (1 - cos_i * cos_i) / (eta * eta);
    if (sin_t2 >= 1) return 1;  // total internal reflection
    const double cos_t = std::sqrt(1 - sin_t2);
    const double rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    const double rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

struct ThinGlass {
    double eta = 1.5;  // index of the glass against the air around it (>= 1)
    // One face of a thin closed slab (a solidified pane): each face is one interface, and a ray
    // crossing both gets (1 - R)^2, within R^2 of the sheet's factor below.
    bool one_interface = false;
    // What visibility rays (direct light, suns, the world) get instead of the Fresnel factor,
    // if >= 0: Cycles' "Light Path" trick for windows makes the glass a Transparent BSDF of that
    // colour for shadow rays, and Cycles defines what the scene means.
    double shadow = -1;

    // Reflectance for a ray meeting the surface at |cos| = cos_i (either side: a parallel slab
    // meets the second interface at the refracted angle, whose reflectance is the first one's).
    // A sheet sums the internal reflections, r' = r + t r t + t r^3 t + ... = 2r / (1 + r)
    // (Mitsuba 3's thindielectric).
    double reflectance(double cos_i) const {
        const double r = fresnel_dielectric(cos_i, eta);
        return one_interface ? r : 2 * r / (1 + r);
    }
    // The straight pass-through, 1 - reflectance (no absorption).
    double transmittance(double cos_i) const { return 1 - reflectance(cos_i); }
    double shadow_transmittance(double cos_i) const { return shadow >= 0 ? shadow : transmittance(cos_i); }
};

}  // namespace bsgi
