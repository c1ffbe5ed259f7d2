// A texture over a surface's own parameter domain: an RGB image on [0, 1]^2 (column along u,
// row along v, row 0 at v = 0) whose texel (c, r) covers [c/W, (c+1)/W] x [r/H, (r+1)/H].
// Albedo textures multiply a Lambertian surface's irradiance / pi (the smooth factor of the
// decomposition (38), the texture in the role of the detail); emission textures replace the
// constant emission. Specular textures tint a GGX lobe (its f0): the surface's radiance is the
// texture's blend of its radiance at f0 = 1 and at f0 = 0, each a spline.
#pragma once
#include <string>
#include <vector>

#include "bsgi/vec3.h"

namespace bsgi {

class Texture {
public:
    // `rgb`: height * width * 3 values, row-major. Throws std::invalid_argument, naming `what`,
    // unless every value is finite, >= 0 and (with at_most_one, for albedo) <= 1.
    Texture(int width, int height, std::vector<float> rgb, const std::string& what, bool at_most_one);

    int width() const { return width_; }
    int height() const { return height_; }
    const std::vector<float>& rgb() const { return rgb_; }

    // Bilinear between texel centres, clamped at the edges.
    Vec3 at(double u, double v) const;
    // Mean over the parameter rectangle [u0, u1] x [v0, v1] of the image as texels (box filter,
    // exact by the summed-area table); at(u, v) where the rectangle has no area.
    Vec3 mean(double u0, double u1, double v0, double v1) const;
    // Bilinear where the footprint (half widths du, dv in the parameters) is within a texel,
    // else the box mean over it: what a ray whose cone covers that footprint sees.
    Vec3 filtered(double u, double v, double du, double dv) const;
    // Mean over the whole domain and largest channel value.
    const Vec3& mean() const { return mean_; }
    double max() const { return max_; }

private:
    Vec3 texel(int c, int r) const;
    // Integral of the texel image over [0, x] x [0, y] (x, y in texels), bilinear in the
    // summed-area table (exact for a piecewise-constant image).
    Vec3 integral(double x, double y) const;

    int width_, height_;
    std::vector<float> rgb_;
    std::vector<double> sat_;  // (height + 1) x (width + 1) x 3: sums of texels below and left
    Vec3 mean_;
    double max_ = 0;
};

}  // namespace bsgi
