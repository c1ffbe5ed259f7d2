#include "bsgi/environment.h"

#include <algorithm>
#include <cmath>
#include <limits>
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
    // The level: `factor` times the mean of the map clipped at the level (so that the sun
    // itself does not raise it), by fixed-point iteration from the plain mean.
    double level = std::numeric_limits<double>::infinity();
    for (int it = 0; it < 20; ++it) {
        double sum = 0;
        for (int r = 0; r < height_; ++r) {
            double row = 0;
            for (int c = 0; c < width_; ++c) row += std::min(max_component(pixel(r, c)), level);
            sum += row * solid_angle(r);
        }
        const double next = factor * sum / (4 * kPi);
        const bool settled = std::abs(next - level) <= 1e-3 * next;
        level = next;
        if (settled) break;
    }
    if (!(level > 0)) return out;
    // Bright pixels get, in the remainder, the mean of their neighbours outside the bright part
    // (filled inwards, ring by ring): the remainder stays as smooth as the sky around a sun.
    std::vector<char> known(size_t(height_) * width_, 1);
    std::vector<std::pair<int, int>> unknown;
    for (int r = 0; r < height_; ++r)
        for (int c = 0; c < width_; ++c)
            if (max_component(pixel(r, c)) > level) known[size_t(r) * width_ + c] = 0, unknown.emplace_back(r, c);
    while (!unknown.empty()) {
        std::vector<std::pair<std::pair<int, int>, Vec3>> filled;
        std::vector<std::pair<int, int>> still;
        for (const auto& [r, c] : unknown) {
            Vec3 sum{0, 0, 0};
            int n = 0;
            const int neighbours[4][2] = {{r - 1, c}, {r + 1, c}, {r, (c + 1) % width_}, {r, (c + width_ - 1) % width_}};
            for (const auto& [nr, nc] : neighbours) {
                if (nr < 0 || nr >= height_ || !known[size_t(nr) * width_ + nc]) continue;
                const double* p = &out.smooth[3 * (size_t(nr) * width_ + nc)];
                sum += Vec3{p[0], p[1], p[2]}, ++n;
            }
            if (n) filled.push_back({{r, c}, sum / n});
            else still.emplace_back(r, c);
        }
        if (filled.empty()) break;  // every pixel bright: nothing to fill from (cannot happen for factor > 1)
        for (const auto& [rc, v] : filled) {
            double* p = &out.smooth[3 * (size_t(rc.first) * width_ + rc.second)];
            p[0] = v.x, p[1] = v.y, p[2] = v.z;
            known[size_t(rc.first) * width_ + rc.second] = 1;
        }
        unknown.swap(still);
    }
    // The bright part of each pixel: what the remainder does not keep.
    std::map<std::pair<int, int>, Vec3> cells;
    for (int r = 0; r < height_; ++r)
        for (int c = 0; c < width_; ++c) {
            if (max_component(pixel(r, c)) <= level) continue;
            const double* kept = &out.smooth[3 * (size_t(r) * width_ + c)];
            const Vec3 L = pixel(r, c);
            const Vec3 bright{std::max(0.0, L.x - kept[0]), std::max(0.0, L.y - kept[1]), std::max(0.0, L.z - kept[2])};
            cells[{r, c}] = bright * solid_angle(r);
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
