// The scene the solver sees: surfaces with their materials, and which of them block light.
#pragma once
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bsgi/surface.h"

namespace bsgi {

// Lambertian reflection with RGB albedo, plus emitted radiance leaving the front side.
struct Material {
    Vec3 albedo;
    Vec3 emission;
    bool emits() const { return max_component(emission) > 0; }
};

struct SceneSurface {
    std::shared_ptr<const Surface> surface;  // shared: Python may hold the same surface
    Material material;
    bool receiver;  // gets a radiance spline (false for light objects, which only emit)
    bool occluder;  // blocks rays (false for light objects, as in Cycles)
};

class Scene {
public:
    int add(std::shared_ptr<const Surface> surface, const Material& material, bool receiver = true, bool occluder = true) {
        if (!surface) throw std::invalid_argument("Scene::add: no surface");
        const std::string& name = surface->name();
        for (int c = 0; c < 3; ++c) {
            if (!std::isfinite(material.albedo[c]) || material.albedo[c] < 0 || material.albedo[c] > 1)
                throw std::invalid_argument("surface '" + name + "': albedo must be finite and in [0, 1]");
            if (!std::isfinite(material.emission[c]) || material.emission[c] < 0)
                throw std::invalid_argument("surface '" + name + "': emission must be finite and >= 0");
        }
        surfaces_.push_back({std::move(surface), material, receiver, occluder});
        return static_cast<int>(surfaces_.size()) - 1;
    }
    size_t size() const { return surfaces_.size(); }
    const SceneSurface& operator[](size_t i) const { return surfaces_[i]; }
    const std::vector<SceneSurface>& surfaces() const { return surfaces_; }

private:
    std::vector<SceneSurface> surfaces_;
};

}  // namespace bsgi
