"""Cycles' GGX reflection as a Mitsuba 3 BSDF for the references: a metal (the Principled BSDF's,
Schlick's Fresnel from its base colour, its F82 tint model with the default white tint) or the
Glossy BSDF (its colour, no Fresnel), anisotropic (alpha_u along the shading frame's s), with
Smith's height-correlated shadowing 1 / (1 + Lambda(wo) + Lambda(wi)) as Cycles evaluates it
(Mitsuba's roughconductor and principled shadow with the separable product, up to 14% darker at
grazing angles and roughness 1), and with Cycles' Multiscatter GGX (the default distribution) the
light lost between microfacets put back along the view as Cycles puts it back (Kulla and Conty
2017): f_ms = f (1 + F_ms (1 - E(mu_o)) / E(mu_o)), F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)), E the
white lobe's directional albedo (isotropic, alpha sqrt(alpha_u alpha_v), as Cycles reads its
table), E_avg its cosine-weighted mean and F_ss the Fresnel's. E is tabulated here by a numpy
quadrature, independent of the solver's core; the test of this plugin
(tests/reference/test_mitsuba_scene.py) compares it with the solver's lobe."""
from __future__ import annotations

import numpy as np

import cycles_bsdf  # (beside this file)
from cycles_bsdf import multiple_scattering_colour

NAME = "cycles_glossy"


def albedo_table(alpha):
    """E of the white single-scattering lobe at the table's nodes; the narrow lobes need a finer
    rule near the normal."""
    n = 1200 if alpha < 0.1 else 400
    return cycles_bsdf.table(lambda mu: cycles_bsdf.reflection_albedo(mu, alpha, None, n))


def register(mi):
    """Registers the plugin with Mitsuba (its JIT variant: llvm_ad_rgb), once."""
    import drjit as dr

    if getattr(register, "done", False):
        return

    class CyclesGlossy(cycles_bsdf.plugin_base(mi, dr)):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.f0 = mi.Color3f(props["f0_r"], props["f0_g"], props["f0_b"])
            self.schlick = bool(props["schlick"])
            self.alpha_u, self.alpha_v = float(props["alpha_u"]), float(props["alpha_v"])
            self.distribution = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, self.alpha_u, self.alpha_v, True)
            self.multiscatter = bool(props["multiscatter"])
            if self.multiscatter:
                f0 = np.array([props["f0_r"], props["f0_g"], props["f0_b"]], float)
                f_ss = f0 + (1 - f0) / 21 if self.schlick else f0  # 2 int (1 - mu)^5 mu dmu = 1 / 21
                table = albedo_table(float(np.sqrt(self.alpha_u * self.alpha_v)))
                self.table = mi.Float(table)
                self.fms = mi.Color3f(*(float(c) for c in multiple_scattering_colour(table, f_ss)))
            glossy = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
            self.m_components = [glossy]
            self.m_flags = glossy

        def _lambda(self, w):
            tan2 = (dr.square(self.alpha_u * w.x) + dr.square(self.alpha_v * w.y)) / dr.maximum(dr.square(w.z), 1e-12)
            return (dr.sqrt(1 + tan2) - 1) / 2

        def _factor(self, si):
            if not self.multiscatter:
                return 1.0
            e = dr.maximum(self._at(self.table, mi.Frame3f.cos_theta(si.wi)), 1e-3)
            return 1 + self.fms * ((1 - e) / e)

        def _value(self, si, wo):
            # si.wi: towards the viewer (the light leaving); wo: towards the light (Mitsuba's names).
            cos_v, cos_l = mi.Frame3f.cos_theta(si.wi), mi.Frame3f.cos_theta(wo)
            h = dr.normalize(si.wi + wo)
            c = dr.clip(dr.dot(wo, h), 0.0, 1.0)
            F = self.f0 + (1 - self.f0) * dr.power(1 - c, 5) if self.schlick else self.f0
            G = 1 / (1 + self._lambda(si.wi) + self._lambda(wo))
            value = F * self.distribution.eval(h) * G / (4 * cos_v) * self._factor(si)  # times cos_l
            return dr.select((cos_v > 0) & (cos_l > 0), value, 0.0)

        def _pdf(self, si, wo):
            h = dr.normalize(si.wi + wo)
            ok = (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            return dr.select(ok, self.distribution.pdf(si.wi, h) / (4 * dr.abs(dr.dot(wo, h))), 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            m, _ = self.distribution.sample(si.wi, sample2)
            bs = mi.BSDFSample3f()
            bs.wo = mi.reflect(si.wi, m)
            bs.pdf = self._pdf(si, bs.wo)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            ok = active & (bs.pdf > 0) & (mi.Frame3f.cos_theta(bs.wo) > 0)
            return bs, dr.select(ok, self._value(si, bs.wo) / bs.pdf, 0.0)

        def to_string(self):
            return f"CyclesGlossy[alpha=({self.alpha_u}, {self.alpha_v}), multiscatter={self.multiscatter}]"

    mi.register_bsdf(NAME, lambda props: CyclesGlossy(props))
    register.done = True


def bsdf_dict(f0, schlick: bool, alpha_u: float, alpha_v: float, multiscatter: bool) -> dict:
    """The plugin's scene dictionary: the lobe's colour (f0 of Schlick's curve, or the Glossy
    BSDF's colour), its alphas (u along the shading frame's s) and its multiple scattering."""
    r, g, b = (float(c) for c in f0)
    return {"type": NAME, "f0_r": r, "f0_g": g, "f0_b": b, "schlick": bool(schlick), "alpha_u": float(alpha_u),
            "alpha_v": float(alpha_v), "multiscatter": bool(multiscatter)}
