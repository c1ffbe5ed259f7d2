#include "bsgi/environment.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <utility>

namespace bsgi {

namespace {
constexpr double kPi = 3.14159265358979323846;
}

EnvironmentMap::EnvironmentMap(int height, int width, std::vector<double> rgb, const std::string& what)
    : height_(height), width_(width), rgb_(std::move(rgb)) {
    if (height < 1 || width < 1)
        throw std::invalid_argument(what + ": the image must have at least one row and one column");
    if (rgb_.size() != size_t(height) * size_t(width) * 3)
        throw std::invalid_argument(what + ": expected " + std::to_string(height) + " x " + std::to_string(width) +
                                    " x 3 values, got " + std::to_string(rgb_.size()));
    for (size_t i = 0; i < rgb_.size(); ++i)
        if (!std::isfinite(rgb_[i]) || rgb_[i] < 0)
            throw std::invalid_argument(what + ": pixel (" + std::to_string(i / 3 / width) + ", " +
                                        std::to_string(i / 3 % width) + ") must be finite and >= 0");
}

Vec3 EnvironmentMap::direction(double row, double col) const {
    const double theta = kPi * row / height_, phi = kPi * (1 - 2 * col / width_);
    const double s = std::sin(theta);
    return {s * std::cos(phi), s * std::sin(phi), std::cos(theta)};
}

double EnvironmentMap::solid_angle(int row) const {
    return 2 * kPi / width_ * (std::cos(kPi * row / height_) - std::cos(kPi * (row + 1) / height_));
}

Vec3 EnvironmentMap::radiance(const Vec3& d) const {
    const double theta = std::acos(std::clamp(d.z / length(d), -1.0, 1.0));
    const double u = 0.5 - std::atan2(d.y, d.x) / (2 * kPi);
    // Continuous pixel coordinates with centres at integers.
    const double y = std::clamp(theta / kPi * height_ - 0.5, 0.0, double(height_ - 1));
    double x = u * width_ - 0.5;
    x -= width_ * std::floor(x / width_);
    const int r0 = std::min(int(y), height_ - 1), r1 = std::min(r0 + 1, height_ - 1);
    const int c0 = std::min(int(x), width_ - 1), c1 = (c0 + 1) % width_;
    const double a = x - c0, b = y - r0;
    // Differences, not weights: a constant image interpolates to itself exactly.
    auto along_row = [&](int r) { return pixel(r, c0) + (pixel(r, c1) - pixel(r, c0)) * a; };
    const Vec3 top = along_row(r0);
    return top + (along_row(r1) - top) * b;
}

Vec3 EnvironmentMap::mean() const {
    Vec3 sum{0, 0, 0};
    for (int r = 0; r < height_; ++r) {
        Vec3 row{0, 0, 0};
        for (int c = 0; c < width_; ++c) row += pixel(r, c);
        sum += row * solid_angle(r);
    }
    return sum / (4 * kPi);
}

EnvironmentMap::Split EnvironmentMap::split(double factor, size_t max_samples) const {
    Split out;
    out.smooth = rgb_;
    const double level = factor * max_component(mean());
    if (!(level > 0)) return out;
    // The bright part of each pixel above the level, as (row, col) -> irradiance.
    std::map<std::pair<int, int>, Vec3> cells;
    for (int r = 0; r < height_; ++r)
        for (int c = 0; c < width_; ++c) {
            const Vec3 L = pixel(r, c);
            const double m = max_component(L);
            if (m <= level) continue;
            const Vec3 kept = L * (level / m);
            double* s = &out.smooth[3 * (size_t(r) * width_ + c)];
            s[0] = kept.x, s[1] = kept.y, s[2] = kept.z;
            cells[{r, c}] = (L - kept) * solid_angle(r);
        }
    // Energy-weighted directions of the cells (one pixel each at first), merged over blocks
    // twice as large until few enough remain.
    struct Cell {
        Vec3 irradiance, weighted_direction;
        double weight = 0;
    };
    std::map<std::pair<int, int>, Cell> merged;
    for (const auto& [rc, e] : cells) {
        const double w = max_component(e);
        merged[rc] = {e, direction(rc.first + 0.5, rc.second + 0.5) * w, w};
    }
    while (merged.size() > std::max<size_t>(max_samples, 1)) {
        std::map<std::pair<int, int>, Cell> coarser;
        for (const auto& [rc, cell] : merged) {
            Cell& into = coarser[{rc.first / 2, rc.second / 2}];
            into.irradiance += cell.irradiance;
            into.weighted_direction += cell.weighted_direction;
            into.weight += cell.weight;
        }
        merged.swap(coarser);
    }
    for (const auto& [rc, cell] : merged) {
        const double n = length(cell.weighted_direction);
        if (!(n > 0)) continue;
        out.bright.push_back({cell.weighted_direction / n, cell.irradiance});
    }
    return out;
}

}  // namespace bsgi
