"""MeshChart: a mesh with a UV map as one surface, with the domain mask chi of (8)."""
import numpy as np
import pytest

import bsgi


def disc_mesh(n=24, rings=4, center=(0.5, 0.5), radius=0.4):
    """A disc in UV space mapped onto the paraboloid z = x^2 + y^2 (x, y = 2 (uv - center)):
    a non-rectangular parameter domain."""
    uv = [center]
    for r in range(1, rings + 1):
        for k in range(n):
            a = 2 * np.pi * k / n
            uv.append((center[0] + radius * r / rings * np.cos(a), center[1] + radius * r / rings * np.sin(a)))
    uv = np.array(uv)
    tris = [(0, 1 + k, 1 + (k + 1) % n) for k in range(n)]
    for r in range(1, rings):
        a0, b0 = 1 + (r - 1) * n, 1 + r * n
        for k in range(n):
            k1 = (k + 1) % n
            tris += [(a0 + k, b0 + k, b0 + k1), (a0 + k, b0 + k1, a0 + k1)]
    tris = np.array(tris)
    xy = 2 * (uv - center)
    positions = np.column_stack([xy, np.sum(xy ** 2, axis=1)])
    return positions, tris, uv[tris], uv


def barycentric_2d(p, a, b, c):
    m = np.column_stack([b - a, c - a])
    b1, b2 = np.linalg.solve(m, p - a)
    return 1 - b1 - b2, b1, b2


def test_mask_and_evaluation_on_a_disc_domain():
    positions, tris, corner_uvs, uv = disc_mesh()
    chart = bsgi.MeshChart("disc", positions, tris, corner_uvs)
    rng = np.random.default_rng(1)
    q = rng.uniform(0, 1, (4000, 2))
    mask = chart.in_domain(q)
    # The domain is the inscribed 24-gon of the circle of radius 0.4: inside radius 0.4 cos(pi/24)
    # surely in, outside 0.4 surely out.
    r = np.linalg.norm(q - 0.5, axis=1)
    assert mask[r < 0.4 * np.cos(np.pi / 24) - 1e-9].all()
    assert not mask[r > 0.4 + 1e-9].any()
    assert not chart.in_domain(np.array([[0.02, 0.02], [0.98, 0.5]])).any()
    # Inside: the mesh point with those UVs, by barycentric interpolation on the UV triangle.
    inside = q[mask][:200]
    got = chart.evaluate(inside)["position"]
    for p, g in zip(inside, got):
        for t in tris:
            w = barycentric_2d(p, *uv[t])
            if min(w) >= -1e-12:
                assert np.allclose(g, np.dot(w, positions[t]), atol=1e-12)
                break
        else:
            pytest.fail("no UV triangle holds an in-domain point")


def test_points_outside_the_domain_move_to_its_nearest_point():
    positions, tris, corner_uvs, uv = disc_mesh()
    chart = bsgi.MeshChart("disc", positions, tris, corner_uvs)
    outside = np.array([[0.02, 0.5], [0.5, 0.98], [0.05, 0.05], [0.97, 0.93]])
    boundary = uv[1 + 3 * 24:]  # outer ring, in order
    for q, got in zip(outside, chart.evaluate(outside)["position"]):
        # Nearest point of the polygon's edges, by brute force.
        best, best_p = np.inf, None
        for k in range(24):
            a, b = boundary[k], boundary[(k + 1) % 24]
            s = np.clip(np.dot(q - a, b - a) / np.dot(b - a, b - a), 0, 1)
            d = np.linalg.norm(a + s * (b - a) - q)
            if d < best:
                best, best_p = d, a + s * (b - a)
        assert np.allclose(got, chart.evaluate(best_p[None])["position"][0], atol=1e-9)


def test_derivatives_area_and_frame_of_a_planar_chart():
    # A 2 x 3 rectangle, UV = (x / 2, y / 3) mirrored nowhere: s_u = (2, 0, 0), s_v = (0, 3, 0).
    positions = np.array([[0, 0, 1], [2, 0, 1], [2, 3, 1], [0, 3, 1]], float)
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    uvs = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)
    chart = bsgi.MeshChart("rect", positions, tris, uvs)
    e = chart.evaluate(np.array([[0.3, 0.6], [0.9, 0.1]]))
    assert np.allclose(e["dpdu"], [2, 0, 0]) and np.allclose(e["dpdv"], [0, 3, 0])
    assert np.allclose(e["position"], [[0.6, 1.8, 1], [1.8, 0.3, 1]])
    assert np.allclose(e["jacobian"], 6)
    assert np.allclose(e["x"], [1, 0, 0]) and np.allclose(e["normal"], [0, 0, 1])
    assert chart.area == pytest.approx(6)
    assert chart.tessellation_is_exact


def test_normal_follows_the_winding_even_with_mirrored_uvs():
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    mirrored = np.array([[[1, 0], [0, 0], [1, 1]]], float)  # u runs against x
    e = bsgi.MeshChart("mirror", positions, np.array([[0, 1, 2]]), mirrored).evaluate(np.array([[0.8, 0.3]]))
    assert np.allclose(e["normal"], [[0, 0, 1]])
    assert np.allclose(e["x"], [[-1, 0, 0]])  # still along s_u


def test_seams_split_vertices_so_each_carries_one_uv():
    # A cylinder band: the last column of quads wraps onto the first vertices, with u = 1 there.
    n = 8
    ang = 2 * np.pi * np.arange(n) / n
    positions = np.concatenate([np.column_stack([np.cos(ang), np.sin(ang), np.full(n, z)]) for z in (0, 1)])
    tris, uvs = [], []
    for k in range(n):
        k1 = (k + 1) % n
        u0, u1 = k / n, (k + 1) / n
        tris += [(k, k1, n + k1), (k, n + k1, n + k)]
        uvs += [[(u0, 0), (u1, 0), (u1, 1)], [(u0, 0), (u1, 1), (u0, 1)]]
    chart = bsgi.MeshChart("band", positions, np.array(tris), np.array(uvs))
    t = chart.tessellate()
    assert len(t["positions"]) == 2 * n + 2  # the seam column appears twice
    # Each tessellation vertex has the UV its corners had.
    for tri, corner_uv in zip(t["triangles"], np.array(uvs, np.float32)):
        assert np.array_equal(t["uvs"][tri], corner_uv)


@pytest.mark.parametrize("change,message", [
    (lambda p, t, u: (p[:0], t, u), "empty mesh"),
    (lambda p, t, u: (p, t[:0], u[:0]), "empty mesh"),
    (lambda p, t, u: (np.where(np.arange(len(p))[:, None] == 2, np.nan, p), t, u), "vertex 2 is NaN or infinite"),
    (lambda p, t, u: (p, t + 10, u), "triangle 0 uses vertex"),
    (lambda p, t, u: (p, t, u * 1.5), r"outside \[0, 1\]\^2"),
    (lambda p, t, u: (p, t, u[:1]), "expected 2 UV values"),
    (lambda p, t, u: (p, t, np.full_like(u, 0.5)), "UV map has no area"),
    (lambda p, t, u: (p, t, np.where(u > 0.5, np.inf, u)), "NaN or infinite"),
])
def test_bad_meshes_are_named(change, message):
    positions, tris, corner_uvs, _ = disc_mesh(n=6, rings=1)
    p, t, u = change(positions, tris, corner_uvs)
    with pytest.raises(ValueError, match=f"surface 'Mesh.007'.*{message}"):
        bsgi.MeshChart("Mesh.007", p, t, u)
