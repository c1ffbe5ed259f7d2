"""Multiple scattering between GGX microfacets (bsdf.h MultipleScattering: Cycles' Multiscatter
GGX, the default of its Principled, Glossy and Anisotropic BSDFs), against closed forms: a white
lobe reflects all of its light at every angle, and a coloured one what Kulla and Conty's model
gives from the single-scattering lobe's own directional albedo (a quadrature independent of the
core's tables)."""
import numpy as np
import pytest

import bsgi
from closed_forms import directional_albedo

MUS = (1.0, 0.7, 0.4, 0.2, 0.08)


def sampled_albedo(bsdf, mu, n=400000):
    """The directional albedo as the mean weight of n samples of the lobe (eval cos / pdf, 0
    where none is drawn): unbiased for any pdf, and nearly noiseless for a GGX lobe, whose
    weight is near constant (a narrow lobe's peak falls between the midpoint rule's nodes).
    mu: the view's cosine, or the view itself."""
    view = np.asarray(mu, float) if np.ndim(mu) else np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    wo = np.tile(view, (n, 1))
    s = type(bsdf).sample(bsdf, wo, np.random.default_rng(5).uniform(size=(n, 3)))
    return float(np.where(s["valid"], s["weight"][:, 0], 0.0).mean())


@pytest.mark.parametrize("height_correlated", [False, True])
@pytest.mark.parametrize("alpha", [0.09, 0.25, 0.5, 1.0])
def test_white_lobe_with_multiple_scattering_is_a_white_furnace(alpha, height_correlated):
    # Measured: within 6e-4 at every angle, with either shadowing; single scattering keeps
    # 0.31-0.57 of the light at alpha 1 (1 - ln 2 along the normal, with either), 0.87-0.99 at 0.09.
    white = bsgi.GgxReflection(alpha, alpha, [1, 1, 1], schlick=False, multiscatter=True,
                               height_correlated=height_correlated)
    single = bsgi.GgxReflection(alpha, alpha, [1, 1, 1], schlick=False, height_correlated=height_correlated)
    got = np.array([sampled_albedo(white, mu) for mu in MUS])
    lost = np.array([sampled_albedo(single, mu) for mu in MUS])
    print(f"\nalpha {alpha}, height-correlated {height_correlated}: multiscatter {np.round(got, 4)}, "
          f"single {np.round(lost, 4)}")
    assert np.abs(got - 1).max() < 1.2e-3
    assert lost.min() < 0.9
    if alpha == 1.0:
        assert abs(lost[0] - (1 - np.log(2))) < 1e-3  # the closed form of the single lobe along the normal


@pytest.mark.parametrize("kind", ["schlick", "constant", "dielectric"])
def test_coloured_lobe_reflects_kulla_contys_multiple_scattering(kind):
    # rho_ms = rho (1 + F_ms (1 - E(mu)) / E(mu)), F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)): its
    # directional albedo is E_F(mu) (1 + F_ms (1 - E) / E), E_F the single lobe's with its Fresnel,
    # E the white lobe's, both by the quadrature here; F_ss = f0 + (1 - f0) / 21 for Schlick's
    # curve, f0 for a constant one, the dielectric's by quadrature. Measured: within 1.3e-4 (the
    # metal's colour: 20-41% more light at mu 0.4, alpha 0.5; a dielectric's 2.8%).
    alpha = 0.5
    f0 = np.array([0.95, 0.64, 0.54]) if kind != "dielectric" else np.array([0.04] * 3)
    keywords = {"schlick": {}, "constant": {"schlick": False}, "dielectric": {"eta": 1.5}}[kind]
    coloured = bsgi.GgxReflection(alpha, alpha, f0, multiscatter=True, **keywords)
    single = bsgi.GgxReflection(alpha, alpha, f0, **keywords)
    white = bsgi.GgxReflection(alpha, alpha, [1, 1, 1], schlick=False)
    mus = (np.arange(64) + 0.5) / 64
    e = np.array([directional_albedo(white, mu, 200)[0] for mu in mus])
    e_avg = 2 * np.mean(e * mus)
    if kind == "schlick":
        f_ss = f0 + (1 - f0) / 21
    elif kind == "constant":
        f_ss = f0
    else:  # the dielectric's curve remapped to f0 (here its own f0): the Fresnel equations
        c = mus
        t = np.sqrt(1 - (1 - c**2) / 1.5**2)
        f = 0.5 * (((c - 1.5 * t) / (c + 1.5 * t)) ** 2 + ((1.5 * c - t) / (1.5 * c + t)) ** 2)
        f_ss = np.full(3, 2 * np.mean(f * c))
    f_ms = f_ss * e_avg / (1 - f_ss * (1 - e_avg))
    worst = 0.0
    for mu in MUS:
        e_mu = directional_albedo(white, mu)[0]
        want = directional_albedo(single, mu) * (1 + f_ms * (1 - e_mu) / e_mu)
        worst = max(worst, np.abs(directional_albedo(coloured, mu) / want - 1).max())
    gain = directional_albedo(coloured, 0.4) / directional_albedo(single, 0.4) - 1
    print(f"\n{kind}: worst {worst:.2e}; multiple scattering adds {np.round(gain * 100, 1)}% at mu 0.4")
    assert gain.max() > 0.004
    assert worst < 3e-4


