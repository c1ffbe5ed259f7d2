// A surface's solved outgoing radiance (paper 3.1-3.3, 4.3): a 2D spline D(u, v) where the
// surface is diffuse, a 4D spline L(u, v, alpha, beta) over the hemisphere map (20)-(22) where
// it is glossy, and a second spline for the lower hemisphere where it transmits or where light
// reaches an opaque surface's back side.
#pragma once
#include <array>
#include <cmath>
#include <optional>
#include <string>

#include "bsgi/hemisphere_map.h"
#include "bsgi/normal_map.h"
#include "bsgi/scene.h"
#include "bsgi/tensor_spline.h"

namespace bsgi {

// Radiance of one side's spline at (u, v) along `local`: a 2D spline ignores the direction, a 4D
// one takes it through the inverse hemisphere map (of |z|: the caller has chosen the side).
inline Vec3 evaluate_side(Representation kind, const HemisphereMap& map, const TensorSpline& s, double u, double v,
                          const Vec3& local) {
    double out[3];
    if (kind == Representation::Diffuse) {
        const double x[2] = {u, v};
        s.evaluate(x, out);
    } else {
        double x[4] = {u, v, 0, 0};
        map.to_disc(local.x, local.y, std::abs(local.z), x + 2);
        s.evaluate(x, out);
    }
    return {out[0], out[1], out[2]};
}

struct SurfaceRadiance {
    Representation kind = Representation::Diffuse;
    HemisphereMap map{1.0};
    TensorSpline upper;                   // leaving the front side (the glossy S of (38) if decomposed)
    std::optional<TensorSpline> lower;    // leaving the back side, where it was solved (S's if decomposed)
    std::optional<TensorSpline> diffuse;  // D(u, v) of (38), emission included, if decomposed
    std::optional<TensorSpline> lower_diffuse;  // D of the back side, if decomposed and solved there
    // Textured surfaces: the diffuse spline (upper if diffuse, else D) holds irradiance / pi, the
    // smooth factor, and the albedo texture its detail; the emission is then the emission
    // texture (constant emission as one texel), not part of the spline.
    std::shared_ptr<const Texture> albedo, emission;
    // A textured base under a layered coat: how its texels show along the view.
    std::optional<CoatedBase> coat;
    // A textured GGX colour f0 (Scene::set_specular_texture): upper and lower hold the radiance at
    // f0 = 1, tint_zero and lower_tint_zero at f0 = 0 (Schlick's rise towards grazing angles), and
    // the surface shows specular x the first + (1 - specular) x the second: (38) with the texture as
    // the detail factor of the smooth splines.
    std::optional<TensorSpline> tint_zero, lower_tint_zero;
    std::shared_ptr<const Texture> specular;
    bool two_sided_emission = false;  // the emission leaves the back side too

    // A Lambertian surface under a normal map: upper (and lower) are over its bumped normal.
    std::shared_ptr<const Texture> normals;

    // Radiance leaving (u, v) along `local` (a direction in the frame (1)-(3), any length).
    Vec3 evaluate(double u, double v, const Vec3& along) const {
        const Vec3 local = normals ? (along.z < 0 ? -bumped_normal(*normals, u, v) : bumped_normal(*normals, u, v)) : along;
        const bool detail = kind == Representation::Diffuse || normals;  // the albedo texture multiplies the spline
        if (local.z < 0) {
            Vec3 L = lower ? tinted(evaluate_side(kind, map, *lower, u, v, local), lower_tint_zero, u, v, local) : Vec3{0, 0, 0};
            if (lower_diffuse) L += textured(evaluate_side(Representation::Diffuse, map, *lower_diffuse, u, v, local), u, v, local);
            else if (detail) L = textured(L, u, v, local);
            if (emission && two_sided_emission) L += emission->at(u, v);
            return L;
        }
        Vec3 L = tinted(evaluate_side(kind, map, upper, u, v, local), tint_zero, u, v, local);
        if (diffuse) L += textured(evaluate_side(Representation::Diffuse, map, *diffuse, u, v, local), u, v, local);
        else if (detail) L = textured(L, u, v, local);
        if (emission) L += emission->at(u, v);
        return L;
    }
    Vec3 textured(const Vec3& smooth, double u, double v, const Vec3& local) const {
        if (!albedo) return smooth;
        const Vec3 t = albedo->at(u, v);
        return smooth * (coat ? coat->texel(t, std::abs(local.z) / length(local)) : t);
    }
    Vec3 tinted(const Vec3& white, const std::optional<TensorSpline>& black, double u, double v, const Vec3& local) const {
        if (!specular) return white;
        const Vec3 t = specular->at(u, v);
        return white * t + (black ? evaluate_side(kind, map, *black, u, v, local) * (Vec3{1, 1, 1} - t) : Vec3{0, 0, 0});
    }
};

// What the solver chose for a surface, and why.
struct SurfaceReport {
    std::string name;
    // "diffuse 2D", "glossy 4D", "glossy 4D + transmission", "emitter"; opaque surfaces add the
    // sides solved other than the front alone: ", both sides", ", back side", ", no side lit".
    std::string representation;
    std::vector<int> shape;      // coefficients per dimension of the upper spline
    std::string reason;
    // Relative RMS error of the radiance leaving the surface (RGB, over its visible points,
    // uniform in (u, v), and cosine-distributed directions) against its mean radiance: the
    // spline's own error (against the gathered radiance where no node sits), the error of the
    // splines the gather read and the bounces not taken, added in quadrature
    // (SolverSettings::estimate_error); a sample (another error_checks_seed, another estimate).
    // NaN where not estimated (emitters, panes) and where no viewer sees the surface (every check
    // point's directions meet the back of an opaque surface: a book's face pressed against a
    // shelf); 0 where it is seen and gets no light.
    double estimated_error = std::nan("");
    // Its parts, in quadrature: the fit of the surface's own spline, the splines the gather read,
    // the integration (of the spline's own error, what doubled integration nodes change), the
    // bounces' tail (what refining the surface's own knots can lower is the first).
    std::array<double, 4> error_parts{std::nan(""), std::nan(""), std::nan(""), std::nan("")};
};

}  // namespace bsgi
