"""BSDFs: reciprocity, energy (white furnace by numerical integration), sampling against the
pdf (chi-square), GGX against Mitsuba 3's roughconductor."""
import pathlib
import sys

import numpy as np
import pytest
from scipy.stats import chi2

import bsgi


def direction(cos_theta, phi):
    s = np.sqrt(np.maximum(0, 1 - cos_theta ** 2))
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), cos_theta])


def quadrature(n_cos, n_phi, lo=0.0, hi=1.0):
    """Midpoint rule over cos(theta) in [lo, hi] and phi: nodes and solid-angle weights."""
    c = lo + (hi - lo) * (np.arange(n_cos) + 0.5) / n_cos
    p = 2 * np.pi * (np.arange(n_phi) + 0.5) / n_phi
    C, P = np.meshgrid(c, p, indexing="ij")
    return direction(C.ravel(), P.ravel()), np.full(C.size, (hi - lo) / n_cos * 2 * np.pi / n_phi)


def random_directions(rng, n, lower=False):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 2] = np.abs(d[:, 2]) * (-1 if lower else 1)
    return d[np.abs(d[:, 2]) > 0.02]


REFLECTORS = {
    "lambert": lambda: bsgi.Lambert([1.0, 0.5, 0.2]),
    "phong": lambda: bsgi.NormalizedPhong([0.3, 0.3, 0.3], [0.6, 0.5, 0.7], 30.0),
    "ashikhmin_shirley": lambda: bsgi.AshikhminShirley([0.4, 0.3, 0.2], [0.2, 0.5, 0.9], 60.0, 8.0),
    "ggx": lambda: bsgi.GgxReflection(0.35, 0.15, [1.0, 0.8, 0.3]),
    "ggx_rotated": lambda: bsgi.GgxReflection(0.4, 0.1, [1.0, 0.8, 0.3], rotation=2.0),
    "diffuse_ggx": lambda: bsgi.DiffuseGgx([0.5, 0.3, 0.2], 0.3, 0.2, [0.04, 0.04, 0.04]),
}


