// Small 3-vector and orthonormal frame used throughout the core.
#pragma once
#include <cmath>

namespace bsgi {

struct Vec3 {
    double x = 0, y = 0, z = 0;
    constexpr Vec3() = default;
    constexpr Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
    constexpr Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    constexpr Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    constexpr Vec3 operator-() const { return {-x, -y, -z}; }
    constexpr Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    constexpr Vec3 operator/(double s) const { return {x / s, y / s, z / s}; }
    constexpr Vec3 operator*(const Vec3& o) const { return {x * o.x, y * o.y, z * o.z}; }  // per channel
    Vec3& operator+=(const Vec3& o) { x += o.x; y += o.y; z += o.z; return *this; }
    Vec3& operator-=(const Vec3& o) { x -= o.x; y -= o.y; z -= o.z; return *this; }
    Vec3& operator*=(double s) { x *= s; y *= s; z *= s; return *this; }
    double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
};

inline constexpr Vec3 operator*(double s, const Vec3& v) { return v * s; }
inline constexpr double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalize(const Vec3& a) { return a / length(a); }
inline bool is_finite(const Vec3& a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }
inline bool is_zero(const Vec3& a) { return a.x == 0 && a.y == 0 && a.z == 0; }
inline double max_component(const Vec3& a) { return std::fmax(a.x, std::fmax(a.y, a.z)); }

// Orthonormal frame (x, y, z) of paper eqs. (1)-(3): z is the surface normal.
struct Frame {
    Vec3 x{1, 0, 0}, y{0, 1, 0}, z{0, 0, 1};
    Vec3 to_local(const Vec3& d) const { return {dot(d, x), dot(d, y), dot(d, z)}; }
    Vec3 to_world(const Vec3& d) const { return x * d.x + y * d.y + z * d.z; }

    // Any orthonormal frame around unit normal n (Duff et al. 2017), used where s_u vanishes.
    static Frame from_normal(const Vec3& n) {
        const double sign = std::copysign(1.0, n.z);
        const double a = -1.0 / (sign + n.z);
        const double b = n.x * n.y * a;
        Frame f;
        f.x = {1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x};
        f.y = {b, sign + n.y * n.y * a, -n.y};
        f.z = n;
        return f;
    }
};

}  // namespace bsgi
