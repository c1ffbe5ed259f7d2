"""Cycles' Principled BSDF without metal or transmission, as a Mitsuba 3 BSDF for the references: a
Lambertian base under a GGX dielectric coat, layered as Cycles layers it. The base gets what the
coat leaves along the view, f = (1 - E(mu_o)) base / pi + GGX(alpha) with the dielectric's Fresnel,
E the coat's directional albedo; with Multiscatter GGX (Cycles' default) the coat's light between
microfacets put back as in cycles_glossy.py, and E with it. (Mitsuba's roughplastic models the coat's internal scattering
instead: its albedo over a base of 0.8 is 0.60 at roughness 0.5 and 0.27 at 1, where Cycles' is
0.81 and 0.80.)

E is tabulated here by a numpy quadrature of the coat (Walter et al.'s GGX with Smith's
height-correlated shadowing, as Cycles', and the Fresnel equations), independent of the solver's core; the test of this plugin compares its
directional albedo with Cycles' own (tests/reference/test_mitsuba_scene.py)."""
from __future__ import annotations

import numpy as np

import cycles_bsdf  # (beside this file)
import cycles_glossy
from cycles_bsdf import TABLE_NODES, fresnel

NAME = "cycles_principled"


def albedo_table(alpha, eta):
    """The coat's directional albedo (its BRDF times cos over the hemisphere) at the table's nodes."""
    return cycles_bsdf.table(lambda mu: cycles_bsdf.reflection_albedo(mu, alpha, eta, 512))


def multiscatter_factors(alpha, eta):
    """With Cycles' Multiscatter GGX (cycles_glossy.py), the coat's factor 1 + F_ms (1 - E) / E
    at the table's nodes (E the white lobe's; F_ss the dielectric's cosine-weighted mean)."""
    white = cycles_glossy.albedo_table(alpha)
    mu = (np.arange(2048) + 0.5) / 2048
    f_ss = 2 * np.mean(fresnel(mu, eta) * mu)
    f_ms = float(cycles_bsdf.multiple_scattering_colour(white, [f_ss])[0])
    return 1 + f_ms * (1 - white) / np.maximum(white, 1e-3)


def register(mi):
    """Registers the plugin with Mitsuba (its JIT variant: llvm_ad_rgb), once."""
    import drjit as dr

    if getattr(register, "done", False):
        return

    class CyclesPrincipled(cycles_bsdf.plugin_base(mi, dr)):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.base = mi.Color3f(props["base_r"], props["base_g"], props["base_b"])
            self.alpha = float(props["alpha"])
            self.eta = float(props["eta"])
            table, factors = albedo_table(self.alpha, self.eta), np.ones(TABLE_NODES)
            if bool(props["multiscatter"]):
                factors = multiscatter_factors(self.alpha, self.eta)
            # The coat's albedo with its multiple scattering, which the base gives up.
            self.table = mi.Float(table * factors)
            self.factors = mi.Float(factors)
            self.distribution = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, self.alpha, True)
            diffuse = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            glossy = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            self.m_components = [diffuse, glossy]
            self.m_flags = diffuse | glossy
            mean = (props["base_r"] + props["base_g"] + props["base_b"]) / 3
            self.p_diffuse = float(np.clip(mean / (mean + 0.2), 0.1, 0.9))

        def _e(self, mu):
            return self._at(self.table, mu)

        def _lambda(self, c):
            tan2 = dr.maximum(1 - c * c, 0.0) / dr.maximum(c * c, 1e-12)
            return (dr.sqrt(1 + self.alpha * self.alpha * tan2) - 1) / 2

        def _value(self, si, wo):
            # si.wi: towards the viewer (the light leaving); wo: towards the light (Mitsuba's names).
            cos_v, cos_l = mi.Frame3f.cos_theta(si.wi), mi.Frame3f.cos_theta(wo)
            h = dr.normalize(si.wi + wo)
            F, _, _, _ = mi.fresnel(dr.dot(wo, h), self.eta)
            # Cycles' shadowing-masking: Smith's height-correlated G2 (Mitsuba's own G is separable).
            G = 1 / (1 + self._lambda(cos_v) + self._lambda(cos_l))
            coat = F * self.distribution.eval(h) * G / (4 * cos_v) * self._at(self.factors, cos_v)  # times cos_l
            base = self.base * ((1 - self._e(cos_v)) * dr.inv_pi * cos_l)
            valid = (cos_v > 0) & (cos_l > 0)
            return dr.select(valid, base + coat, 0.0)

        def _pdf(self, si, wo):
            cos_v, cos_l = mi.Frame3f.cos_theta(si.wi), mi.Frame3f.cos_theta(wo)
            h = dr.normalize(si.wi + wo)
            glossy = self.distribution.pdf(si.wi, h) / (4 * dr.abs(dr.dot(wo, h)))
            diffuse = mi.warp.square_to_cosine_hemisphere_pdf(wo)
            return dr.select((cos_v > 0) & (cos_l > 0), self.p_diffuse * diffuse + (1 - self.p_diffuse) * glossy, 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            m, _ = self.distribution.sample(si.wi, sample2)
            glossy_wo = mi.reflect(si.wi, m)
            diffuse_wo = mi.warp.square_to_cosine_hemisphere(sample2)
            pick_diffuse = sample1 < self.p_diffuse
            bs = mi.BSDFSample3f()
            bs.wo = dr.select(pick_diffuse, diffuse_wo, glossy_wo)
            bs.pdf = self._pdf(si, bs.wo)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(dr.select(pick_diffuse, mi.UInt32(+mi.BSDFFlags.DiffuseReflection),
                                                  mi.UInt32(+mi.BSDFFlags.GlossyReflection)))
            bs.sampled_component = dr.select(pick_diffuse, mi.UInt32(0), mi.UInt32(1))
            value = self._value(si, bs.wo)
            ok = active & (bs.pdf > 0) & (mi.Frame3f.cos_theta(bs.wo) > 0)
            return bs, dr.select(ok, value / bs.pdf, 0.0)

        def to_string(self):
            return f"CyclesPrincipled[alpha={self.alpha}, eta={self.eta}]"

    mi.register_bsdf(NAME, lambda props: CyclesPrincipled(props))
    register.done = True


def bsdf_dict(base, roughness: float, f0: float, multiscatter: bool = False) -> dict:
    """The plugin's scene dictionary for a Principled base colour, Blender roughness, the coat's
    reflectance at normal incidence (its IOR's) and its distribution (Multiscatter GGX or not)."""
    root = np.sqrt(min(max(f0, 1e-6), 0.99))
    r, g, b = (float(c) for c in base)
    return {"type": NAME, "base_r": r, "base_g": g, "base_b": b, "alpha": max(roughness, 1e-3) ** 2,
            "eta": float((1 + root) / (1 - root)), "multiscatter": bool(multiscatter)}
