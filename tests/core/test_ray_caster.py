"""RayCaster: Embree hits answered as (surface, u, v), point and frame; exact on curved NURBS,
checked against analytic spheres and planes; self-intersection at 1e-3 and 1e4 scene units."""
import threading
import time

import numpy as np
import pytest
from scipy.interpolate import BPoly
from scipy.optimize import brentq

import bsgi
from nurbs_reference import SPHERE_FLAGS, blender_sphere_points


def sphere(radius=1.0, center=(0, 0, 0), name="sphere"):
    pts = blender_sphere_points(radius)
    pts[:, :3] += center
    return bsgi.NurbsSurface(name, pts, **SPHERE_FLAGS)


def plane_chart(half, height, center=(0, 0), name="ground"):
    """A square at z = height as a two-triangle mesh chart with u along x, v along y."""
    cx, cy = center
    positions = np.array([[cx - half, cy - half, height], [cx + half, cy - half, height], [cx + half, cy + half, height],
                          [cx - half, cy + half, height]])
    uvs = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)
    return bsgi.MeshChart(name, positions, np.array([[0, 1, 2], [0, 2, 3]]), uvs)


def ray_sphere(o, d, c, r):
    """Analytic first intersection t > 0 (inf if none) of unit-direction rays."""
    oc = o - c
    b = np.sum(oc * d, axis=1)
    disc = b * b - (np.sum(oc * oc, axis=1) - r * r)
    sq = np.sqrt(np.maximum(disc, 0))
    t0, t1 = -b - sq, -b + sq
    t = np.where(t0 > 0, t0, np.where(t1 > 0, t1, np.inf))
    return np.where(disc > 0, t, np.inf)


def ray_square(o, d, height, half, center=(0, 0)):
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (height - o[:, 2]) / d[:, 2]
    p = o + t[:, None] * d
    inside = (np.abs(p[:, 0] - center[0]) < half) & (np.abs(p[:, 1] - center[1]) < half) & (t > 0)
    return np.where(inside, t, np.inf)


def unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_hits_on_the_nurbs_sphere_are_the_analytic_sphere():
    c, r = np.array([0.3, -0.2, 0.5]), 1.3
    caster = bsgi.RayCaster([sphere(r, c)])
    rng = np.random.default_rng(0)
    n = 20000
    o = c + 4 * unit(rng.normal(size=(n, 3)))
    d = unit(c + rng.uniform(-1.5, 1.5, (n, 3)) - o)  # many rays graze the silhouette
    h = caster.closest_hit(o, d)
    t_ref = ray_sphere(o, d, c, r)
    # Impact parameter: leave out only rays within 1e-9 of tangency, where either answer is right.
    imp = np.linalg.norm(np.cross(c - o, d), axis=1)
    clear = np.abs(imp - r) > 1e-9 * r
    assert np.array_equal((h["surface"] == 0)[clear], np.isfinite(t_ref)[clear])
    hit = (h["surface"] == 0) & clear
    assert hit.sum() > 0.3 * n
    assert np.abs(h["t"][hit] - t_ref[hit]).max() < 1e-9 * r
    p = h["position"][hit]
    assert np.abs(p - (o + h["t"][:, None] * d)[hit]).max() < 1e-9 * r
    radial = (p - c) / r
    z = h["frame"][hit, 2]
    assert np.abs(np.abs(np.sum(z * radial, axis=1)) - 1).max() < 1e-9
    F = h["frame"][hit]
    assert np.abs(F @ F.transpose(0, 2, 1) - np.eye(3)).max() < 1e-12
    # The hit's parameters give back its point on the surface.
    s = sphere(r, c)
    assert np.abs(s.evaluate(h["uv"][hit])["position"] - p).max() < 1e-9 * r
    assert np.isinf(h["t"][h["surface"] < 0]).all()


def height_field():
    """A bicubic Bezier height field with x = u, y = v exactly (control x, y at the Greville
    abscissae 0, 1/3, 2/3, 1), so a hit's parameters are its x and y."""
    rng = np.random.default_rng(4)
    heights = rng.uniform(-0.25, 0.25, (4, 4))  # [v][u]
    pts = np.array([[i / 3, j / 3, heights[j, i], 1.0] for j in range(4) for i in range(4)])
    surface = bsgi.NurbsSurface("field", pts, 4, 4, 4, 4, endpoint_u=True, endpoint_v=True)
    # Reference height with scipy's Bernstein polynomials (independent of our evaluator).
    in_u = BPoly(heights.T[:, None, :], [0, 1])  # Bernstein in u, one column per v row

    def h(x, y):
        return float(BPoly(in_u(x).reshape(4, 1), [0, 1])(y))

    return surface, h


