"""Fuzzing every surface type, the ray caster and every BSDF (issue 17, item 1): random and
degenerate geometry (collinear, coincident, huge, tiny, far from the origin) either gives a surface
whose points, frames and tessellation are finite and orthonormal, or a ValueError naming the surface."""
import numpy as np
from hypothesis import given, settings, strategies as st

import bsgi
from fuzz_support import any_float, arrays, case, examples, finite, points, refused, rgb, unit_float

SCALE = st.sampled_from([1.0, 1e-6, 1e-3, 1e3, 1e6, 1e150])
OFFSET = st.sampled_from([0.0, 1.0, 1e4, 1e7, -1e9])
# Coordinates: ordinary, on a grid (coincident and collinear corners are likely), or anything.
COORD = st.one_of(st.floats(-2, 2), st.sampled_from([0.0, 1.0, 2.0]), any_float)


@st.composite
def corners(draw, n):
    c = draw(arrays((n, 3), COORD))
    return c * draw(SCALE) + draw(OFFSET)


@st.composite
def nurbs(draw):
    cu, cv = draw(st.integers(-1, 6)), draw(st.integers(-1, 6))
    n = max(cu, 0) * max(cv, 0)
    shape = draw(st.sampled_from([(n, 4), (n, 4), (n, 3), (n + 1, 4)]))
    weights = st.one_of(st.floats(0.1, 3), st.sampled_from([0.0, -1.0, 1e-300, np.nan]))
    p = draw(arrays(shape, COORD))
    if shape[1] == 4 and shape[0] > 0:
        p[:, 3] = draw(arrays((shape[0],), weights))
    kwargs = dict(order_u=draw(st.integers(-1, 7)), order_v=draw(st.integers(-1, 7)),
                  endpoint_u=draw(st.booleans()), endpoint_v=draw(st.booleans()),
                  bezier_u=draw(st.booleans()), bezier_v=draw(st.booleans()),
                  cyclic_u=draw(st.booleans()), cyclic_v=draw(st.booleans()),
                  subdivisions=draw(st.sampled_from([0, 1, 3, -1])), front=draw(st.sampled_from(["blender", "su_x_sv", "x"])))
    return ("nurbs", p, cu, cv, kwargs)


@st.composite
def mesh(draw):
    nv = draw(st.integers(0, 6))
    pos = draw(corners(nv)) if nv else np.zeros((0, 3))
    nt = draw(st.integers(0, 4))
    tris = np.array(draw(st.lists(st.integers(-1, nv + 1), min_size=3 * nt, max_size=3 * nt)), np.int64).reshape(nt, 3)
    uvs = draw(st.one_of(arrays((nt, 3, 2), st.one_of(unit_float, any_float)), arrays((3 * nt, 2), unit_float),
                         points(2)))
    return ("mesh", pos, tris, uvs)


SURFACES = st.one_of(
    st.builds(lambda c: ("bilinear", c), corners(4)),
    st.builds(lambda c: ("triangle", c), corners(3)),
    st.builds(lambda c: ("bilinear", c), st.one_of(corners(3), corners(5))),
    nurbs(),
    mesh(),
)


def build(spec, name="S"):
    kind = spec[0]
    if kind == "bilinear":
        return bsgi.BilinearPatch(name, spec[1])
    if kind == "triangle":
        return bsgi.TrianglePatch(name, spec[1])
    if kind == "nurbs":
        _, p, cu, cv, kwargs = spec
        return bsgi.NurbsSurface(name, p, cu, cv, **kwargs)
    _, pos, tris, uvs = spec
    return bsgi.MeshChart(name, pos, tris, uvs)


