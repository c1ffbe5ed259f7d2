"""The study's Mitsuba 3 scenes (bench/study/mitsuba_scene.py) shade Blender's triangles as Cycles
does: a smooth surface (the example's NURBS spheres) with its corner normals interpolated, a flat
face with its own normal. Until 6 December every triangle was shaded flat; the spheres' facets
(their normals up to 0.9 degrees off the sphere's) moved their highlights' flanks by 4-5% either way, and the glossy
spheres' final preset measured 2.30% against that reference, 0.85% against this one."""
from __future__ import annotations

import pathlib
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench" / "study"))
sys.path.insert(0, str(ROOT / "example_blends"))


def _angles_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1, 1)))


@pytest.mark.blender
def test_smooth_spheres_take_interpolated_normals_and_flat_faces_their_own():
    pytest.importorskip("mitsuba")
    import mitsuba_scene
    import references
    from make_glossy_spheres import RADIUS
    from mitsuba_scene import load_mitsuba

    description = references.describe(ROOT / "example_blends" / "glossy_spheres.blend")
    scene = mitsuba_scene.load_scene(description)
    mi = load_mitsuba()
    rng = np.random.default_rng(3)

    def hit(origin, direction):
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(origin.T.astype(np.float32)),
                                          mi.Vector3f(direction.T.astype(np.float32))))
        return np.array(si.p).T, np.array(si.n).T, np.array(si.sh_frame.n).T

    # Rays at the isotropic sphere's centre from all around its upper two thirds (the table hides the rest).
    centre = np.array([-0.5, 0.1, RADIUS])
    out = rng.normal(size=(2000, 3))
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    out = out[out[:, 2] > -0.3]
    p, geometric, shading = hit(centre + 1.2 * RADIUS * out, -out)
    on = np.abs(np.linalg.norm(p - centre, axis=1) - RADIUS) < 1e-3  # not the table's
    assert on.mean() > 0.95, on.mean()
    p, geometric, shading = p[on], geometric[on], shading[on]
    exact = (p - centre) / np.linalg.norm(p - centre, axis=1, keepdims=True)
    facets, smooth = _angles_deg(geometric, exact), _angles_deg(shading, exact)
    print(f"\nsphere normals off the exact one: facets up to {facets.max():.3f} deg, shading up to {smooth.max():.4f} deg")
    assert facets.max() > 0.5  # the facets are there (measured 0.90 deg)
    assert smooth.max() < 0.05, smooth.max()  # interpolated: measured 0.027 deg

    # The table (a flat quad): the shading normal is the face's.
    origin = np.column_stack([rng.uniform(-1.9, 1.9, 200), rng.uniform(-0.9, -0.5, 200), np.full(200, 1.0)])
    _, geometric, shading = hit(origin, np.tile([0.0, 0.0, -1.0], (200, 1)))
    np.testing.assert_allclose(shading, geometric, atol=1e-6)
    np.testing.assert_allclose(geometric, np.tile([0.0, 0.0, 1.0], (200, 1)), atol=1e-6)


_COAT_FLOOR = """
import sys, bpy
sys.path.insert(0, {addon!r}); sys.path.insert(0, {parts!r})
import cli
cli.load_addon().register()
from scene_parts import principled_material
bpy.ops.wm.read_factory_settings(use_empty=True)
mesh = bpy.data.meshes.new("Floor")
mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
mesh.materials.append(principled_material("Default", (0.8, 0.8, 0.8)))  # roughness 0.5, IOR 1.5
floor = bpy.data.objects.new("Floor", mesh)
bpy.context.scene.collection.objects.link(floor)
lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "AREA"))
lamp.data.size, lamp.data.energy, lamp.location = 0.5, 50.0, (0, 0, 1)
bpy.context.scene.collection.objects.link(lamp)
bpy.context.scene.bsgi.coats = sys.argv[2]
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[1])
"""


