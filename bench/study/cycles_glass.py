"""Cycles' rough glass (its Glass BSDF, the Principled BSDF's transmission) as a Mitsuba 3 BSDF for
the references. Mitsuba's roughdielectric differs from it in three ways: Cycles shadows with
Smith's height-correlated 1 / (1 + Lambda(wo) + Lambda(wi)); it carries the light across the
boundary without the radiance's (n_o / n_i)^2 (Mitsuba's radiance mode scales by it: the same
through a closed solid, where the factors of the way in and out cancel, but an open sheet seen
from its other side is 1 / IOR^2 as bright); and with Multiscatter GGX (the default) it divides
the lobe by E(mu_o), the single-scattering glass's directional albedo (reflected plus
transmitted) from the side of the view, so the glass keeps all of the light. E is tabulated here
by a numpy quadrature, independent of the solver's core; tests/reference/test_mitsuba_scene.py
compares this plugin with the solver's lobe."""
from __future__ import annotations

import numpy as np

import cycles_bsdf  # (beside this file)
from cycles_bsdf import fresnel, ggx_d, ggx_lambda

NAME = "cycles_glass"


def transmission_albedo(mu, alpha, eta, n=500):
    """The transmitted part of the glass's directional albedo (Cycles' BTDF times |cos| over the
    far hemisphere) for a view of cosine mu on the side of index 1, the far side's index eta."""
    wi, wo = cycles_bsdf.cosine_rule(n, lower=True), cycles_bsdf.view(mu)
    h = -(eta * wi + wo)
    length = np.linalg.norm(h, axis=1)
    h /= length[:, None]
    h *= np.where(h[:, 2] < 0, -1.0, 1.0)[:, None]
    c_o, c_i = h @ wo, np.einsum("ij,ij->i", wi, h)
    G = 1 / (1 + ggx_lambda(mu, alpha) + ggx_lambda(-wi[:, 2], alpha))
    f = (1 - fresnel(np.clip(c_o, 0, 1), eta)) * ggx_d(h[:, 2], alpha) * G * eta**2 * np.abs(c_o * c_i)
    f /= mu * -wi[:, 2] * length**2
    return float(np.pi * np.mean(np.where((c_o > 0) & (c_i < 0), f, 0.0)))


def albedo_tables(alpha, eta):
    """E from outside (the far side of index eta) and from inside (1 / eta), at the table's nodes."""
    return tuple(cycles_bsdf.table(lambda mu: cycles_bsdf.reflection_albedo(mu, alpha, rel, 500)
                                   + transmission_albedo(mu, alpha, rel)) for rel in (eta, 1 / eta))


