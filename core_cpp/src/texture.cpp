#include "bsgi/texture.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bsgi {

Texture::Texture(int width, int height, std::vector<float> rgb, const std::string& what, bool at_most_one)
    : width_(width), height_(height), rgb_(std::move(rgb)) {
    if (width < 1 || height < 1 || rgb_.size() != size_t(width) * height * 3)
        throw std::invalid_argument(what + " must be an image of shape (height, width, 3) with at least one texel");
    for (float x : rgb_) {
        if (!std::isfinite(x) || x < 0 || (at_most_one && x > 1))
            throw std::invalid_argument(what + " must be finite and in " + (at_most_one ? "[0, 1]" : "[0, inf)"));
        max_ = std::max(max_, double(x));
    }
    const size_t w1 = size_t(width) + 1;
    sat_.assign((size_t(height) + 1) * w1 * 3, 0.0);
    for (int r = 0; r < height; ++r)
        for (int c = 0; c < width; ++c)
            for (int k = 0; k < 3; ++k)
                sat_[((r + 1) * w1 + c + 1) * 3 + k] = rgb_[(size_t(r) * width + c) * 3 + k] + sat_[(r * w1 + c + 1) * 3 + k] +
                                                       sat_[((r + 1) * w1 + c) * 3 + k] - sat_[(r * w1 + c) * 3 + k];
    mean_ = integral(width, height) / (double(width) * height);
}

Vec3 Texture::texel(int c, int r) const {
    c = std::clamp(c, 0, width_ - 1), r = std::clamp(r, 0, height_ - 1);
    const float* t = &rgb_[(size_t(r) * width_ + c) * 3];
    return {t[0], t[1], t[2]};
}

Vec3 Texture::at(double u, double v) const {
    const double x = std::clamp(u, 0.0, 1.0) * width_ - 0.5, y = std::clamp(v, 0.0, 1.0) * height_ - 0.5;
    const double fx = std::floor(x), fy = std::floor(y);
    const int c = int(fx), r = int(fy);
    const double a = x - fx, b = y - fy;
    return (texel(c, r) * (1 - a) + texel(c + 1, r) * a) * (1 - b) + (texel(c, r + 1) * (1 - a) + texel(c + 1, r + 1) * a) * b;
}

Vec3 Texture::integral(double x, double y) const {
    x = std::clamp(x, 0.0, double(width_)), y = std::clamp(y, 0.0, double(height_));
    const int c = std::min(int(x), width_ - 1), r = std::min(int(y), height_ - 1);
    const double a = x - c, b = y - r;
    const size_t w1 = size_t(width_) + 1;
    auto s = [&](int cc, int rr) {
        const double* p = &sat_[(size_t(rr) * w1 + cc) * 3];
        return Vec3{p[0], p[1], p[2]};
    };
    return (s(c, r) * (1 - a) + s(c + 1, r) * a) * (1 - b) + (s(c, r + 1) * (1 - a) + s(c + 1, r + 1) * a) * b;
}

Vec3 Texture::mean(double u0, double u1, double v0, double v1) const {
    u0 = std::clamp(u0, 0.0, 1.0), u1 = std::clamp(u1, 0.0, 1.0);
    v0 = std::clamp(v0, 0.0, 1.0), v1 = std::clamp(v1, 0.0, 1.0);
    const double area = (u1 - u0) * width_ * (v1 - v0) * height_;
    if (!(area > 1e-12)) return at(0.5 * (u0 + u1), 0.5 * (v0 + v1));
    const double x0 = u0 * width_, x1 = u1 * width_, y0 = v0 * height_, y1 = v1 * height_;
    return (integral(x1, y1) - integral(x0, y1) - integral(x1, y0) + integral(x0, y0)) / area;
}

Vec3 Texture::filtered(double u, double v, double du, double dv) const {
    if (du * width_ <= 0.5 && dv * height_ <= 0.5) return at(u, v);
    return mean(u - du, u + du, v - dv, v + dv);
}

}  // namespace bsgi
