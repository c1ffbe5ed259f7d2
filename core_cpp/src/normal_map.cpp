#include "bsgi/normal_map.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bsgi {

namespace {

// A stored texel's normal, (n + 1) / 2 back to n (not yet unit).
Vec3 decoded(const Vec3& t) { return t * 2.0 - Vec3{1, 1, 1}; }

Vec3 above(Vec3 n) {
    n = normalize(n);
    if (n.z >= kLeastBumpedCosine) return n;
    const double t = std::sqrt(std::max(n.x * n.x + n.y * n.y, 1e-300));
    const double s = std::sqrt(1 - kLeastBumpedCosine * kLeastBumpedCosine) / t;
    return {n.x * s, n.y * s, kLeastBumpedCosine};
}

}  // namespace

std::shared_ptr<const Texture> normal_map(const Surface& surface, int width, int height, const std::vector<float>& world,
                                          const std::string& what) {
    if (width < 1 || height < 1 || world.size() != size_t(width) * height * 3)
        throw std::invalid_argument(what + " must be an image of shape (height, width, 3) with at least one texel");
    std::vector<float> encoded(world.size());
    for (int r = 0; r < height; ++r)
        for (int c = 0; c < width; ++c) {
            const size_t i = (size_t(r) * width + c) * 3;
            const Vec3 n{world[i], world[i + 1], world[i + 2]};
            const double len = length(n);
            if (!std::isfinite(len) || !(len > 1e-6))
                throw std::invalid_argument(what + ": texel (" + std::to_string(c) + ", " + std::to_string(r) +
                                            ") is not a direction");
            const Vec3 local = above(radiance_frame(surface.evaluate((c + 0.5) / width, (r + 0.5) / height)).to_local(n / len));
            for (int k = 0; k < 3; ++k) encoded[i + k] = float(std::clamp(0.5 * (local[k] + 1), 0.0, 1.0));
        }
    return std::make_shared<Texture>(width, height, std::move(encoded), what, true);
}

double largest_tilt(const Texture& map) {
    double lowest = 1;
    const std::vector<float>& t = map.rgb();
    for (size_t i = 0; i < t.size(); i += 3) {
        const Vec3 n = decoded({t[i], t[i + 1], t[i + 2]});
        if (length(n) > 1e-9) lowest = std::min(lowest, above(n).z);
    }
    return std::acos(std::clamp(lowest, -1.0, 1.0));
}

Vec3 bumped_normal(const Texture& map, double u, double v) {
    const Vec3 n = decoded(map.at(u, v));
    return length(n) > 1e-9 ? above(n) : Vec3{0, 0, 1};
}

}  // namespace bsgi