@pytest.mark.parametrize("name", [*REFLECTORS, "rough_dielectric"])
def test_eval_pdf_is_eval_and_pdf(name):
    # The gather takes both at once (GGX shares its half vector and D): the same as apart.
    b = REFLECTORS[name]() if name in REFLECTORS else bsgi.RoughDielectric(1.5, 0.3, 0.3)
    rng = np.random.default_rng(5)
    wo = np.vstack([random_directions(rng, 300), random_directions(rng, 50, lower=True)])
    wi = np.vstack([random_directions(rng, 300), random_directions(rng, 50, lower=True)])
    n = min(len(wo), len(wi))
    wo, wi = wo[:n], rng.permutation(wi[:n])
    values, pdf = b.eval_pdf(wo, wi)
    assert (pdf > 0).sum() > n // 3
    np.testing.assert_allclose(values, b.eval(wo, wi), rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(pdf, b.pdf(wo, wi), rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("name", REFLECTORS)
def test_reflection_is_reciprocal(name):
    b = REFLECTORS[name]()
    rng = np.random.default_rng(1)
    wo, wi = random_directions(rng, 2000), random_directions(rng, 2000)
    n = min(len(wo), len(wi))
    f, g = b.eval(wo[:n], wi[:n]), b.eval(wi[:n], wo[:n])
    assert f.max() > 0
    assert np.allclose(f, g, rtol=1e-12, atol=0)
    # One-sided: nothing through or from below the surface.
    assert not b.eval(wo[:n], -wi[:n]).any() and not b.eval(-wo[:n], wi[:n]).any()


def test_rough_dielectric_obeys_generalised_reciprocity():
    """f(wo, wi) / n(wo)^2 = f(wi, wo) / n(wi)^2 (radiance BTDFs carry the index squared)."""
    b = bsgi.RoughDielectric(1.5, 0.3, 0.2)
    rng = np.random.default_rng(2)
    for lower_o, lower_i in [(False, False), (False, True), (True, False), (True, True)]:
        wo, wi = random_directions(rng, 3000, lower_o), random_directions(rng, 3000, lower_i)
        n = min(len(wo), len(wi))
        wo, wi = wo[:n], wi[:n]
        f = b.eval(wo, wi)[:, 0] / b.index_on_side(wo) ** 2
        g = b.eval(wi, wo)[:, 0] / b.index_on_side(wi) ** 2
        assert f.max() > 0
        assert np.allclose(f, g, rtol=1e-8, atol=1e-300)


def albedo(b, wo, n=1200, full_sphere=False):
    """Directional albedo sum over wi of f(wo, wi) |cos theta_i| (n(wi)/n(wo))^2 domega: the
    fraction of power scattered (the index ratio turns radiance BTDFs into power)."""
    nodes, w = quadrature(n, n, -1.0 if full_sphere else 0.0, 1.0)
    wo_rep = np.tile(wo, (len(nodes), 1))
    f = b.eval(wo_rep, nodes)
    ratio = (b.index_on_side(nodes) / b.index_on_side(wo_rep)) ** 2
    return np.sum(f * (np.abs(nodes[:, 2]) * w * ratio)[:, None], axis=0)


FURNACE = {
    "lambert": (lambda: bsgi.Lambert([1.0, 1.0, 1.0]), False),
    # (DiffuseGgx is an uncoupled sum: its coat's Fresnel rises at grazing angles while the base
    # stays, so it can exceed 1 there; it is not in this list on purpose.)
    "phong": (lambda: bsgi.NormalizedPhong([0.4, 0.4, 0.4], [0.6, 0.6, 0.6], 40.0), False),
    "ashikhmin_shirley": (lambda: bsgi.AshikhminShirley([1.0, 1.0, 1.0], [0.05, 0.5, 1.0], 40.0, 5.0), False),
    "ggx": (lambda: bsgi.GgxReflection(0.3, 0.1, [1.0, 1.0, 1.0]), False),
    "rough_dielectric": (lambda: bsgi.RoughDielectric(1.5, 0.3, 0.3), True),
}


@pytest.mark.parametrize("name", FURNACE)
def test_white_furnace_albedo_at_most_one(name):
    make, full = FURNACE[name]
    b = make()
    for cos_o in [1.0, 0.8, 0.5, 0.2, 0.05]:
        for side in ([1, -1] if full else [1]):
            wo = direction(np.array([side * cos_o]), np.array([0.7]))
            a = albedo(b, wo, full_sphere=full)
            assert a.max() <= 1 + 2e-3, (cos_o, side, a)
            assert a.min() > 0.1, (cos_o, side, a)  # and not trivially zero


def test_lambert_and_phong_albedo_match_closed_forms():
    wo = direction(np.array([1.0]), np.array([0.0]))
    assert albedo(bsgi.Lambert([1.0, 0.5, 0.25]), wo) == pytest.approx([1.0, 0.5, 0.25], rel=1e-3)
    # A pure normalised Phong lobe at normal incidence: (n + 2)/(2 pi) int cos^(n+1) = 1.
    assert albedo(bsgi.NormalizedPhong([0, 0, 0], [1, 1, 1], 20.0), wo) == pytest.approx([1, 1, 1], rel=2e-3)


def test_smooth_dielectric_splits_power_by_fresnel_and_bends_by_snell():
    eta = 1.5
    b = bsgi.SmoothDielectric(eta)
    rng = np.random.default_rng(3)
    for lower in [False, True]:
        wo = random_directions(rng, 200, lower)
        u = rng.uniform(size=(len(wo), 3))
        s = b.sample(wo, u)
        n_o, n_i = (eta, 1.0) if lower else (1.0, eta)
        cos_o = np.abs(wo[:, 2])
        sin_t = n_o / n_i * np.sqrt(1 - cos_o ** 2)
        tir = sin_t >= 1
        cos_t = np.sqrt(np.maximum(0, 1 - sin_t ** 2))
        rs = (n_o * cos_o - n_i * cos_t) / (n_o * cos_o + n_i * cos_t)
        rp = (n_i * cos_o - n_o * cos_t) / (n_i * cos_o + n_o * cos_t)
        F = np.where(tir, 1.0, 0.5 * (rs ** 2 + rp ** 2))
        reflected = u[:, 0] < F
        assert s["valid"].all() and s["delta"].all()
        assert np.allclose(s["pdf"], np.where(reflected, F, 1 - F))
        assert np.allclose(s["wi"][reflected], wo[reflected] * [-1, -1, 1])
        t = ~reflected
        assert np.allclose(n_i * np.linalg.norm(s["wi"][t, :2], axis=1), n_o * np.linalg.norm(wo[t, :2], axis=1))  # Snell
        assert (np.sign(s["wi"][t, 2]) == -np.sign(wo[t, 2])).all()
        # Power: reflected F, transmitted (1 - F) once the radiance factor (n_o/n_i)^2 is undone.
        assert np.allclose(s["weight"][reflected], 1)
        assert np.allclose(s["weight"][t, 0] * (n_i / n_o) ** 2, 1)
        assert not b.eval(wo, s["wi"]).any() and not b.pdf(wo, s["wi"]).any()
        # Tinted: each branch's throughput times its tint, the choice between them unchanged.
        reflection, transmission = np.array([0.9, 0.5, 0.2]), np.array([0.3, 0.6, 0.9])
        tinted = bsgi.SmoothDielectric(eta, reflection_tint=reflection, transmission_tint=transmission).sample(wo, u)
        assert np.allclose(tinted["wi"], s["wi"]) and np.allclose(tinted["pdf"], s["pdf"])
        assert np.allclose(tinted["weight"], s["weight"] * np.where(reflected[:, None], reflection, transmission))


SAMPLED = {
    "lambert": (lambda: bsgi.Lambert([0.8, 0.8, 0.8]), False),
    "diffuse_ggx": (lambda: bsgi.DiffuseGgx([0.5, 0.5, 0.5], 0.25, 0.25, [0.3, 0.3, 0.3]), False),
    "phong": (lambda: bsgi.NormalizedPhong([0.3, 0.3, 0.3], [0.6, 0.6, 0.6], 25.0), False),
    "ashikhmin_shirley": (lambda: bsgi.AshikhminShirley([0.5, 0.5, 0.5], [0.3, 0.3, 0.3], 30.0, 4.0), False),
    "ggx": (lambda: bsgi.GgxReflection(0.4, 0.2, [0.9, 0.9, 0.9]), False),
    "ggx_rotated": (lambda: bsgi.GgxReflection(0.45, 0.12, [0.9, 0.9, 0.9], rotation=0.8), False),
    "ggx_multiscatter": (lambda: bsgi.GgxReflection(0.6, 0.6, [0.9, 0.6, 0.5], multiscatter=True), False),
    "ggx_height_correlated": (lambda: bsgi.GgxReflection(0.5, 0.2, [0.9, 0.6, 0.5], rotation=0.4, multiscatter=True,
                                                         height_correlated=True), False),
    "layered_coat_multiscatter": (lambda: bsgi.DiffuseGgx([0.5, 0.5, 0.5], 0.5, 0.5, [0.04] * 3, layered=True, eta=1.5,
                                                          multiscatter=True), False),
    "rough_dielectric": (lambda: bsgi.RoughDielectric(1.5, 0.35, 0.25), True),
    # A tint scales the branches' weights, not their density.
    "rough_dielectric_tinted": (lambda: bsgi.RoughDielectric(1.5, 0.35, 0.25, multiscatter=True, reflection_tint=[0.9, 0.5, 0.2],
                                                             transmission_tint=[0.3, 0.6, 0.9]), True),
}


def chi_square_p_value(b, wo, full, n=200000, bins=(24, 48), seed=0):
    rng = np.random.default_rng(seed)
    s = b.sample(np.tile(wo, (n, 1)), rng.uniform(size=(n, 3)))
    wi = s["wi"][s["valid"]]
    lo = -1.0 if full else 0.0
    nc, nphi = bins
    ci = np.clip(((wi[:, 2] - lo) / (1 - lo) * nc).astype(int), 0, nc - 1)
    pi = np.clip((np.mod(np.arctan2(wi[:, 1], wi[:, 0]), 2 * np.pi) / (2 * np.pi) * nphi).astype(int), 0, nphi - 1)
    observed = np.bincount(ci * nphi + pi, minlength=nc * nphi).astype(float)
    # Expected counts: the pdf integrated over each bin (8 x 8 midpoints per bin).
    nodes, w = quadrature(8 * nc, 8 * nphi, lo, 1.0)
    dens = b.pdf(np.tile(wo, (len(nodes), 1)), nodes) * w
    expected = n * dens.reshape(nc, 8, nphi, 8).sum(axis=(1, 3)).ravel()
    # Valid samples carry all the mass the pdf has (the rest are draws below the surface).
    assert abs(len(wi) - expected.sum()) < 5 * np.sqrt(n) + 2e-3 * n
    small = expected < 5
    obs = np.append(observed[~small], observed[small].sum())
    exp = np.append(expected[~small], expected[small].sum())
    keep = exp > 0
    stat = np.sum((obs[keep] - exp[keep]) ** 2 / exp[keep])
    return chi2.sf(stat, keep.sum() - 1), s


@pytest.mark.parametrize("name", SAMPLED)
def test_sampling_matches_pdf(name):
    make, full = SAMPLED[name]
    b = make()
    for k, cos_o in enumerate([0.9, 0.4, -0.6] if full else [0.9, 0.4]):
        wo = direction(np.array([cos_o]), np.array([1.1]))
        p, s = chi_square_p_value(b, wo, full, seed=k)
        assert p > 1e-3, (name, cos_o, p)
        # Weights are eval |cos| / pdf at the drawn directions.
        ok = s["valid"]
        wo_rep = np.tile(wo, (ok.sum(), 1))
        expect = b.eval(wo_rep, s["wi"][ok]) * (np.abs(s["wi"][ok, 2]) / b.pdf(wo_rep, s["wi"][ok]))[:, None]
        assert np.allclose(s["weight"][ok], expect, rtol=1e-10)
        assert np.allclose(s["pdf"][ok], b.pdf(wo_rep, s["wi"][ok]), rtol=1e-12)


def test_sampling_test_detects_a_wrong_pdf():
    """The chi-square check is not toothless: a Phong lobe sampled with another exponent's pdf
    fails it."""
    class Mismatched:
        def __init__(self):
            self.sampler = bsgi.NormalizedPhong([0.0] * 3, [1.0] * 3, 25.0)
            self.density = bsgi.NormalizedPhong([0.0] * 3, [1.0] * 3, 22.0)

        def sample(self, wo, u):
            return self.sampler.sample(wo, u)

        def pdf(self, wo, wi):
            return self.density.pdf(wo, wi)

    p, _ = chi_square_p_value(Mismatched(), direction(np.array([0.9]), np.array([1.1])), False)
    assert p < 1e-6


def test_emission_is_one_sided_and_cosine_sampled():
    e = bsgi.Emission([2.0, 1.0, 0.5])
    up, down = direction(np.array([0.5]), np.array([0.3])), direction(np.array([-0.5]), np.array([0.3]))
    assert np.allclose(e.eval(up), [[2, 1, 0.5]]) and not e.eval(down).any()
    nodes, w = quadrature(400, 400, -1, 1)
    assert np.sum(e.pdf(nodes) * w) == pytest.approx(1, rel=1e-4)
    two = bsgi.Emission([1.0, 1.0, 1.0], two_sided=True)
    assert np.allclose(two.eval(down), 1) and np.sum(two.pdf(nodes) * w) == pytest.approx(1, rel=1e-4)
    d, pdf = e.sample(np.random.default_rng(0).uniform(size=(50000, 3)))
    assert np.allclose(pdf, d[:, 2] / np.pi)
    assert np.mean(d[:, 2]) == pytest.approx(2 / 3, abs=5e-3)  # E[cos] under cos/pi is 2/3


@pytest.mark.parametrize("make,message", [
    (lambda: bsgi.Lambert([1.2, 0, 0]), "albedo"),
    (lambda: bsgi.NormalizedPhong([0.6] * 3, [0.6] * 3, 10), "kd \\+ ks"),
    (lambda: bsgi.NormalizedPhong([0.1] * 3, [0.1] * 3, -1), "exponent"),
    (lambda: bsgi.AshikhminShirley([0.1] * 3, [0.1] * 3, np.nan, 1), "nu"),
    (lambda: bsgi.GgxReflection(0.0, 0.1, [1, 1, 1]), "alpha"),
    (lambda: bsgi.RoughDielectric(-1.5, 0.1, 0.1), "eta"),
    (lambda: bsgi.RoughDielectric(1.5, 0.1, 0.1, transmission_tint=[1.2, 1, 1]), "transmission tint"),
    (lambda: bsgi.SmoothDielectric(1.5, reflection_tint=[0.5, np.nan, 1]), "reflection tint"),
    (lambda: bsgi.Emission([-1, 0, 0]), "radiance"),
])
def test_bad_parameters_are_refused(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def assert_eval_and_pdf_are_mitsubas(mi, ctx, ref, ours, wo, wi, mi_wo, mi_wi, label):
    """Our BSDF value times cos(wi) and pdf at (wo, wi) equal Mitsuba's at (mi_wo, mi_wi), the same
    directions in Mitsuba's frame. Mitsuba's si.wi is our wo (towards the viewer), its wo our wi;
    its eval includes cos(wi)."""
    f = ours.eval(wo, wi)[:, 0] * wi[:, 2]
    pdf = ours.pdf(wo, wi)
    for k in range(len(wo)):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*mi_wo[k])
        value = ref.eval(ctx, si, mi.Vector3f(*mi_wi[k]))[0]
        assert f[k] == pytest.approx(value, rel=1e-5, abs=1e-7 * max(f.max(), 1)), (*label, wo[k], wi[k])
        assert pdf[k] == pytest.approx(ref.pdf(ctx, si, mi.Vector3f(*mi_wi[k])), rel=1e-5,
                                       abs=1e-7 * max(pdf.max(), 1))

def test_height_correlated_ggx_is_heitz_form_as_cycles_evaluates_it():
    # Cycles' GGX (bsdf_microfacet.h): F D / (4 cos_o cos_i (1 + Lambda(wo) + Lambda(wi))) with
    # the anisotropic Lambda(w) = (sqrt(1 + (ax^2 wx^2 + ay^2 wy^2) / wz^2) - 1) / 2, written out
    # here against the core at random directions; the separable form shadows more at grazing.
    ax, ay, f0 = 0.5, 0.2, np.array([0.9, 0.6, 0.5])
    b = bsgi.GgxReflection(ax, ay, f0, height_correlated=True)
    separable = bsgi.GgxReflection(ax, ay, f0)
    assert b.height_correlated and not separable.height_correlated
    rng = np.random.default_rng(3)
    wo, wi = (d / np.linalg.norm(d, axis=1, keepdims=True)
              for d in (rng.normal(size=(500, 3)) * [1, 1, 0.5] + [0, 0, 0.6], rng.normal(size=(500, 3)) * [1, 1, 0.5] + [0, 0, 0.6]))
    up = (wo[:, 2] > 0.01) & (wi[:, 2] > 0.01)
    wo, wi = wo[up], wi[up]
    h = (wo + wi) / np.linalg.norm(wo + wi, axis=1, keepdims=True)
    d = 1 / (np.pi * ax * ay * ((h[:, 0] / ax) ** 2 + (h[:, 1] / ay) ** 2 + h[:, 2] ** 2) ** 2)

    def lam(w):
        return (np.sqrt(1 + ((ax * w[:, 0]) ** 2 + (ay * w[:, 1]) ** 2) / w[:, 2] ** 2) - 1) / 2

    c = np.einsum("ij,ij->i", wi, h)
    fresnel = f0 + (1 - f0) * ((1 - c) ** 5)[:, None]
    want = fresnel * (d / (4 * wo[:, 2] * wi[:, 2] * (1 + lam(wo) + lam(wi))))[:, None]
    np.testing.assert_allclose(b.eval(wo, wi), want, rtol=1e-10)
    grazing = (wo[:, 2] < 0.3) & (wi[:, 2] < 0.3)
    ratio = separable.eval(wo, wi)[grazing, 0] / want[grazing, 0]
    assert grazing.sum() > 10 and (ratio < 1).all() and ratio.mean() < 0.9


def test_rough_glass_as_cycles_is_its_formula_and_mitsubas_less_the_radiance_factor():
    # Cycles' glass (bsdf_microfacet.h, single scattering), its BSDF with the view wo above the
    # normal it is flipped to (ior = n_t / n_o from the view's side): reflected F D / (4 cos_o
    # cos_i (1 + L(wo) + L(wi))), transmitted (1 - F) D ior^2 |h.wo h.wi| / (cos_o |cos_i|
    # |ior wi + wo|^2 (1 + L(wo) + L(wi))), h along -(ior wi + wo): no (n_o / n_i)^2 on the light
    # it carries (Mitsuba's radiance has it), written out here against the core on both sides.
    eta, alpha = 1.45, 0.4
    cycles = bsgi.RoughDielectric(eta, alpha, alpha, height_correlated=True, scale_radiance=False)
    mitsuba = bsgi.RoughDielectric(eta, alpha, alpha)
    rng = np.random.default_rng(11)

    def lam(w):
        return (np.sqrt(1 + alpha ** 2 * (w[:, 0] ** 2 + w[:, 1] ** 2) / w[:, 2] ** 2) - 1) / 2

    def fresnel(c, ior):
        s2 = (1 - c * c) / ior ** 2
        ct = np.sqrt(np.maximum(1 - s2, 0))
        rs, rp = (c - ior * ct) / (c + ior * ct), (ior * c - ct) / (ior * c + ct)
        return np.where(s2 >= 1, 1.0, 0.5 * (rs ** 2 + rp ** 2))

    def cycles_eval(wo, wi, ior):
        d = lambda h: alpha ** 2 / (np.pi * (1 + (alpha ** 2 - 1) * h[:, 2] ** 2) ** 2)
        g = 1 / (1 + lam(wo) + lam(wi))
        up = wi[:, 2] > 0
        h = np.where(up[:, None], wo + wi, -(ior * wi + wo))
        length = np.linalg.norm(h, axis=1)
        h = h / length[:, None]
        h *= np.sign(h[:, 2])[:, None]
        c_o, c_i = np.einsum("ij,ij->i", wo, h), np.einsum("ij,ij->i", wi, h)
        F = fresnel(np.abs(c_o), ior)
        reflected = F * d(h) * g / (4 * wo[:, 2] * wi[:, 2])
        refracted = (1 - F) * d(h) * g * ior ** 2 * np.abs(c_o * c_i) / (wo[:, 2] * np.abs(wi[:, 2]) * length ** 2)
        # Only microfacets seen from both sides refract (h.wo > 0 > h.wi).
        refracted = np.where((c_o > 0) & (c_i < 0), refracted, 0.0)
        return np.where(up, reflected, refracted)

    checked = 0
    for below in (False, True):  # the view outside (above) or inside the glass
        for light_below in (False, True):
            wo, wi = random_directions(rng, 800, below), random_directions(rng, 800, light_below)
            n = min(len(wo), len(wi))
            wo, wi = wo[:n], wi[:n]
            flip = np.array([1, 1, -1]) if below else np.array([1, 1, 1])
            ior = 1 / eta if below else eta
            want = cycles_eval(wo * flip, wi * flip, ior)
            got = cycles.eval(wo, wi)[:, 0]
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * want.max())
            checked += (want > 0).sum()
            # Mitsuba's radiance carries (n_o / n_i)^2 across, the rest is the shadowing alone.
            crossing = light_below != below
            n_o, n_i = (eta, 1.0) if below else (1.0, eta)
            ratio = mitsuba.eval(wo, wi)[:, 0] / np.where(want > 0, want, np.nan)
            ratio /= (n_o / n_i) ** 2 if crossing else 1.0
            steep = (np.abs(wo[:, 2]) > 0.7) & (np.abs(wi[:, 2]) > 0.7) & (want > 0)
            # Near the normal both shadowings are near 1: there the two differ by the factor only.
            np.testing.assert_allclose(ratio[steep], 1.0, atol=0.03)
    assert checked > 1000


def test_ggx_matches_mitsuba_roughconductor():
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    rng = np.random.default_rng(7)
    ctx = mi.BSDFContext()
    for ax, ay in [(0.1, 0.1), (0.3, 0.3), (0.5, 0.2), (0.15, 0.6)]:
        # material 'none': Mitsuba's perfect mirror, Fresnel 1 (our f0 = 1).
        ref = mi.load_dict({"type": "roughconductor", "distribution": "ggx", "alpha_u": ax, "alpha_v": ay, "material": "none"})
        ours = bsgi.GgxReflection(ax, ay, [1.0, 1.0, 1.0])
        wo, wi = random_directions(rng, 300), random_directions(rng, 300)
        n = min(len(wo), len(wi))
        wo, wi = wo[:n], wi[:n]
        assert_eval_and_pdf_are_mitsubas(mi, ctx, ref, ours, wo, wi, wo, wi, (ax, ay))


def test_coloured_ggx_is_the_study_references_metal():
    # Cycles' metals (Principled BSDF, F82 tint white) reflect with Schlick's Fresnel from the base
    # colour, as the solver's GGX (its Glossy BSDF: the colour, no Fresnel, as the solver's with
    # schlick off), both with Cycles' height-correlated shadowing, as the add-on makes them; the
    # study's Mitsuba converter makes them its plugin of Cycles' lobe (cycles_glossy.py). Equal in
    # every RGB channel at random direction pairs, isotropic and anisotropic (Blender's
    # Anisotropic 0.8, alpha_u / alpha_v = 1 / (1 - 0.9 a)). A conductor of that f0 (k = 0; the
    # converter until 6 December) is 20% darker at grazing angles: not equal.
    pytest.importorskip("mitsuba")
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "bench" / "study"))
    import cycles_glossy
    import drjit as dr
    import mitsuba_scene
    from blend_scene import Material

    mi = mitsuba_scene.load_mitsuba()
    cycles_glossy.register(mi)
    rng = np.random.default_rng(8)
    ctx = mi.BSDFContext()

    def mitsuba_eval(bsdf, wo, wi):
        si = dr.zeros(mi.SurfaceInteraction3f, len(wo))
        si.wi = mi.Vector3f(wo[:, 0], wo[:, 1], wo[:, 2])
        value = bsdf.eval(ctx, si, mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2]))
        return np.stack([np.array(value[c]) for c in range(3)], axis=1)

    # (The last: a Glossy BSDF, Cycles' colour times GGX without Fresnel, and the solver's GGX with schlick off.)
    for f0, roughness, anisotropic, schlick in [((0.95, 0.64, 0.54), 0.6, 0.0, True), ((1.0, 0.76, 0.33), 0.6, 0.8, True),
                                                ((0.8, 0.83, 0.87), 0.3, 0.0, True), ((0.8, 0.7, 0.6), 0.6, 0.0, False)]:
        stretch = 1 / np.sqrt(1 - 0.9 * anisotropic)
        material = Material((0.0,) * 3, f0, roughness, 0.0, 1.5, (0.0,) * 3, stretch, schlick=schlick)
        ref = mi.load_dict(mitsuba_scene.bsdf(material))
        alpha = roughness ** 2
        ours = bsgi.GgxReflection(alpha * stretch, alpha / stretch, list(f0), schlick=schlick, height_correlated=True)
        wo, wi = random_directions(rng, 200), random_directions(rng, 200)
        n = min(len(wo), len(wi))
        wo, wi = wo[:n], wi[:n]
        f = ours.eval(wo, wi) * wi[:, 2:3]
        np.testing.assert_allclose(mitsuba_eval(ref, wo, wi), f, rtol=1e-5, atol=1e-7 * max(f.max(), 1), err_msg=str(f0))
    f0 = (0.8, 0.83, 0.87)
    ours = bsgi.GgxReflection(0.09, 0.09, f0)
    s = np.sqrt(np.array(f0))
    conductor = mi.load_dict({"type": "roughconductor", "distribution": "ggx", "alpha": 0.09,
                              "eta": {"type": "rgb", "value": ((1 + s) / (1 - s)).tolist()},
                              "k": {"type": "rgb", "value": [0.0] * 3}})
    viewer, light = np.array([[np.sin(1.45), 0, np.cos(1.45)]]), np.array([[-np.sin(1.45), 0, np.cos(1.45)]])  # 83 degrees
    ratio = mitsuba_eval(conductor, viewer, light)[0] / (ours.eval(viewer, light)[0] * light[0, 2])
    assert ratio.min() < 0.95, ratio


