"""SplitPiece: a band of a surface between two curves of its domain (paper section 5.1's split
along a discontinuity). Pieces of a NURBS sphere against the sphere itself: points on it, its
normals, the sphere's area 4 pi r^2 summed over the pieces, derivatives against finite
differences, shared boundary vertices, ray hits mapped back to the parent; bad bands named."""
import numpy as np
import pytest

import bsgi
from bsgi import _core
from nurbs_reference import SPHERE_FLAGS, blender_sphere_points

RADIUS = 1.5
U0, U1 = 0.2, 0.7
STEPS = np.linspace(U0, U1, 21)
# Two wavy curves across the band, as a closed line's lower and upper halves would be.
LOWER = 0.3 + 0.05 * np.sin(2 * np.pi * STEPS)
UPPER = 0.6 + 0.08 * np.cos(3 * np.pi * STEPS)


def sphere():
    return bsgi.NurbsSurface("sphere", blender_sphere_points(RADIUS), **SPHERE_FLAGS)


def pieces(parent, along_v=False):
    """The sphere cut into five: before and after the band, and the band's three layers (along v:
    the curves are u(v), the band a range of v)."""
    band = [(LOWER * 0, LOWER), (LOWER, UPPER), (UPPER, UPPER * 0 + 1)]
    whole = dict(lower=np.array([0.0]), upper=np.array([1.0]), along_v=along_v)
    out = [_core.SplitPiece("before", parent, 0.0, U0, **whole)]
    out += [_core.SplitPiece(f"band {k}", parent, U0, U1, lo, hi, along_v) for k, (lo, hi) in enumerate(band)]
    out.append(_core.SplitPiece("after", parent, U1, 1.0, **whole))
    return out


def grid(n=41):
    g = np.linspace(0, 1, n)
    return np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)


@pytest.mark.parametrize("along_v", [False, True])
def test_pieces_lie_on_the_parent_with_its_normals_and_add_up_to_its_area(along_v):
    parent = sphere()
    total = 0.0
    for piece in pieces(parent, along_v):
        ab = grid()
        got = piece.evaluate(ab)
        uv = piece.parent_parameters(ab)
        want = parent.evaluate(uv)
        assert np.abs(got["position"] - want["position"]).max() < 1e-12
        assert np.abs(np.linalg.norm(got["position"], axis=1) - RADIUS).max() < 1e-12
        # The parent's side (a NURBS surface faces Blender's way, -(s_u x s_v)), to rounding.
        assert np.einsum("ij,ij->i", got["normal"], want["normal"]).min() > 1 - 1e-9
        total += piece.area
    assert total == pytest.approx(4 * np.pi * RADIUS**2, rel=8e-5)  # 1.6e-5, 3.9e-5: the speed's kinks at knots in cells
    assert total == pytest.approx(parent.area, rel=8e-5)


@pytest.mark.parametrize("along_v", [False, True])
def test_derivatives_match_finite_differences(along_v):
    piece = pieces(sphere(), along_v)[2]
    rng = np.random.default_rng(3)
    ab = rng.uniform(0.05, 0.95, (50, 2))
    h = 1e-6
    got = piece.evaluate(ab)
    for axis, key in ((0, "dpdu"), (1, "dpdv")):
        step = np.zeros(2)
        step[axis] = h
        diff = (piece.evaluate(ab + step)["position"] - piece.evaluate(ab - step)["position"]) / (2 * h)
        assert np.abs(diff - got[key]).max() < 1e-6 * RADIUS
    assert np.abs(got["jacobian"] - np.linalg.norm(np.cross(got["dpdu"], got["dpdv"]), axis=1)).max() < 1e-12


@pytest.mark.parametrize("along_v", [False, True])
def test_boundary_curves_pass_through_their_samples_and_parameters_map_back(along_v):
    parent = sphere()
    lower = pieces(parent, along_v)[2]  # between LOWER and UPPER
    t = (STEPS - U0) / (U1 - U0)
    along, across = (1, 0) if along_v else (0, 1)
    for w, curve in ((0.0, LOWER), (1.0, UPPER)):
        ab = np.column_stack([np.full_like(t, w), t] if along_v else [t, np.full_like(t, w)])
        uv = lower.parent_parameters(ab)
        assert np.abs(uv[:, along] - STEPS).max() < 1e-15 and np.abs(uv[:, across] - curve).max() < 1e-15
    ab = grid(17)
    back = lower.piece_parameters(lower.parent_parameters(ab))
    assert np.abs(back - ab).max() < 1e-12


def test_neighbouring_pieces_share_their_boundary_vertices():
    below, between = pieces(sphere())[1:3]
    tb, tm = below.tessellate(), between.tessellate()
    top = tb["positions"][np.isclose(tb["uvs"][:, 1], 1.0)]
    bottom = tm["positions"][np.isclose(tm["uvs"][:, 1], 0.0)]
    assert len(top) == len(bottom) > 10
    assert np.abs(top - bottom).max() < 1e-12


def test_rays_hit_the_piece_holding_the_parent_point():
    parent = sphere()
    split = pieces(parent)
    caster = bsgi.RayCaster(split)
    rng = np.random.default_rng(7)
    targets = parent.evaluate(rng.uniform(0.02, 0.98, (400, 2)))["position"]
    origins = targets * 3.0  # from outside, straight at the centre
    hit = caster.closest_hit(origins, -origins / np.linalg.norm(origins, axis=1)[:, None])
    assert (hit["surface"] >= 0).all()
    assert np.abs(hit["position"] - targets).max() < 1e-9
    for s in np.unique(hit["surface"]):
        rows = hit["surface"] == s
        on = split[s].evaluate(hit["uv"][rows])["position"]
        assert np.abs(on - targets[rows]).max() < 1e-9


@pytest.mark.parametrize("u0,u1,lower,upper,message", [
    (0.5, 0.5, [0.0], [1.0], "t0 < t1"),
    (0.2, 1.2, [0.0], [1.0], "t0 < t1"),
    (0.2, 0.4, [-0.1, 0.2], [1.0], "leaves"),
    (0.2, 0.4, [0.0, np.nan], [1.0], "leaves"),
    (0.2, 0.4, [0.3, 0.7], [0.6, 0.5], "crosses"),
    (0.2, 0.4, [], [1.0], "no samples"),
])
def test_bad_bands_are_named(u0, u1, lower, upper, message):
    with pytest.raises(ValueError, match=f"surface 'cut'.*{message}"):
        _core.SplitPiece("cut", sphere(), u0, u1, np.array(lower, float), np.array(upper, float))
