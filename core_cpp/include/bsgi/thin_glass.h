// A window pane: a thin sheet of smooth glass. Light passes straight through it (the sheet's
// two refractions cancel, its offset is negligible), attenuated by Fresnel reflection at its
// faces and coloured by its glass's tints, and a little is reflected specularly. It needs no
// radiance spline: rays cross it.
#pragma once
#include <algorithm>
#include <cmath>
#include <optional>

#include "bsgi/vec3.h"

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
    // What visibility rays (direct light, suns, the world) get instead of the Fresnel factor and
    // the tint, if set: Cycles' "Light Path" trick for windows makes the glass a Transparent BSDF
    // of that colour for shadow rays, and Cycles defines what the scene means.
    std::optional<Vec3> shadow;
    // The glass's colour on the light it passes and on the light it reflects, per crossing of
    // the pane (of each face of a slab), as Cycles tints each glass event (bsdf.h RoughDielectric's).
    Vec3 transmission_tint{1, 1, 1}, reflection_tint{1, 1, 1};

    // Reflectance for a ray meeting the surface at |cos| = cos_i (either side: a parallel slab
    // meets the second interface at the refracted angle, whose reflectance is the first one's).
    // A sheet sums the internal reflections, r' = r + t r t + t r^3 t + ... = 2r / (1 + r)
    // (Mitsuba 3's thindielectric).
    double reflectance(double cos_i) const {
        const double r = fresnel_dielectric(cos_i, eta);
        return one_interface ? r : 2 * r / (1 + r);
    }
    // The straight pass-through, 1 - reflectance (no absorption) times the tint (the reflected
    // light is reflectance times reflection_tint).
    Vec3 transmittance(double cos_i) const { return transmission_tint * (1 - reflectance(cos_i)); }
    Vec3 shadow_transmittance(double cos_i) const { return shadow ? *shadow : transmittance(cos_i); }
    // Whether it passes or reflects some colours more than others (light through it is then RGB).
    bool coloured() const {
        auto grey = [](const Vec3& c) { return c.x == c.y && c.y == c.z; };
        return !grey(transmission_tint) || !grey(reflection_tint) || (shadow && !grey(*shadow));
    }
};

}  // namespace bsgi
