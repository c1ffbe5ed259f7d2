// The world's light as an image over directions: an equirectangular environment map in the
// layout of Cycles' Environment Texture, and its split into a few bright directions (a sun) and
// a smooth remainder for the deterministic solve.
#pragma once
#include <string>
#include <vector>

#include "bsgi/vec3.h"

namespace bsgi {

// Radiance arriving from direction d (unit, towards the world), as an H x W RGB image, row 0 at
// the zenith (+Z). Pixel (r, c) has its centre at polar angle theta = pi (r + 1/2) / H and
// azimuth phi = atan2(d.y, d.x) = pi (1 - 2 u), u = (c + 1/2) / W: Cycles' equirectangular
// mapping (u = 1/2 - phi / 2 pi) with the image's rows from the top, so +X is at the centre.
class EnvironmentMap {
public:
    // `rgb` holds height * width * 3 values, row-major; all finite and >= 0 (else
    // std::invalid_argument naming `what`).
    EnvironmentMap(int height, int width, std::vector<double> rgb, const std::string& what = "world map");

    int height() const { return height_; }
    int width() const { return width_; }
    const std::vector<double>& pixels() const { return rgb_; }
    Vec3 pixel(int row, int col) const {
        const double* p = &rgb_[3 * (size_t(row) * width_ + col)];
        return {p[0], p[1], p[2]};
    }
    // Radiance along unit direction d: bilinear between pixel centres (wrapping in azimuth,
    // clamped at the poles' rows); a constant map gives its constant exactly.
    Vec3 radiance(const Vec3& d) const;
    // Unit direction of a point of the image (row, col in pixel units; centres at + 1/2).
    Vec3 direction(double row, double col) const;
    // Solid angle of a pixel of row r.
    double solid_angle(int row) const;
    // Integral of the radiance over the sphere (pixelwise constant) divided by 4 pi.
    Vec3 mean() const;

    // A direction of the bright part and the irradiance it brings to a surface facing it.
    struct BrightSample {
        Vec3 direction;
        Vec3 irradiance;
    };
    // The map as bright directions plus a smooth remainder. Bright pixels are those whose
    // largest channel exceeds the level `factor` times the mean of the map clipped at that level
    // (solid-angle weighted, largest channel: the sky's brightness, which the sun does not
    // raise); in the remainder they take the mean of their neighbours outside the bright part,
    // and the rest of their light is a sample of irradiance (that radiance x the pixel's solid
    // angle) at the pixel's centre. Neighbouring samples are merged over 2 x 2, 4 x 4, ... blocks
    // (at the block's energy-weighted mean direction) until at most `max_samples` remain.
    struct Split {
        std::vector<BrightSample> bright;
        std::vector<double> smooth;  // the remainder's pixels, as rgb
    };
    Split split(double factor, size_t max_samples) const;

private:
    int height_, width_;
    std::vector<double> rgb_;
};

}  // namespace bsgi