def test_hit_parameters_on_a_nurbs_height_field_are_exact():
    surface, h = height_field()
    caster = bsgi.RayCaster([surface])
    rng = np.random.default_rng(6)
    n = 300
    target = rng.uniform(0.15, 0.85, (n, 2))
    tilt = rng.uniform(-0.08, 0.08, (n, 2))
    d = unit(np.column_stack([tilt, -np.ones(n)]))
    o = np.column_stack([target, np.zeros(n)]) - 2 * d
    hits = caster.closest_hit(o, d)
    assert (hits["surface"] == 0).all()
    for k in range(n):
        g = lambda t: (o[k, 2] + t * d[k, 2]) - h(o[k, 0] + t * d[k, 0], o[k, 1] + t * d[k, 1])
        t = brentq(g, 0.5, 4.0, xtol=1e-15)
        x, y = o[k, 0] + t * d[k, 0], o[k, 1] + t * d[k, 1]
        assert abs(hits["uv"][k, 0] - x) < 1e-6 and abs(hits["uv"][k, 1] - y) < 1e-6  # the bound
        assert abs(hits["uv"][k, 0] - x) < 1e-10 and abs(hits["uv"][k, 1] - y) < 1e-10  # what Newton gives
        assert abs(hits["t"][k] - t) < 1e-10


def test_plane_hits_are_analytic():
    ground = plane_chart(2.0, -0.5, center=(1, 0))
    quad = bsgi.BilinearPatch("quad", np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float) * [1, 1, 1] + [5, 5, 0])
    caster = bsgi.RayCaster([ground, quad])
    rng = np.random.default_rng(2)
    n = 5000
    o = np.column_stack([rng.uniform(-1, 3, n), rng.uniform(-2, 2, n), np.full(n, 3.0)])
    d = unit(np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), -np.ones(n)]))
    h = caster.closest_hit(o, d)
    t_ref = ray_square(o, d, -0.5, 2.0, center=(1, 0))
    assert np.array_equal(h["surface"] == 0, np.isfinite(t_ref))
    hit = h["surface"] == 0
    assert np.allclose(h["t"][hit], t_ref[hit], rtol=1e-6)
    p = o[hit] + t_ref[hit, None] * d[hit]
    assert np.allclose(h["uv"][hit], (p[:, :2] - [-1, -2]) / 4, atol=1e-6)
    assert np.allclose(h["frame"][hit, 2], [0, 0, 1]) and np.allclose(h["frame"][hit, 0], [1, 0, 0])
    # The parallelogram: straight down onto it.
    top = caster.closest_hit(np.array([[5.25, 5.75, 9.0]]), np.array([[0, 0, -1.0]]))
    assert top["surface"][0] == 1 and np.allclose(top["uv"][0], [0.25, 0.75]) and top["t"][0] == pytest.approx(8)


def test_twisted_patch_and_triangle_hits_refine_to_their_exact_parameters():
    twisted = bsgi.BilinearPatch("twist", np.array([[0, 0, 0], [1, 0, 0.5], [1, 1, 0], [0, 1, 0.5]], float))
    tri = bsgi.TrianglePatch("tri", np.array([[3, 0, 0], [4, 0, 0], [3, 1, 0]], float))
    caster = bsgi.RayCaster([twisted, tri])
    rng = np.random.default_rng(8)
    n = 400
    o = np.column_stack([rng.uniform(0.05, 0.95, n), rng.uniform(0.05, 0.95, n), np.full(n, 2.0)])
    o[n // 2:, 0] += 3
    o[n // 2:] = np.where((o[n // 2:, 0] - 3 + o[n // 2:, 1] < 0.95)[:, None], o[n // 2:], [3.2, 0.2, 2])
    d = np.tile([0, 0, -1.0], (n, 1))
    h = caster.closest_hit(o, d)
    assert (h["surface"] >= 0).all()
    for s, surf in enumerate([twisted, tri]):
        k = h["surface"] == s
        back = surf.evaluate(h["uv"][k])["position"]
        assert np.abs(back - h["position"][k]).max() < 1e-10  # parameters on the exact surface
        assert np.abs(back[:, :2] - o[k, :2]).max() < 1e-10  # and on the ray


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e4])
def test_secondary_rays_do_not_hit_their_own_surface(scale):
    """Rays leaving hit points (spawned by the caster's scene-scaled offset) find the next
    surface the analytic geometry says, never the point they left."""
    c, r = np.array([3.0, -2.0, 1.0]) * scale, 1.0 * scale
    ground_z, half = c[2] - 1.5 * scale, 4 * scale
    caster = bsgi.RayCaster([sphere(r, c), plane_chart(half, ground_z, center=c[:2])])
    assert caster.offset < 1e-4 * np.linalg.norm(c) + 1e-4 * 8 * scale
    rng = np.random.default_rng(int(np.log10(scale)) + 10)
    n = 4000
    # Primary rays from above onto sphere and ground.
    o = c + np.array([0, 0, 6 * scale]) + rng.uniform(-3, 3, (n, 3)) * scale * [1, 1, 0]
    d = unit(c + rng.uniform(-2.5, 2.5, (n, 3)) * scale * [1, 1, 0] - [0, 0, 1.5 * scale] - o)
    first = caster.closest_hit(o, d)
    keep = first["surface"] >= 0
    p, F, sid = first["position"][keep], first["frame"][keep], first["surface"][keep]
    m = len(p)
    # Random secondary directions on both sides of each surface.
    dirs = unit(rng.normal(size=(m, 3)))
    origins = caster.spawn(p, F[:, 2], dirs)
    second = caster.closest_hit(origins, dirs)
    # Analytic next surface: the origins sit off their surface on the side the ray goes, so
    # the first positive roots are right as they are (outward from the sphere: none).
    t_sphere = ray_sphere(origins, dirs, c, r)
    t_ground = ray_square(origins, dirs, ground_z, half, center=c[:2])
    expected_t = np.minimum(t_sphere, t_ground)
    expected_id = np.where(np.isinf(expected_t), -1, np.where(t_sphere <= t_ground, 0, 1))
    assert np.array_equal(second["surface"], expected_id)
    found = expected_id >= 0
    assert np.abs(second["t"][found] - expected_t[found]).max() < 1e-5 * scale
    assert (second["t"][found] > 1e-3 * scale).all()  # nothing at the start


