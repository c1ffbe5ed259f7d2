"""The BSDF's factors of a glossy gather read from a table per receiver, density and side
(scatter_table.cpp), against the closed form of a glossy floor under a constant world: the light
it reflects towards wo is W times its directional albedo, the integral of f(wo, wi) cos(theta_i)
over the hemisphere (here by a fine numpy quadrature of the BSDF). Two floors of different
roughness and the same angular nodes are gathered by the same threads: each must read its own
table; at 8 times the integration nodes per axis the table is too large to keep and its rows are
recomputed at each use."""
import numpy as np
import pytest

import bsgi

WORLD = 0.8
ALPHAS = {"smooth": 0.15, "rough": 0.5}


def floors():
    scene = bsgi.Scene()
    for k, (name, alpha) in enumerate(ALPHAS.items()):
        # Side by side in one plane: neither sees the other, each sees only the world above.
        corners = np.array([[3.0 * k, 0, 0], [3.0 * k + 2, 0, 0], [3.0 * k + 2, 2, 0], [3.0 * k, 2, 0]])
        scene.add_bilinear_patch(name, corners, albedo=(0, 0, 0), emission=(0, 0, 0),
                                 bsdf=bsgi.GgxReflection(alpha, alpha, [1.0, 1.0, 1.0]), angular_coeffs=12,
                                 spatial_coeffs=4)
    scene.world_radiance = np.full(3, WORLD)
    return scene


def directional_albedo(bsdf, wo, n=600):
    """Integral of f(wo, wi) cos(theta_i) over the upper hemisphere: midpoint rule in cos(theta)
    and phi on an n x 2n grid."""
    c = (np.arange(n) + 0.5) / n
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    c, phi = np.meshgrid(c, phi, indexing="ij")
    s = np.sqrt(1 - c ** 2)
    wi = np.stack([s * np.cos(phi), s * np.sin(phi), c], -1).reshape(-1, 3)
    f = bsdf.eval(np.broadcast_to(wo, wi.shape).copy(), wi)[:, 0]
    return (f * wi[:, 2]).mean() * 2 * np.pi


OUTGOING = [np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
            for t in np.radians([0, 30, 55, 70]) for p in np.radians([10, 100])]


def relative_errors(solution, index, alpha):
    bsdf = bsgi.GgxReflection(alpha, alpha, [1.0, 1.0, 1.0])
    out = []
    for wo in OUTGOING:
        ours = solution.surfaces[index].evaluate(np.array([[0.5, 0.5]]), wo[None])[0, 0]
        exact = WORLD * directional_albedo(bsdf, wo)
        out.append(abs(ours - exact) / exact)
    return np.array(out)


def settings(threads=0):
    s = bsgi.SolverSettings.preset("preview")
    s.final_gather = False
    s.threads = threads
    return s


def test_each_floor_reflects_the_world_as_its_directional_albedo():
    solution = bsgi.solve(floors(), settings())
    for index, (name, alpha) in enumerate(ALPHAS.items()):
        errors = relative_errors(solution, index, alpha)
        print(f"\n{name} (alpha {alpha}): relative errors {np.round(errors, 4)}")
        # Measured at most 0.49% (smooth) and 0.50% (rough): the cosine nodes' and BSDF samples'
        # quadrature and the angular spline. The other floor's table would be 28-42% off.
        assert errors.max() < 0.01, name


def test_the_same_coefficients_whatever_the_threads_gathered_before():
    scene = floors()
    one = bsgi.solve(scene, settings(threads=1))
    other = floors()
    other.set_integration_factor(0, 2)
    bsgi.solve(other, settings(threads=2))  # other tables in the threads' caches meanwhile
    two = bsgi.solve(scene, settings(threads=2))
    for a, b in zip(one.surfaces, two.surfaces):
        np.testing.assert_array_equal(np.asarray(a.upper.coefficients), np.asarray(b.upper.coefficients))


def test_a_table_too_large_to_keep_gives_the_closed_form_too():
    # 8 x 8 times the nodes of the final gather on the smooth floor: 144 values x 96 x 192 nodes,
    # about 85 MB of terms, over the 32 MB kept.
    scene = floors()
    scene.set_integration_factor(0, 8)
    s = settings()
    s.final_gather, s.final_passes = True, 1
    solution = bsgi.solve(scene, s)
    errors = relative_errors(solution, 0, ALPHAS["smooth"])
    print(f"\nsmooth, 8x the nodes: relative errors {np.round(errors, 4)}")
    assert errors.max() < 0.004  # measured 0.18%