def check_surface(s, uv):
    assert s.name == "S"
    area, size = s.area, s.size
    assert area >= 0 and size >= 0  # inf allowed: the scene refuses it (test_fuzz_scene_solve)
    e = s.evaluate(uv)
    n = len(uv)
    for key in ("position", "dpdu", "dpdv", "x", "y", "normal"):
        assert e[key].shape == (n, 3)
    assert e["jacobian"].shape == (n,)
    assert s.in_domain(uv).shape == (n,)
    if np.isfinite(area) and area > 0 and np.isfinite(size):
        inside = ((uv >= 0) & (uv <= 1)).all(axis=1)  # the parameter domain [0, 1]^2
        finite(e["position"][inside], "points")
        for key in ("x", "y", "normal"):
            v = e[key][inside]
            ok = np.isfinite(v).all(axis=1)  # a frame at a singular point (a cone's tip) may be NaN
            np.testing.assert_allclose(np.linalg.norm(v[ok], axis=1), 1, atol=1e-6)
        for for_rays in (False, True):
            t = s.tessellate(for_rays)
            finite(t["positions"], "tessellation")
            if len(t["triangles"]):
                assert t["triangles"].max() < len(t["positions"])
            assert len(t["uvs"]) == len(t["positions"])


@settings(max_examples=examples(1500))
@given(spec=SURFACES, uv=arrays(st.integers(0, 8).map(lambda n: (n, 2)), st.one_of(unit_float, any_float)))
def test_surfaces_from_any_geometry(spec, uv):
    case(spec=spec, uv=uv)
    try:
        s = build(spec)
    except ValueError as e:
        refused(e, "'S'")
        return
    check_surface(s, uv)


@settings(max_examples=examples(400))
@given(specs=st.lists(SURFACES, min_size=0, max_size=4), origins=points(3), data=st.data(),
       panes=st.dictionaries(st.integers(-1, 4), any_float, max_size=2))
def test_ray_caster(specs, origins, data, panes):
    surfaces = []
    for spec in specs:
        try:
            surfaces.append(build(spec))
        except ValueError:
            pass
    n = origins.shape[0] if origins.ndim == 2 else 1
    directions = data.draw(st.one_of(arrays((n, 3)), arrays((n, 3), st.floats(-1, 1)), points(3)))
    case(specs=specs, origins=origins, directions=directions, panes=panes)
    try:
        caster = bsgi.RayCaster(surfaces, panes)
    except ValueError as e:
        refused(e, "panes", "'S'")
        return
    assert caster.offset >= 0
    try:
        hits = caster.closest_hit(origins, directions)
    except ValueError as e:
        refused(e, "origins", "directions", "rays")
        return
    m = len(hits["surface"])
    assert m == n and hits["position"].shape == (m, 3) and hits["frame"].shape == (m, 3, 3)
    hit = hits["surface"] >= 0
    assert (hits["surface"] < max(len(surfaces), 1)).all()
    finite(hits["t"][hit], "hit distances"), finite(hits["uv"][hit], "hit parameters")
    assert (hits["uv"][hit] >= -1e-6).all() and (hits["uv"][hit] <= 1 + 1e-6).all()
    assert np.isinf(hits["t"][~hit]).all()
    occluded = caster.occluded(origins, directions)
    t = caster.transmittance(origins, directions)
    assert occluded.shape == (m,) and t.shape == (m, 3)
    assert ((t >= 0) & (t <= 1)).all()
    assert (occluded >= hit).all() or panes  # a hit blocks unless it is a pane


# ---- BSDFs ----

ALPHA = st.one_of(st.floats(1e-4, 10), any_float)
BSDFS = st.one_of(
    st.builds(lambda a: ("Lambert", (a,)), rgb()),
    st.builds(lambda kd, ks, n: ("NormalizedPhong", (kd, ks, n)), rgb(st.floats(0, 0.5)), rgb(st.floats(0, 0.5)),
              st.one_of(st.floats(0, 1e6), any_float)),
    st.builds(lambda rd, rs, nu, nv: ("AshikhminShirley", (rd, rs, nu, nv)), rgb(), rgb(), st.one_of(st.floats(0, 1e4), any_float),
              st.one_of(st.floats(0, 1e4), any_float)),
    st.builds(lambda ax, ay, f0, r: ("GgxReflection", (ax, ay, f0, r)), ALPHA, ALPHA, rgb(), st.one_of(st.floats(-7, 7), any_float)),
    st.builds(lambda a, ax, ay, f0: ("DiffuseGgx", (a, ax, ay, f0)), rgb(), ALPHA, ALPHA, rgb()),
    st.builds(lambda eta: ("SmoothDielectric", (eta,)), st.one_of(st.floats(1, 3), any_float)),
    st.builds(lambda eta, ax, ay: ("RoughDielectric", (eta, ax, ay)), st.one_of(st.floats(1, 3), any_float), ALPHA, ALPHA),
)
DIRECTION = st.one_of(st.floats(-1, 1), st.sampled_from([0.0, 1.0, -1.0, 1e-300]), any_float)
UNIT = st.sampled_from([[0, 0, 1], [0, 0, -1], [1, 0, 0], [0.6, 0, 0.8], [0, -0.8, 0.6], [0.48, 0.6, 0.64]])


