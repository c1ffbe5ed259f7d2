// The cosine-weighted product rule over the hemisphere of the gather (paper (26)-(32)):
// integral of L(w) cos(theta) d(omega) = pi * mean over the rule of weight * L(node).
//
// cos(theta) d(omega) = 2 s ds d(phi) with s = cos(theta), so the rule is Gauss-Legendre in s
// with weights 2 s lambda (exact for L a polynomial of degree 2 nt - 2 in cos(theta)) times the
// midpoint rule in phi (rows staggered by half a step, alternately). The paper's nodes, uniform
// in cos^2(theta) with equal weights, sample the band next to the horizon at one point for the
// twelfth of the light it brings: where the light rises from a dark horizon (a room's corners
// seen from its ceiling) that overestimates the integral by 0.3-0.5%, which the fit's bias
// hid; in cos(theta), radiance is smooth up to the horizon.
#pragma once
#include <utility>
#include <vector>

#include "bsgi/vec3.h"

namespace bsgi {

class CosineRule {
public:
    // nt x np nodes, nt and np >= 1.
    CosineRule(int nt, int np);
    int theta_nodes() const { return nt_; }
    int phi_nodes() const { return np_; }
    int size() const { return nt_ * np_; }
    // Local direction of node m (z up; computed once: a gather asks for each at every node).
    // The nodes go in tile_order (tiles of kTile x kTile neighbours in theta and phi), so that
    // a packet of rays traced together (RayCaster::closest_hits_from) spans a small solid angle.
    const Vec3& direction(int m) const { return directions_[size_t(m)]; }
    const Vec3* directions() const { return directions_.data(); }
    // Weight of node m: the share of the cosine-weighted hemisphere it stands for, times
    // size() (mean 1 over the nodes).
    double weight(int m) const { return weights_[size_t(m)]; }
    static constexpr int kTile = 4;

private:
    std::vector<Vec3> directions_;
    std::vector<double> weights_;
    int nt_, np_;
};

// The (theta row, phi column) of each of nt x np directions in tiles of CosineRule::kTile x kTile
// neighbours (row-major tiles, row-major within a tile): rays in this order, traced in packets,
// share their traversal of the BVH.
std::vector<std::pair<int, int>> tile_order(int nt, int np);

// The rule of nt x np nodes, built once per thread.
const CosineRule& cosine_rule(int nt, int np);

}  // namespace bsgi