def test_rotated_anisotropic_ggx_is_mitsubas_roughconductor_in_the_turned_frame():
    """rotation turns the alpha_x axis from s_u (x) towards y about the normal: our BSDF at local
    directions equals Mitsuba's unrotated one at the directions' coordinates in the turned frame."""
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    rng = np.random.default_rng(11)
    ctx = mi.BSDFContext()
    for ax, ay, phi in [(0.4, 0.1, 0.25 * 2 * np.pi), (0.12, 0.5, 0.7), (0.3, 0.08, -2.4)]:
        ref = mi.load_dict({"type": "roughconductor", "distribution": "ggx", "alpha_u": ax, "alpha_v": ay, "material": "none"})
        ours = bsgi.GgxReflection(ax, ay, [1.0, 1.0, 1.0], rotation=phi)
        wo, wi = random_directions(rng, 200), random_directions(rng, 200)
        n = min(len(wo), len(wi))
        wo, wi = wo[:n], wi[:n]
        # Coordinates along the turned tangent t = (cos phi, sin phi, 0) and b = z x t.
        c, s = np.cos(phi), np.sin(phi)
        def turned(w):
            return np.column_stack([c * w[:, 0] + s * w[:, 1], -s * w[:, 0] + c * w[:, 1], w[:, 2]])
        two, twi = turned(wo), turned(wi)
        assert_eval_and_pdf_are_mitsubas(mi, ctx, ref, ours, wo, wi, two, twi, (ax, ay, phi))
    # The turn matters: a quarter turn swaps the axes, so an unturned lobe differs.
    a, b = bsgi.GgxReflection(0.4, 0.1, [1.0] * 3, rotation=np.pi / 2), bsgi.GgxReflection(0.1, 0.4, [1.0] * 3)
    c0 = bsgi.GgxReflection(0.4, 0.1, [1.0] * 3)
    wo, wi = random_directions(rng, 50), random_directions(rng, 50)
    n = min(len(wo), len(wi))
    assert np.allclose(a.eval(wo[:n], wi[:n]), b.eval(wo[:n], wi[:n]), rtol=1e-10)
    assert not np.allclose(a.eval(wo[:n], wi[:n]), c0.eval(wo[:n], wi[:n]), rtol=1e-2)
