"""What the references' Cycles BSDFs (cycles_glossy.py, cycles_principled.py, cycles_glass.py)
share: GGX with Smith's height-correlated shadowing as Cycles evaluates it, their directional
albedo tables by numpy quadratures (independent of the solver's core), and the Mitsuba 3 plugin
boilerplate. Each plugin gives its _value (the BSDF times the light's |cos|) and _pdf."""
from __future__ import annotations

import numpy as np

TABLE_NODES = 65  # E at mu = (k / (n - 1))^2: dense towards grazing, where the Fresnel rises


def fresnel(cos_i, eta):
    """Unpolarised reflectance of a smooth dielectric boundary for light arriving at cos_i from
    the side of index 1, the other of index eta (1 under total internal reflection, eta < 1)."""
    sin_t2 = (1 - cos_i**2) / eta**2
    cos_t = np.sqrt(np.maximum(1 - sin_t2, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return np.where(sin_t2 >= 1, 1.0, 0.5 * (rs**2 + rp**2))


def ggx_d(h_z, alpha):
    a2 = alpha * alpha
    return a2 / (np.pi * (h_z**2 * (a2 - 1) + 1) ** 2)


def ggx_lambda(c, alpha):
    t2 = (1 - c * c) / np.maximum(c * c, 1e-300)
    return (np.sqrt(1 + alpha * alpha * t2) - 1) / 2


def cosine_rule(n, lower=False):
    """A midpoint rule in cos^2 theta and phi over the upper (or lower) hemisphere: directions
    whose mean of f times pi is the integral of f |cos theta|."""
    g = (np.arange(n) + 0.5) / n
    c2, phi = np.meshgrid(g, 2 * np.pi * (np.arange(2 * n) + 0.5) / (2 * n), indexing="ij")
    ci, si = np.sqrt(c2).ravel(), np.sqrt(1 - c2).ravel()
    return np.stack([si * np.cos(phi.ravel()), si * np.sin(phi.ravel()), -ci if lower else ci], 1)


def view(mu):
    return np.array([np.sqrt(max(1 - mu * mu, 0.0)), 0.0, mu])


def reflection_albedo(mu, alpha, eta=None, n=400):
    """Directional albedo of the single-scattering GGX reflection (Fresnel 1, or the dielectric's
    of relative index eta) for light leaving at cos theta = mu."""
    wi, wo = cosine_rule(n), view(mu)
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    F = 1.0 if eta is None else fresnel(np.clip(np.einsum("ij,ij->i", wi, h), 0, 1), eta)
    G = 1 / (1 + ggx_lambda(wi[:, 2], alpha) + ggx_lambda(mu, alpha))
    return float(np.pi * np.mean(F * ggx_d(h[:, 2], alpha) * G / (4 * mu * wi[:, 2])))


def table_at(table, mu):
    x = np.sqrt(np.clip(mu, 0.0, 1.0)) * (TABLE_NODES - 1)
    k = np.minimum(np.asarray(x).astype(int), TABLE_NODES - 2)
    return table[k] + (x - k) * (table[k + 1] - table[k])


def table(albedo):
    """albedo(mu) at the table's nodes."""
    return np.array([albedo(max(t * t, 1e-4)) for t in np.linspace(0.0, 1.0, TABLE_NODES)])


def multiple_scattering_colour(white, f_ss):
    """Kulla and Conty's F_ms of a Fresnel's cosine-weighted mean f_ss (RGB), from the white
    lobe's table: F_ss E_avg / (1 - F_ss (1 - E_avg))."""
    mu = (np.arange(2048) + 0.5) / 2048
    e_avg = 2 * np.mean(table_at(white, mu) * mu)
    f_ss = np.asarray(f_ss, float)
    return f_ss * e_avg / (1 - f_ss * (1 - e_avg))


def plugin_base(mi, dr):
    """The Mitsuba BSDF base of the plugins: eval and pdf from the subclass's _value and _pdf,
    and its tables read as the core reads them (linear in sqrt(mu))."""

    class CyclesBsdf(mi.BSDF):
        def _at(self, table, mu):
            x = dr.sqrt(dr.clip(mu, 0.0, 1.0)) * (TABLE_NODES - 1)
            k = dr.minimum(mi.UInt32(x), TABLE_NODES - 2)
            return dr.lerp(dr.gather(mi.Float, table, k), dr.gather(mi.Float, table, k + 1), x - mi.Float(k))

        def eval(self, ctx, si, wo, active=True):
            return dr.select(active, self._value(si, wo), 0.0)

        def pdf(self, ctx, si, wo, active=True):
            return dr.select(active, self._pdf(si, wo), 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys):
            pass

    return CyclesBsdf