def test_layered_coat_with_multiple_scattering_over_a_white_base_is_a_white_furnace():
    # The base gets what the coat, its multiple scattering included, leaves along the view.
    layered = bsgi.DiffuseGgx([1, 1, 1], 0.5, 0.5, [0.04] * 3, layered=True, eta=1.5, multiscatter=True)
    got = np.array([directional_albedo(layered, mu)[0] for mu in MUS])
    print(f"\nlayered coat, multiscatter: {np.round(got, 4)}")
    assert np.abs(got - 1).max() < 2e-3


def test_multiple_scattering_is_a_choice_of_the_lobe():
    assert bsgi.GgxReflection(0.3, 0.3, [0.9] * 3, multiscatter=True).multiscatter
    assert not bsgi.GgxReflection(0.3, 0.3, [0.9] * 3).multiscatter


@pytest.mark.parametrize("height_correlated", [False, True])
@pytest.mark.parametrize("eta", [1.1, 1.5, 2.4])
@pytest.mark.parametrize("alpha", [0.3, 1.0])
def test_glass_with_multiple_scattering_is_a_white_furnace_from_either_side(alpha, eta, height_correlated):
    # Cycles' Multiscatter GGX glass: the single-scattering lobe over its directional albedo E(mu_o)
    # (reflected plus transmitted energy, from the side of the view), so with the light carried
    # across as Cycles carries it (scale_radiance off) it keeps all of it at every angle, outside
    # and inside (there total internal reflection's edge crosses the table). Measured on 7
    # December with 400,000 samples over alpha 0.1-1, eta 1.1-2.4: within 2.8e-3 (alpha 0.5, eta
    # 1.5, inside at mu 0.08), with 200,000 here within 4e-3 (alpha 1, eta 1.1, separable: the
    # samples' noise); single scattering keeps 0.13-1.
    worst, lost = 0.0, 1.0
    for side in (1, -1):
        for mu in MUS:
            wo = np.array([np.sqrt(1 - mu * mu), 0.0, side * mu])
            glass = bsgi.RoughDielectric(eta, alpha, alpha, multiscatter=True, height_correlated=height_correlated,
                                         scale_radiance=False)
            single = bsgi.RoughDielectric(eta, alpha, alpha, height_correlated=height_correlated, scale_radiance=False)
            worst = max(worst, abs(sampled_albedo(glass, wo, 200000) - 1))
            lost = min(lost, sampled_albedo(single, wo, 200000))
    print(f"\nglass alpha {alpha} eta {eta} height-correlated {height_correlated}: |E_ms - 1| <= {worst:.2e}, "
          f"single scattering down to {lost:.3f}")
    assert worst < 5e-3
    assert lost < 0.9


def branch_albedos(bsdf, wo, n=200000):
    """The light a glass sends back to wo's side and through it, per channel (RGB), from n of its
    own samples (the mean weight of those on each side)."""
    s = type(bsdf).sample(bsdf, np.tile(wo, (n, 1)), np.random.default_rng(7).uniform(size=(n, 3)))
    same = s["valid"] & (s["wi"][:, 2] * wo[2] > 0)
    through = s["valid"] & (s["wi"][:, 2] * wo[2] < 0)
    return (np.where(same[:, None], s["weight"], 0).mean(axis=0),
            np.where(through[:, None], s["weight"], 0).mean(axis=0))


@pytest.mark.parametrize("side", [1, -1])
def test_tinted_glass_puts_back_kulla_contys_light_of_its_transmission_tint(side):
    # Cycles' tinted glass (svm closure.h: a Glass BSDF's colour tints both branches, a Principled
    # BSDF's sqrt(base colour) the transmitted one; microfacet_ggx_preserve_energy takes the
    # transmission tint as F_ss): E_tinted(mu) = (R E_r + T E_t)(1 + F_ms (1 - E) / E), E_r and
    # E_t the clear single-scattering glass's reflected and transmitted energy, E their sum and
    # E_avg = 2 int E mu dmu over the side of the view, F_ms = T E_avg / (1 - T (1 - E_avg)), all
    # here from the clear glass's samples (the core's E is a table by another rule).
    alpha, eta = 0.5, 1.5
    reflection, transmission = np.array([0.9, 0.6, 0.3]), np.array([0.8, 0.5, 0.2])
    tinted = bsgi.RoughDielectric(eta, alpha, alpha, multiscatter=True, height_correlated=True, scale_radiance=False,
                                  reflection_tint=reflection, transmission_tint=transmission)
    clear = bsgi.RoughDielectric(eta, alpha, alpha, height_correlated=True, scale_radiance=False)

    def view(mu):
        return np.array([np.sqrt(1 - mu * mu), 0.0, side * mu])

    mus = (np.arange(32) + 0.5) / 32
    e_avg = 2 * np.mean([sum(branch_albedos(clear, view(mu), 50000))[0] * mu for mu in mus])
    f_ms = transmission * e_avg / (1 - transmission * (1 - e_avg))
    worst, darker = 0.0, 0.0
    for mu in MUS:
        e_r, e_t = (e[0] for e in branch_albedos(clear, view(mu)))
        e = e_r + e_t
        want = (reflection * e_r + transmission * e_t) * (1 + f_ms * (1 - e) / e)
        got = sum(branch_albedos(tinted, view(mu)))
        worst = max(worst, np.abs(got / want - 1).max())
        # What the tint's repeated bounces take: the clear glass's 1 / E would give more.
        darker = max(darker, ((reflection * e_r + transmission * e_t) / e / got - 1).max())
    print(f"\ntinted glass, {'outside' if side > 0 else 'inside'}: worst {worst:.2e}, E_avg {e_avg:.4f}; "
          f"1 / E would give up to {darker * 100:.1f}% more")
    assert darker > 0.01
    assert worst < 3e-3