@pytest.mark.parametrize("scale", [1e-3, 1e4])
def test_shadow_rays_from_curved_surfaces_are_not_self_occluded(scale):
    c, r = np.array([-2.0, 1.0, 0.5]) * scale, 1.0 * scale
    caster = bsgi.RayCaster([sphere(r, c)])
    rng = np.random.default_rng(3)
    n = 3000
    uv = rng.uniform(0, 1, (n, 2))
    e = sphere(r, c).evaluate(uv)
    light = c + np.array([0.3, 0.2, 3.0]) * scale
    to_light = light - e["position"]
    dist = np.linalg.norm(to_light, axis=1)
    dirs = to_light / dist[:, None]
    origins = caster.spawn(e["position"], e["normal"], dirs)
    blocked = caster.occluded(origins, dirs, tfar=np.linalg.norm(light - origins, axis=1))
    # Analytic: the segment to the light crosses the sphere again iff the point faces away.
    facing = np.sum(dirs * (e["position"] - c), axis=1) > 0
    assert np.array_equal(blocked, ~facing)


def test_batches_agree_across_threads_and_with_single_rays():
    caster = bsgi.RayCaster([sphere(1.0), plane_chart(3.0, -1.2)])
    rng = np.random.default_rng(9)
    n = 5000
    o = rng.uniform(-2, 2, (n, 3)) + [0, 0, 3]
    d = unit(rng.normal(size=(n, 3)))
    one = caster.closest_hit(o, d, threads=1)
    two = caster.closest_hit(o, d, threads=2)
    for key in one:
        assert np.array_equal(one[key], two[key]), key
    for k in range(0, n, 500):
        single = caster.closest_hit(o[k:k + 1], d[k:k + 1])
        assert single["surface"][0] == one["surface"][k]
        assert np.array_equal(single["t"], one["t"][k:k + 1])
    occ1 = caster.occluded(o, d, threads=1)
    assert np.array_equal(occ1, caster.occluded(o, d, threads=2))
    assert np.array_equal(occ1, one["surface"] >= 0)


def cosine_directions(frame, n, rng):
    """n cosine-distributed unit directions about frame's third row."""
    u = rng.random((n, 2))
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u[:, 0])], 1) @ frame


