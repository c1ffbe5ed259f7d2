// A normal map over a surface's (u, v): the bumped shading normal of each point (a Normal Map or
// Bump node's), in the surface's radiance frame (1)-(3) whose z is its own smooth normal. Stored
// as normal-map images store normals, a texture of (n + 1) / 2, read bilinearly and normalised.
// A Lambertian surface under one is a BumpedLambert (bsdf.h): its radiance is a 4D spline over
// the bumped normal, read where the surface is seen at the normal the map gives there.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "bsgi/surface.h"
#include "bsgi/texture.h"

namespace bsgi {

// Bumped normals below this cosine to the surface's own are lifted to it (a map's normal can
// point under the surface; Cycles' shading then drops all light above it but a sliver).
constexpr double kLeastBumpedCosine = 1e-3;

// The map of `surface` from unit world-space normals (height * width * 3, row-major, texel
// (c, r) at (u, v) = ((c + 1/2) / width, (r + 1/2) / height)), each expressed in the radiance
// frame at its texel's centre. Throws std::invalid_argument, naming `what`, for a normal that is
// not finite or of zero length.
std::shared_ptr<const Texture> normal_map(const Surface& surface, int width, int height, const std::vector<float>& world,
                                          const std::string& what);

// The largest angle (radians) between a texel's bumped normal and the surface's own.
double largest_tilt(const Texture& map);

// The bumped normal at (u, v) leaving the front side (z > 0); the back side's is its opposite
// (Cycles turns a back-facing point's mapped normal around).
Vec3 bumped_normal(const Texture& map, double u, double v);

}  // namespace bsgi