def register(mi):
    """Registers the plugin with Mitsuba (its JIT variant: llvm_ad_rgb), once."""
    import drjit as dr

    if getattr(register, "done", False):
        return

    class CyclesGlass(cycles_bsdf.plugin_base(mi, dr)):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.alpha, self.eta = float(props["alpha"]), float(props["eta"])
            self.multiscatter = bool(props["multiscatter"])
            outside, inside = albedo_tables(self.alpha, self.eta) if self.multiscatter else (np.ones(cycles_bsdf.TABLE_NODES),) * 2
            self.outside, self.inside = mi.Float(outside), mi.Float(inside)
            self.distribution = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, self.alpha, True)
            reflection = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
            transmission = mi.BSDFFlags.GlossyTransmission | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
            self.m_components = [reflection, transmission]
            self.m_flags = reflection | transmission

        def _lambda(self, c):
            tan2 = dr.maximum(1 - c * c, 0.0) / dr.maximum(c * c, 1e-12)
            return (dr.sqrt(1 + self.alpha * self.alpha * tan2) - 1) / 2

        def _frame(self, si, wo):
            """The view turned above the surface (both directions mirrored when it is below), the
            far side's relative index and the microfacet normal of the pair (facing up)."""
            below = mi.Frame3f.cos_theta(si.wi) < 0
            flip = mi.Vector3f(1, 1, dr.select(below, -1.0, 1.0))
            v, l = si.wi * flip, wo * flip
            eta = dr.select(below, 1 / self.eta, self.eta)
            through = mi.Frame3f.cos_theta(l) < 0
            h = dr.select(through, -(eta * l + v), v + l)
            h = dr.normalize(h)
            h = dr.select(h.z < 0, -h, h)
            return below, v, l, eta, through, h

        def _value(self, si, wo):
            # si.wi: towards the viewer; wo: towards the light (Mitsuba's names). Times |cos_l|.
            below, v, l, eta, through, h = self._frame(si, wo)
            c_v, c_l = dr.dot(v, h), dr.dot(l, h)
            F, _, _, _ = mi.fresnel(c_v, eta)
            common = self.distribution.eval(h) / (1 + self._lambda(v.z) + self._lambda(l.z)) / v.z
            reflected = F * common / 4
            length2 = dr.squared_norm(eta * l + v)
            transmitted = (1 - F) * common * eta * eta * dr.abs(c_v * c_l) / length2
            value = dr.select(through, dr.select((c_v > 0) & (c_l < 0), transmitted, 0.0), reflected)
            e = dr.maximum(dr.select(below, self._at(self.inside, v.z), self._at(self.outside, v.z)), 1e-3)
            return mi.Color3f(dr.select((v.z > 0) & (c_v > 0), value / e, 0.0))

        def _pdf(self, si, wo):
            below, v, l, eta, through, h = self._frame(si, wo)
            c_v, c_l = dr.dot(v, h), dr.dot(l, h)
            F, _, _, _ = mi.fresnel(c_v, eta)
            visible = self.distribution.pdf(v, h)
            reflected = F * visible / (4 * dr.abs(c_l))
            transmitted = (1 - F) * visible * eta * eta * dr.abs(c_l) / dr.square(c_v + eta * c_l)
            ok = (v.z > 0) & (c_v > 0) & dr.select(through, c_l < 0, c_l > 0)
            return dr.select(ok, dr.select(through, transmitted, reflected), 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            below = mi.Frame3f.cos_theta(si.wi) < 0
            flip = mi.Vector3f(1, 1, dr.select(below, -1.0, 1.0))
            v = si.wi * flip
            m, _ = self.distribution.sample(v, sample2)
            F, cos_t, eta_it, eta_ti = mi.fresnel(dr.dot(v, m), dr.select(below, 1 / self.eta, self.eta))
            reflect = sample1 < F
            l = dr.select(reflect, mi.reflect(v, m), mi.refract(v, m, cos_t, eta_ti))
            bs = mi.BSDFSample3f()
            bs.wo = l * flip
            bs.pdf = self._pdf(si, bs.wo)
            bs.eta = dr.select(reflect, 1.0, eta_it)
            bs.sampled_type = mi.UInt32(dr.select(reflect, mi.UInt32(+mi.BSDFFlags.GlossyReflection),
                                                  mi.UInt32(+mi.BSDFFlags.GlossyTransmission)))
            bs.sampled_component = dr.select(reflect, mi.UInt32(0), mi.UInt32(1))
            ok = active & (bs.pdf > 0)
            return bs, dr.select(ok, self._value(si, bs.wo) / bs.pdf, 0.0)

        def to_string(self):
            return f"CyclesGlass[alpha={self.alpha}, eta={self.eta}, multiscatter={self.multiscatter}]"

    mi.register_bsdf(NAME, lambda props: CyclesGlass(props))
    register.done = True


def bsdf_dict(ior: float, alpha: float, multiscatter: bool) -> dict:
    """The plugin's scene dictionary: the glass's index (inside, the normal pointing out), its
    GGX alpha and its distribution (Multiscatter GGX or not)."""
    return {"type": NAME, "eta": float(ior), "alpha": float(alpha), "multiscatter": bool(multiscatter)}
