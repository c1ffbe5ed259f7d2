"""Cycles' Multiscatter GGX (the default distribution of its Principled, Glossy and Anisotropic
BSDFs) as a Mitsuba 3 BSDF for the references: a single-scattering GGX lobe (Mitsuba's own,
nested) whose light lost between microfacets is put back along the view as Cycles puts it back
(Kulla and Conty 2017), f_ms = f (1 + F_ms (1 - E(mu_o)) / E(mu_o)),
F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)), E the white lobe's directional albedo (isotropic, alpha
sqrt(alpha_u alpha_v), as Cycles reads its table), E_avg its cosine-weighted mean and F_ss the
Fresnel's. E is tabulated here by a numpy quadrature of the white lobe with Smith's separable
shadowing (Mitsuba's, and the solver's), independent of the solver's core; the test of this
plugin (tests/reference/test_mitsuba_scene.py) compares its albedo with the Kulla-Conty closed form."""
from __future__ import annotations

import numpy as np

NAME = "cycles_multiscatter"
TABLE_NODES = 65  # E at mu = (k / (n - 1))^2


def white_albedo(mu, alpha, n=400):
    """Directional albedo of the white single-scattering GGX lobe (F = 1, separable G) for light
    leaving at cos theta = mu, by a midpoint rule in cos^2 theta and phi (cosine-weighted)."""
    g = (np.arange(n) + 0.5) / n
    c2, phi = np.meshgrid(g, 2 * np.pi * (np.arange(2 * n) + 0.5) / (2 * n), indexing="ij")
    ci, si = np.sqrt(c2).ravel(), np.sqrt(1 - c2).ravel()
    wi = np.stack([si * np.cos(phi.ravel()), si * np.sin(phi.ravel()), ci], 1)
    wo = np.array([np.sqrt(max(1 - mu * mu, 0.0)), 0.0, mu])
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    a2 = alpha * alpha
    D = a2 / (np.pi * (h[:, 2] ** 2 * (a2 - 1) + 1) ** 2)

    def g1(c):
        t2 = (1 - c * c) / np.maximum(c * c, 1e-300)
        return 2 / (1 + np.sqrt(1 + a2 * t2))

    f = D * g1(wi[:, 2]) * g1(mu) / (4 * mu * wi[:, 2])
    return float(np.pi * np.mean(f))


def albedo_table(alpha):
    """E at the table's nodes; the narrow lobes need a finer rule near the normal."""
    n = 1200 if alpha < 0.1 else 400
    return np.array([white_albedo(max(t * t, 1e-4), alpha, n) for t in np.linspace(0.0, 1.0, TABLE_NODES)])


def table_at(table, mu):
    x = np.sqrt(np.clip(mu, 0.0, 1.0)) * (TABLE_NODES - 1)
    k = np.minimum(x.astype(int), TABLE_NODES - 2)
    return table[k] + (x - k) * (table[k + 1] - table[k])


def multiple_scattering_colour(table, f_ss):
    """F_ms of the Fresnel's cosine-weighted mean f_ss (RGB)."""
    mu = (np.arange(2048) + 0.5) / 2048
    e_avg = 2 * np.mean(table_at(table, mu) * mu)
    f_ss = np.asarray(f_ss, float)
    return f_ss * e_avg / (1 - f_ss * (1 - e_avg))


def register(mi):
    """Registers the plugin with Mitsuba (its JIT variant: llvm_ad_rgb), once."""
    import drjit as dr

    if getattr(register, "done", False):
        return

    class CyclesMultiscatter(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.lobe = props["lobe"]
            table = albedo_table(float(props["alpha"]))
            self.table = mi.Float(table)
            self.fms = mi.Color3f(*(float(c) for c in multiple_scattering_colour(
                table, [props["fss_r"], props["fss_g"], props["fss_b"]])))
            self.m_components = [self.lobe.flags()]
            self.m_flags = self.lobe.flags()

        def _factor(self, si):
            mu = mi.Frame3f.cos_theta(si.wi)
            x = dr.sqrt(dr.clip(mu, 0.0, 1.0)) * (TABLE_NODES - 1)
            k = dr.minimum(mi.UInt32(x), TABLE_NODES - 2)
            e = dr.lerp(dr.gather(mi.Float, self.table, k), dr.gather(mi.Float, self.table, k + 1), x - mi.Float(k))
            e = dr.maximum(e, 1e-3)
            return 1 + self.fms * ((1 - e) / e)

        def sample(self, ctx, si, sample1, sample2, active=True):
            bs, weight = self.lobe.sample(ctx, si, sample1, sample2, active)
            return bs, weight * self._factor(si)

        def eval(self, ctx, si, wo, active=True):
            return self.lobe.eval(ctx, si, wo, active) * self._factor(si)

        def pdf(self, ctx, si, wo, active=True):
            return self.lobe.pdf(ctx, si, wo, active)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            return f"CyclesMultiscatter[{self.lobe}]"

    mi.register_bsdf(NAME, lambda props: CyclesMultiscatter(props))
    register.done = True


def bsdf_dict(lobe: dict, alpha_u: float, alpha_v: float, f_ss) -> dict:
    """The plugin's scene dictionary around a single-scattering GGX lobe's, its alphas and its
    Fresnel's cosine-weighted mean (RGB)."""
    r, g, b = (float(c) for c in f_ss)
    return {"type": NAME, "lobe": lobe, "alpha": float(np.sqrt(alpha_u * alpha_v)), "fss_r": r, "fss_g": g, "fss_b": b}