def cube_faces(half=1.0):
    """The six faces of a cube as parallelograms meeting along shared edges, normals inward."""
    c = np.array([[x, y, z] for z in (-half, half) for y in (-half, half) for x in (-half, half)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return [bsgi.BilinearPatch(f"face{k}", c[list(q)]) for k, q in enumerate(quads)]


@pytest.mark.parametrize("case", ["sphere over a plane", "inside a cube"])
def test_packets_from_one_origin_agree_with_single_rays(case):
    # A gather traces each node's hemisphere in packets (closest_hits_from): the same hits as
    # one ray at a time, but where two surfaces meet at the same distance (a shared edge) and
    # either is the first; nothing leaks through the cube's edges, and NURBS hits stay exact.
    surfaces = [sphere(1.0), plane_chart(3.0, -1.2)] if case == "sphere over a plane" else cube_faces()
    caster = bsgi.RayCaster(surfaces)
    rng = np.random.default_rng(5)
    ties = total = 0
    for k in range(300):
        s = surfaces[1] if case == "sphere over a plane" else surfaces[k % 6]
        e = s.evaluate(rng.uniform(0.05, 0.95, (1, 2)))
        frame = np.stack([e["x"][0], e["y"][0], e["normal"][0]])
        dirs = cosine_directions(frame, 288, rng)
        origin = caster.spawn(e["position"], e["normal"], dirs[:1])
        packets = caster.closest_hits_from(origin, dirs)
        single = caster.closest_hit(np.repeat(origin, len(dirs), 0), dirs)
        differ = packets["surface"] != single["surface"]
        total += len(dirs)
        ties += differ.sum()
        if case == "inside a cube":
            assert np.all(packets["surface"] >= 0)
        assert np.all((packets["surface"] >= 0) == (single["surface"] >= 0))
        np.testing.assert_allclose(packets["t"], single["t"], rtol=1e-6)
        same = ~differ & (single["surface"] >= 0)
        np.testing.assert_allclose(packets["uv"][same], single["uv"][same], atol=1e-6)
        if case == "sphere over a plane":
            on_sphere = packets["surface"] == 0
            exact = ray_sphere(np.repeat(origin, on_sphere.sum(), 0), dirs[on_sphere], np.zeros(3), 1.0)
            np.testing.assert_allclose(packets["t"][on_sphere], exact, rtol=1e-9)
    assert ties <= 1e-3 * total


def test_packets_refuse_bad_directions():
    caster = bsgi.RayCaster([sphere(1.0)])
    with pytest.raises(ValueError, match="row 1 is not a finite non-zero vector"):
        caster.closest_hits_from(np.array([[0, 0, 3.0]]), np.array([[0, 0, -1.0], [0, 0, 0]]))
    with pytest.raises(ValueError, match="one point"):
        caster.closest_hits_from(np.zeros((2, 3)), np.array([[0, 0, -1.0]]))


def test_batches_release_the_gil():
    caster = bsgi.RayCaster([sphere(1.0)])
    rng = np.random.default_rng(1)
    n = 400000
    o = rng.uniform(-3, 3, (n, 3))
    d = unit(rng.normal(size=(n, 3)))
    done = threading.Event()
    worker = threading.Thread(target=lambda: (caster.closest_hit(o, d, threads=1), done.set()))
    ticks = 0
    worker.start()
    while not done.is_set():
        ticks += 1  # runs only while the worker is inside the core without the GIL
        time.sleep(0)
    worker.join()
    assert ticks > 50


def test_bad_rays_are_refused():
    caster = bsgi.RayCaster([sphere(1.0)])
    with pytest.raises(ValueError, match="finite"):
        caster.closest_hit(np.array([[np.nan, 0, 0]]), np.array([[1.0, 0, 0]]))
    with pytest.raises(ValueError, match="shape"):
        caster.closest_hit(np.zeros((3, 2)), np.zeros((3, 2)))


def test_mesh_chart_hits_carry_the_charts_parameters_and_frame():
    # A bumpy latitude-longitude sphere as one chart; hits from inside.
    nt, nph = 40, 80
    i, j = np.meshgrid(np.arange(nt + 1), np.arange(nph + 1), indexing="ij")
    u, v = i / nt, j / nph
    th, ph = np.pi * u, 2 * np.pi * v
    r = 1 + 0.1 * np.sin(3 * th) * np.cos(2 * ph)
    pos = np.stack([r * np.sin(th) * np.cos(ph), r * np.sin(th) * np.sin(ph), r * np.cos(th)], -1).reshape(-1, 3)
    idx = (i * (nph + 1) + j)[:-1, :-1].ravel()
    tris = np.concatenate([np.stack([idx, idx + nph + 1, idx + nph + 2], 1), np.stack([idx, idx + nph + 2, idx + 1], 1)])
    uv = np.stack([u, v], -1).reshape(-1, 2)
    chart = bsgi.MeshChart("bumpy", pos, tris, uv[tris])
    caster = bsgi.RayCaster([chart])
    rng = np.random.default_rng(12)
    n = 3000
    o = rng.uniform(-0.3, 0.3, (n, 3))
    d = unit(rng.normal(size=(n, 3)))
    h = caster.closest_hit(o, d)
    assert (h["surface"] == 0).all()
    e = chart.evaluate(h["uv"])
    assert np.abs(e["position"] - h["position"]).max() < 1e-5  # float tessellation vs double chart
    assert np.abs(e["normal"] - h["frame"][:, 2]).max() < 1e-5
    assert np.abs(e["x"] - h["frame"][:, 0]).max() < 1e-5
    # Normals face out (the winding), so rays from inside see the back.
    assert (np.sum(h["frame"][:, 2] * d, axis=1) > 0).all()