def unit(w):
    w = np.asarray(w, float)
    return (w.ndim == 2) & np.isfinite(w).all(axis=-1) & (np.abs(np.linalg.norm(w, axis=-1) - 1) < 1e-12)


def make_bsdf(spec):
    kind, args = spec
    return getattr(bsgi, kind)(*args)


@settings(max_examples=examples(1200))
@given(spec=BSDFS, data=st.data())
def test_bsdfs(spec, data):
    n = data.draw(st.integers(0, 6))
    wo = data.draw(st.one_of(arrays((n, 3), DIRECTION), st.lists(UNIT, min_size=n, max_size=n).map(lambda v: np.array(v, float).reshape(n, 3))))
    wi = data.draw(st.one_of(arrays((n, 3), DIRECTION), points(3), st.lists(UNIT, min_size=n, max_size=n).map(
        lambda v: np.array(v, float).reshape(n, 3))))
    u = data.draw(st.one_of(arrays((n, 3), unit_float), arrays((n, 3))))
    case(spec=spec, wo=wo, wi=wi, u=u)
    try:
        b = make_bsdf(spec)
    except ValueError as e:
        refused(e, "albedo", "kd", "ks", "rd", "rs", "exponent", "GGX", "eta", "dielectric", "Lambert", "Phong", "Ashikhmin")
        return
    assert isinstance(b.name, str)
    try:
        f, pdf = b.eval(wo, wi), b.pdf(wo, wi)
    except ValueError as e:
        refused(e, "wo", "wi")
    else:
        # BSDFs take unit directions: for those, values and densities are finite and >= 0.
        with np.errstate(all="ignore"):
            good = unit(wo) & unit(wi)
        assert f.shape == (n, 3) and pdf.shape == (n,)
        assert (finite(f[good], "eval") >= 0).all() and (finite(pdf[good], "pdf") >= 0).all()
    try:
        s = b.sample(wo, u)
    except ValueError as e:
        refused(e, "wo", "u")
        return
    # Samples of unit directions wo from random numbers u in [0, 1)^3 are unit directions (u = 1 is outside:
    # SmoothDielectric(0.5) then refracts under total internal reflection).
    ok = s["valid"] & unit(wo) & ((u >= 0) & (u < 1)).all(axis=1)  # uniform numbers in [0, 1)
    finite(s["weight"][ok], "sample weight"), finite(s["pdf"][ok], "sample pdf")
    assert (s["weight"][ok] >= 0).all()
    np.testing.assert_allclose(np.linalg.norm(finite(s["wi"][ok]), axis=1), 1, rtol=1e-6)
    sides = b.index_on_side(wo)
    assert sides.shape == (n,)


@settings(max_examples=examples(300))
@given(radiance=rgb(st.floats(0, 1e6)), two_sided=st.booleans(), w=points(3), u=points(3, elements=unit_float))
def test_emission(radiance, two_sided, w, u):
    case(radiance=radiance, two_sided=two_sided, w=w, u=u)
    try:
        e = bsgi.Emission(radiance, two_sided)
    except ValueError as err:
        refused(err, "radiance")
        return
    for call, x in ((e.eval, w), (e.pdf, w)):
        try:
            out = call(x)
        except ValueError as err:
            refused(err, "w")
            continue
        rows = x.reshape(-1, 3)
        ok = np.isfinite(rows).all(axis=1) & (np.linalg.norm(rows, axis=1) > 1e-100)
        assert (finite(np.asarray(out)[ok]) >= 0).all()
    try:
        d, pdf = e.sample(u)
    except ValueError as err:
        refused(err, "u")
        return
    ok = pdf > 0
    np.testing.assert_allclose(np.linalg.norm(finite(d[ok]), axis=1), 1, rtol=1e-6)