@pytest.mark.slow
@pytest.mark.blender
def test_default_principled_floor_against_mitsuba_with_cycles_layering(tmp_path):
    # Blender's default material on a floor under an area light (its highlight in view of many of
    # the pairs), the reference by Mitsuba with the study's plugin of Cycles' layered coat
    # (cycles_principled.py), the solve at preview by the add-on as a user's: measured relative
    # RMSE 0.63% (the quick reference's noise 0.68%); with the coat folded into the albedo (Glossy
    # Coats: Folded, as every Principled dielectric was solved before) 7.3%.
    pytest.importorskip("mitsuba")
    import json
    import subprocess

    import references

    blends = {}
    for coats in ("QUALITY", "FOLDED"):
        blends[coats] = tmp_path / f"coat_floor_{coats.lower()}.blend"
        script = _COAT_FLOOR.format(addon=str(ROOT / "addon"), parts=str(ROOT / "example_blends"))
        subprocess.run([sys.executable, "-c", script, str(blends[coats]), coats], check=True, capture_output=True)
    data = references.reference(blends["QUALITY"], quick=True, cache=tmp_path / "references")
    np.savez(tmp_path / "pairs.npz", **data)
    (tmp_path / "settings.json").write_text(json.dumps({"preset": "preview"}))
    errors = {}
    for coats, blend in blends.items():
        out = tmp_path / f"{coats}.npz"
        subprocess.run([sys.executable, str(ROOT / "bench" / "study" / "solve_blend.py"), str(blend),
                        str(tmp_path / "settings.json"), str(tmp_path / "pairs.npz"), str(out)], check=True,
                       capture_output=True)
        got, ref = np.load(out)["radiance"], data["reference"]
        ok = np.isfinite(got).all(axis=1)
        errors[coats] = float(np.sqrt(np.mean(((got[ok] - ref[ok]) ** 2).sum(1)) / np.mean((ref[ok] ** 2).sum(1))))
    noise = float(np.sqrt(np.mean((data["stderr"] ** 2).sum(1)) / np.mean((data["reference"] ** 2).sum(1))))
    print(f"\ndefault Principled floor against Mitsuba (Cycles' layering): {errors}, reference noise {noise:.4f}")
    assert errors["QUALITY"] < max(2 * 0.0063, 2 * noise)
    assert errors["FOLDED"] > 4 * errors["QUALITY"]


def _plugin_albedo(mi, plugin, mu, n=300):
    """The directional albedo of a Mitsuba BSDF (per channel) for light leaving at cos theta = mu:
    a cosine-weighted midpoint rule over its eval (which carries the cosine)."""
    import drjit as dr

    g = (np.arange(n) + 0.5) / n
    c2, phi = np.meshgrid(g, 2 * np.pi * (np.arange(2 * n) + 0.5) / (2 * n), indexing="ij")
    ci, si_ = np.sqrt(c2).ravel(), np.sqrt(1 - c2).ravel()
    wi = np.stack([si_ * np.cos(phi.ravel()), si_ * np.sin(phi.ravel()), ci], 1)
    si = dr.zeros(mi.SurfaceInteraction3f, len(wi))
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.wi = mi.Vector3f(float(np.sqrt(1 - mu * mu)), 0.0, float(mu))
    value = plugin.eval(mi.BSDFContext(), si, mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2]))
    return np.pi * np.array([np.mean(np.array(value[c]) / wi[:, 2]) for c in range(3)])


def test_glossy_plugin_is_the_solvers_lobe_as_the_add_on_makes_it():
    # The references' Cycles GGX (cycles_glossy.py: Mitsuba's distribution, height-correlated
    # shadowing, its E by a numpy quadrature) against the solver's lobe as the add-on makes it
    # (bsgi.GgxReflection height_correlated, multiscatter: its E tabulated from its own
    # sampling), two implementations of one model: single scattering equal at random directions
    # (to float precision), a white lobe with multiple scattering reflecting all of its light, a
    # copper metal and an anisotropic Glossy BSDF reflecting the same light in both. Measured:
    # pointwise 5e-7 of the peak, white 1 +- 6e-5, copper 6e-5 and glossy 1.1e-4 off the solver's.
    pytest.importorskip("mitsuba")
    import drjit as dr

    import cycles_glossy
    from mitsuba_scene import load_mitsuba

    import bsgi

    mi = load_mitsuba()
    cycles_glossy.register(mi)
    sys.path.insert(0, str(ROOT / "tests" / "core"))
    from closed_forms import directional_albedo

    copper = np.array([0.95, 0.64, 0.54])
    cases = {"white": ([1, 1, 1], False, 0.36, 0.36), "copper": (copper, True, 0.36, 0.36),
             "anisotropic glossy": ([0.8, 0.7, 0.3], False, 0.6, 0.2)}
    rng = np.random.default_rng(8)
    wo, wi = (d / np.linalg.norm(d, axis=1, keepdims=True) for d in (np.abs(rng.normal(size=(300, 3))) * [1, 1, 0.6] + [0, 0, 0.1],
                                                                      rng.normal(size=(300, 3)) * [1, 1, 0.6] + [0, 0, 0.8]))
    keep = wi[:, 2] > 0.02
    wo, wi = wo[keep], wi[keep]
    worst_point, worst = 0.0, {}
    for name, (f0, schlick, au, av) in cases.items():
        single = mi.load_dict(cycles_glossy.bsdf_dict(f0, schlick, au, av, False))
        plugin = mi.load_dict(cycles_glossy.bsdf_dict(f0, schlick, au, av, True))
        core = bsgi.GgxReflection(au, av, f0, schlick=schlick, multiscatter=True, height_correlated=True)
        core_single = bsgi.GgxReflection(au, av, f0, schlick=schlick, height_correlated=True)
        si = dr.zeros(mi.SurfaceInteraction3f, len(wo))
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        si.wi = mi.Vector3f(wo[:, 0], wo[:, 1], wo[:, 2])
        value = single.eval(mi.BSDFContext(), si, mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2]))
        got = np.stack([np.array(value[c]) for c in range(3)], 1) / wi[:, 2:3]
        want = core_single.eval(wo, wi)
        worst_point = max(worst_point, float(np.abs(got - want).max() / want.max()))
        # The white lobe against 1 (its closed form), the others against the solver's albedo.
        reference = (lambda mu: 1.0) if name == "white" else (lambda mu: directional_albedo(core, mu, 300))
        worst[name] = max(float(np.abs(_plugin_albedo(mi, plugin, mu) / reference(mu) - 1).max()) for mu in (1.0, 0.5, 0.2))
    print(f"\ncycles_glossy plugin: single scattering within {worst_point:.1e} (of the peak) of the solver's; with "
          f"multiple scattering {', '.join(f'{k} {v:.1e}' for k, v in worst.items())}")
    assert worst_point < 1e-6
    assert worst["white"] < 1.3e-4 and worst["copper"] < 1.3e-4 and worst["anisotropic glossy"] < 2.2e-4


