#include "bsgi/hemisphere_map.h"

#include <stdexcept>
#include <string>

namespace bsgi {

HemisphereMap::HemisphereMap(double R) : R_(R), R2_(R * R), inv_R2_(1 / (R * R)) {
    if (!(R > 0 && R <= 1))
        throw std::invalid_argument("hemisphere map: the disc radius R must be in (0, 1], got " + std::to_string(R));
}

HemisphereMap HemisphereMap::for_max_angle(double delta) {
    if (!(delta >= 0 && delta < M_PI / 2))
        throw std::invalid_argument("hemisphere map: delta must be in [0, pi/2), got " + std::to_string(delta));
    return HemisphereMap(std::sqrt(1 - std::sin(delta)));
}

}  // namespace bsgi
