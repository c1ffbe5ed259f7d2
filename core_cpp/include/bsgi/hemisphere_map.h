// The disc-to-hemisphere map of paper section 3.2, (20)-(22): the angular spline parameters
// (alpha, beta) live in the disc of radius R <= 1 in the tangent plane; a point is lifted to the
// paraboloid z = 1 - r^2 and moved out horizontally to the unit hemisphere. Points outside the
// disc are first pulled in radially to radius R, so the map is defined on the whole plane and
// directions never reach beyond the polar angle theta_max = 2 asin(R / sqrt 2).
//
// Defined behaviour at the special places:
// - pole: (0, 0) <-> (0, 0, 1), phi = 0 there;
// - rim and beyond: directions with theta > theta_max, including those below the horizon, go to
//   the rim point of their azimuth; the straight-down direction (0, 0, -1) goes to (R, 0);
// - a zero, infinite or NaN input gives NaN.
#pragma once
#include <cmath>

// The evaluation kernels are compiled for several instruction sets (target_clones); the map
// must be inlined into each of them rather than called in its baseline form.
#if defined(__GNUC__)
#define BSGI_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define BSGI_ALWAYS_INLINE inline
#endif

namespace bsgi {

class HemisphereMap {
public:
    // 0 < R <= 1; throws std::invalid_argument otherwise.
    explicit HemisphereMap(double R);

    // The R whose cone is exactly theta <= pi/2 - delta: R = sqrt(1 - sin delta). The paper's
    // R ~ sqrt(1 - delta) is its first-order form; it cuts slightly inside the cone.
    static HemisphereMap for_max_angle(double delta);

    double radius() const { return R_; }
    double max_theta() const { return 2 * std::asin(R_ / std::sqrt(2.0)); }

    // (alpha, beta) -> unit direction (x, y, z) in the local frame, (20)-(22) after the pull-in.
    // sqrt(1 - z^2) / r = sqrt(2 - r^2), so nothing is singular at the pole. Infinite or NaN
    // input gives NaN.
    BSGI_ALWAYS_INLINE void to_direction(double alpha, double beta, double* xyz) const {
        double r2 = alpha * alpha + beta * beta;
        const bool valid = r2 <= 1.7976931348623157e308;  // not infinite or NaN
        if (r2 > R2_) {
            const double s = R_ / std::sqrt(r2);
            alpha *= s, beta *= s, r2 = R2_;
        }
        const double f = std::sqrt(2 - r2);
        xyz[0] = valid ? f * alpha : NAN, xyz[1] = valid ? f * beta : NAN, xyz[2] = valid ? 1 - r2 : NAN;
    }

    // Inverse: a local direction (any positive length n) -> (alpha, beta) in the disc of radius R.
    // For the unit direction, r^2 = 1 - z and alpha = x / sqrt(1 + z); unnormalised that is
    // alpha = x / sqrt(q) with q = n (n + z), and the cone test rho^2 <= R^2 (1 + z) becomes
    // rho^2 <= R^2 q: no division, exact at the rim and below the horizon. Outside the cone
    // alpha = R x / rho = x / sqrt(rho^2 / R^2). Branch-free (selects), so that a loop over
    // directions vectorises: two square roots and a division per direction.
    BSGI_ALWAYS_INLINE void to_disc(double x, double y, double z, double* ab) const {
        const double rho2 = x * x + y * y;
        const double n = std::sqrt(rho2 + z * z);
        const double q = n * (n + z);
        const bool inside = rho2 <= R2_ * q && q > 0;
        const double s = 1 / std::sqrt(inside ? q : rho2 * inv_R2_);
        // Straight down (rho = 0, q = 0) has no azimuth: it goes to (R, 0).
        const bool down = !inside && rho2 == 0;
        const bool valid = n > 0 && n <= 1.7976931348623157e308;  // not zero, infinite or NaN
        ab[0] = valid ? (down ? R_ : x * s) : NAN;
        ab[1] = valid ? (down ? 0.0 : y * s) : NAN;
    }

    // Local spherical angles (4), (5) of to_direction(alpha, beta): theta = 2 asin(r / sqrt 2)
    // (accurate near the pole, unlike acos(1 - r^2)), phi = atan2(beta, alpha) in [-pi, pi].
    void angles(double alpha, double beta, double* theta_phi) const {
        const double r = std::fmin(std::sqrt(alpha * alpha + beta * beta), R_);
        theta_phi[0] = std::isnan(alpha + beta) ? NAN : 2 * std::asin(r / std::sqrt(2.0));
        theta_phi[1] = std::atan2(beta, alpha);
    }

private:
    double R_, R2_, inv_R2_;
};

}  // namespace bsgi