def test_glass_plugin_is_the_solvers_glass_as_the_add_on_makes_it():
    # The references' Cycles glass (cycles_glass.py: Mitsuba's distribution, Cycles' formula, its
    # E tables by a numpy quadrature) against the solver's (bsgi.RoughDielectric
    # height_correlated, scale_radiance off, multiscatter: its E from its own sampling): single
    # scattering equal at random pairs on both sides, reflected and transmitted (to float
    # precision), and the two E tables the same within their quadratures.
    pytest.importorskip("mitsuba")
    import drjit as dr

    import cycles_glass
    from mitsuba_scene import load_mitsuba

    import bsgi

    mi = load_mitsuba()
    cycles_glass.register(mi)
    eta, alpha = 1.5, 0.3
    rng = np.random.default_rng(9)
    worst_point, worst_multi = 0.0, 0.0
    for multiscatter in (False, True):
        plugin = mi.load_dict(cycles_glass.bsdf_dict(eta, alpha, multiscatter))
        core = bsgi.RoughDielectric(eta, alpha, alpha, multiscatter=multiscatter, height_correlated=True,
                                    scale_radiance=False)
        for view_below in (False, True):
            for light_below in (False, True):
                v, l = (d / np.linalg.norm(d, axis=1, keepdims=True) for d in (rng.normal(size=(400, 3)), rng.normal(size=(400, 3))))
                v[:, 2] = np.abs(v[:, 2]) * (-1 if view_below else 1)
                l[:, 2] = np.abs(l[:, 2]) * (-1 if light_below else 1)
                keep = (np.abs(v[:, 2]) > 0.05) & (np.abs(l[:, 2]) > 0.05)
                v, l = v[keep], l[keep]
                si = dr.zeros(mi.SurfaceInteraction3f, len(v))
                si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
                si.wi = mi.Vector3f(v[:, 0], v[:, 1], v[:, 2])
                value = plugin.eval(mi.BSDFContext(), si, mi.Vector3f(l[:, 0], l[:, 1], l[:, 2]))
                got = np.array(value[0]) / np.abs(l[:, 2])
                want = core.eval(v, l)[:, 0]
                assert want.max() > 0
                error = float(np.abs(got - want).max() / want.max())
                if multiscatter:
                    worst_multi = max(worst_multi, error)
                else:
                    worst_point = max(worst_point, error)
    outside, inside = cycles_glass.albedo_tables(alpha, eta)
    mus = np.linspace(0.0, 1.0, len(outside)) ** 2
    core_e = [np.array([bsgi.RoughDielectric.single_scattering_albedo(eta, alpha, side, True, max(m, 1e-4)) for m in mus])
              for side in (False, True)]
    # (Near the horizon the numpy rule misses some of the reflection: 1.3e-2 within 1.7 degrees,
    # 5.4e-3 at 87 degrees, where the core's agrees with 4M random samples to 1e-4.)
    steep = mus >= 0.1
    worst_e = max(float(np.abs(outside - core_e[0])[steep].max()), float(np.abs(inside - core_e[1])[steep].max()))
    print(f"\ncycles_glass plugin: single scattering within {worst_point:.1e} (of the peak) of the solver's, "
          f"with multiple scattering {worst_multi:.1e}; E tables within {worst_e:.1e} (mu >= 0.1)")
    assert worst_point < 3e-6
    assert worst_e < 5e-3
    assert worst_multi < 3e-3
