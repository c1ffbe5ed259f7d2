"""Local frames (1)-(3) (core_cpp/include/bsgi/frame.h, used by every surface): exactly the
paper's where s_u x s_v is defined, and orthonormal, finite, continuous at degenerate points:
sphere poles, collapsed rows, zero-area faces, surfaces without area."""
import numpy as np
import pytest

import bsgi
from nurbs_reference import SPHERE_FLAGS, blender_sphere_points


def grid(n, lo=0.0, hi=1.0):
    g = np.linspace(lo, hi, n)
    return np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)


def frames(e):
    return np.stack([e["x"], e["y"], e["normal"]], axis=1)  # rows x, y, z


def assert_orthonormal(F, tol=1e-12):
    assert np.isfinite(F).all()
    assert np.abs(F @ F.transpose(0, 2, 1) - np.eye(3)).max() < tol
    assert np.allclose(np.linalg.det(F), 1, atol=tol)  # right-handed: y = z x x


def test_paper_frame_where_defined():
    rng = np.random.default_rng(3)
    pts = np.column_stack([np.repeat(np.arange(5), 5), np.tile(np.arange(5), 5), rng.uniform(-1, 1, 25),
                           rng.uniform(0.5, 2, 25)])
    s = bsgi.NurbsSurface("wavy", pts, 5, 5, 4, 3, endpoint_u=True, endpoint_v=True, front="su_x_sv")
    uv = rng.uniform(0, 1, (500, 2))
    e = s.evaluate(uv)
    su, sv = e["dpdu"], e["dpdv"]
    x = su / np.linalg.norm(su, axis=1, keepdims=True)
    z = np.cross(su, sv)
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    assert np.allclose(e["x"], x, atol=1e-12)  # (1)
    assert np.allclose(e["normal"], z, atol=1e-12)  # (2)
    assert np.allclose(e["y"], np.cross(z, x), atol=1e-12)  # (3)
    assert np.allclose(e["jacobian"], np.linalg.norm(np.cross(su, sv), axis=1))
    # Blender's front (the default) turns z over and keeps x along s_u, right-handed.
    b = bsgi.NurbsSurface("wavy", pts, 5, 5, 4, 3, endpoint_u=True, endpoint_v=True).evaluate(uv)
    assert np.allclose(b["normal"], -z, atol=1e-12) and np.allclose(b["x"], x, atol=1e-12)
    assert np.allclose(b["y"], np.cross(-z, x), atol=1e-12)


def test_sphere_frames_on_a_dense_grid_with_the_poles():
    s = bsgi.NurbsSurface("sphere", blender_sphere_points(), **SPHERE_FLAGS)
    uv = grid(201)  # u = 0 and u = 1 are the poles: whole rows of control points collapse there
    e = s.evaluate(uv)
    F = frames(e)
    assert_orthonormal(F)
    radial = e["position"] / np.linalg.norm(e["position"], axis=1, keepdims=True)
    cos = np.sum(e["normal"] * radial, axis=1)
    assert np.allclose(cos, cos[0], atol=1e-9) and abs(abs(cos[0]) - 1) < 1e-9  # one side, poles too
    pole = uv[:, 0] == 0
    assert np.all(np.linalg.norm(e["dpdv"][pole], axis=1) < 1e-12)  # truly degenerate there


def test_frame_is_continuous_into_the_pole():
    s = bsgi.NurbsSurface("sphere", blender_sphere_points(), **SPHERE_FLAGS)
    v = np.linspace(0, 1, 33)
    for u_pole, step in [(0.0, 1e-7), (1.0, -1e-7)]:
        at = s.evaluate(np.column_stack([np.full_like(v, u_pole), v]))
        near = s.evaluate(np.column_stack([np.full_like(v, u_pole + step), v]))
        assert np.abs(at["normal"] - near["normal"]).max() < 1e-5
        assert np.abs(at["x"] - near["x"]).max() < 1e-5  # x keeps following s_u into the pole


def test_cone_apex_and_collapsed_corners_are_finite():
    # A row of control points collapsed to one apex, and a corner where both edges collapse.
    pts = []
    for j in range(4):
        for i in range(4):
            r = j / 3
            a = 2 * np.pi * i / 4
            pts.append([r * np.cos(a), r * np.sin(a), 1 - r, 1.0])
    cone = bsgi.NurbsSurface("cone", np.array(pts), 4, 4, 3, 3, endpoint_u=True, endpoint_v=True)
    assert_orthonormal(frames(cone.evaluate(grid(41))))
    corner = np.array([[0, 0, 0, 1.0]] * 3 + [[1, 0, 0, 1]] + [[0, 0, 0, 1.0]] * 2 + [[1, 1, 0, 1], [2, 1, 0.5, 1]]
                      + [[0, 0, 0, 1.0], [1, 2, 0, 1], [2, 2, 1, 1], [3, 2, 0, 1]] + [[0, 3, 0, 1.0], [1, 3, 0, 1], [2, 3, 1, 1], [3, 3, 0, 1]])
    pinched = bsgi.NurbsSurface("pinched", corner, 4, 4, 3, 3, endpoint_u=True, endpoint_v=True)
    assert_orthonormal(frames(pinched.evaluate(grid(41))))


def test_surface_without_area_still_has_frames():
    # All control points on one line: s_u parallel to s_v everywhere, no normal anywhere.
    t = np.linspace(0, 1, 16)
    line = np.column_stack([t, 2 * t, 3 * t, np.ones(16)])
    s = bsgi.NurbsSurface("line", line, 4, 4, 3, 3)
    assert_orthonormal(frames(s.evaluate(grid(21))))


def test_triangle_patch_collapsed_edge():
    s = bsgi.TrianglePatch("tri", np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float))
    e = s.evaluate(grid(21))
    assert_orthonormal(frames(e))
    assert np.allclose(e["normal"], [0, 0, 1])


def test_zero_area_mesh_triangle_borrows_its_neighbours_normal():
    # A quad (two triangles) plus a sliver with all three corners on one line.
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0, 0]], float)
    triangles = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 1]])
    # UV islands apart: the quad above v = 0.3, the sliver below.
    uvs = np.array([[[0, 0.3], [0.9, 0.3], [0.9, 0.9]], [[0, 0.3], [0.9, 0.9], [0, 0.9]], [[0, 0], [0.45, 0.2], [0.9, 0]]])
    chart = bsgi.MeshChart("sliver", positions, triangles, uvs)
    e = chart.evaluate(np.array([[0.45, 0.05]]))  # inside the sliver's UV triangle
    assert_orthonormal(frames(e))
    assert np.allclose(e["normal"], [[0, 0, 1]])
    assert e["jacobian"][0] == pytest.approx(0, abs=1e-12)
