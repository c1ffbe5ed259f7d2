"""Textured glossy colour in the core (Scene.set_specular_texture): a GGX metal's f0 over its
(u, v), solved as the radiance at f0 = 1 and at f0 = 0 (Schlick's Fresnel is affine in f0) that
the texture blends, against Mitsuba 3 and against the same surface with a constant colour."""
import numpy as np
import pytest

import bsgi
from test_solver_textures import FLOOR, LAMP, settings, texel_centres, up

LIGHT, DARK = (0.9, 0.9, 0.9), (0.8, 0.1, 0.1)
ALPHA = 0.3


def stripes(n=4, texels=8):
    """(1, n * texels, 3): n light and dark stripes across u (constant along v), each `texels`
    wide (the core's texture is bilinear between texel centres, so a stripe holds its colour to
    within half a texel of its edges)."""
    return np.array([[LIGHT if k // texels % 2 == 0 else DARK for k in range(n * texels)]], np.float32)


def metal_under_lamp(texture=None, f0=(0.5, 0.5, 0.5), bsdf=None, bounces=0, coeffs=8, sharpen=True, **options):
    scene = bsgi.Scene()
    bsdf = bsdf or bsgi.GgxReflection(ALPHA, ALPHA, list(f0))
    scene.add_bilinear_patch("metal", FLOOR, albedo=[0] * 3, emission=[0] * 3, bsdf=bsdf, **options)
    scene.add_bilinear_patch("lamp", LAMP, albedo=[0] * 3, emission=[3.0] * 3, receiver=False, occluder=False)
    if texture is not None:
        scene.set_specular_texture(0, texture)
    s = settings(bounces=bounces, coeffs=coeffs)
    s.sharpen_fit = sharpen
    return bsgi.solve(scene, s).surfaces[0]


def views(uv, rng):
    """Outgoing directions within 30 degrees of the normal (where Schlick's Fresnel is its f0 to
    within 1e-4: the texture's colour is then exact), one per point."""
    theta, phi = np.radians(rng.uniform(0, 30, len(uv))), rng.uniform(0, 2 * np.pi, len(uv))
    return np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


@pytest.fixture(scope="module")
def mitsuba_stripes():
    return mitsuba_stripes_reference()


def mitsuba_stripes_reference():
    """Mitsuba 3's direct light off the striped metal (GGX, Fresnel 1, the stripes as its specular
    reflectance: the BRDF linear in the colour) at stripe centres, seen from near the normal."""
    mitsuba_reference = pytest.importorskip("reference.mitsuba_reference")
    mi = mitsuba_reference.load_mitsuba()
    import pathlib
    import tempfile
    with tempfile.TemporaryDirectory(prefix="bsgi-specular-") as name:  # read while Mitsuba loads
        folder = pathlib.Path(name)
        floor = folder / "floor.obj"
        floor.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in FLOOR) + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                         "f 1/1 2/2 3/3 4/4\n")
        lamp = folder / "lamp.obj"
        lamp.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in LAMP) + "f 1 2 3 4\n")
        texture = {"type": "bitmap", "data": mi.TensorXf(stripes()), "raw": True, "filter_type": "nearest"}
        scene = mi.load_dict({
            "type": "scene", "integrator": {"type": "path", "max_depth": 2},
            "floor": {"type": "obj", "filename": str(floor), "face_normals": True,
                      "bsdf": {"type": "roughconductor", "distribution": "ggx", "alpha": ALPHA, "material": "none",
                               "specular_reflectance": texture}},
            "lamp": {"type": "obj", "filename": str(lamp), "face_normals": True,
                     "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [3.0] * 3}}},
        }, optimize=False)
    rng = np.random.default_rng(4)
    u = (np.repeat(np.arange(4), 6) + 0.5) / 4 + rng.uniform(-0.08, 0.08, 24)
    uv = np.column_stack([u, rng.uniform(0.2, 0.8, 24)])
    d = views(uv, rng)
    point = np.column_stack([uv, np.zeros(len(uv))])
    ref, stderr = mitsuba_reference.radiance_along(scene, point + 0.3 * d, point, spp=4096, seed=3)
    return uv, d, ref, stderr


@pytest.mark.slow
def test_striped_metal_reflects_the_lamp_in_its_stripes_colours(mitsuba_stripes):
    uv, d, ref, stderr = mitsuba_stripes
    metal = metal_under_lamp(stripes(), coeffs=16)
    got = metal.evaluate(uv, d)
    lit = ref.max(axis=1) > 0.05 * ref.max()
    err = np.median(np.abs(got[lit] / ref[lit] - 1))
    noise = np.median(stderr[lit] / ref[lit])
    # Each stripe's colour: red over green of the dark stripes, against the light ones' (9 here).
    dark = (np.floor(uv[:, 0] * 4) % 2 == 1) & lit
    light = (np.floor(uv[:, 0] * 4) % 2 == 0) & lit
    def redness(x, m):
        return float(np.mean(x[m, 0] / x[m, 1]))
    contrast, contrast_ref = redness(got, dark) / redness(got, light), redness(ref, dark) / redness(ref, light)
    print(f"striped metal vs Mitsuba: median relative difference {err:.4f} (Mitsuba's noise {noise:.4f}) over "
          f"{lit.sum()} lit pairs; dark/light redness {contrast:.3f}, Mitsuba {contrast_ref:.3f}")
    # The spline's own error on this lobe (alpha 0.3, 16 x 16 spatial coefficients) dominates.
    assert err <= 0.05  # measured 0.025 (Mitsuba's noise 0.009)
    assert abs(contrast / contrast_ref - 1) <= 0.01  # measured below 1e-4: the texture is the detail


def random_views(n, seed):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2])  # any direction above the surface, grazing ones too
    return rng.uniform(0, 1, (n, 2)), d


def test_each_stripe_shows_its_own_fresnel_at_every_angle():
    # Schlick's F = f0 + (1 - f0)(1 - cos)^5 is affine in f0: inside each stripe the textured
    # metal is exactly the metal of that stripe's colour, at grazing views too (where F rises
    # towards white whatever f0 is). The f0 given with the BSDF is replaced. Exact with the linear
    # fit: the sharpened one limits each spline by its own samples, and the blend of the two
    # then holds to 1e-4 (the model is what this checks).
    textured = metal_under_lamp(stripes(), f0=(0.1, 0.9, 0.5), bounces=2, sharpen=False)
    assert textured.kind == "glossy" and textured.specular is not None and textured.tint_zero is not None
    uv, d = random_views(400, 1)
    s = uv[:, 0] * 4
    inside = np.abs(s - np.round(s)) > 0.1  # more than half a texel from a stripe's edge
    for colour, mine in ((LIGHT, np.floor(s) % 2 == 0), (DARK, np.floor(s) % 2 == 1)):
        plain = metal_under_lamp(f0=colour, bounces=2, sharpen=False)
        m = inside & mine
        np.testing.assert_allclose(textured.evaluate(uv[m], d[m]), plain.evaluate(uv[m], d[m]), rtol=1e-6, atol=1e-12)
    # A one-texel texture is the constant colour everywhere.
    colour = [0.7, 0.4, 0.2]
    textured = metal_under_lamp(np.array([[colour]], np.float32), sharpen=False)
    plain = metal_under_lamp(f0=colour, sharpen=False)
    np.testing.assert_allclose(textured.evaluate(uv, d), plain.evaluate(uv, d), rtol=1e-6, atol=1e-12)


def test_the_texture_blends_the_radiance_at_f0_one_and_zero():
    # The stored texture is the user's; what the surface shows is T x upper + (1 - T) x tint_zero.
    image = stripes()
    metal = metal_under_lamp(image)
    np.testing.assert_array_equal(metal.specular, image)
    uv = texel_centres(32)
    d = up(len(uv))
    x = np.column_stack([uv, np.zeros((len(uv), 2))])  # the disc's centre: along the normal
    texel = image[0, np.minimum((uv[:, 0] * image.shape[1]).astype(int), image.shape[1] - 1)]
    want = metal.upper.evaluate(x) * texel + metal.tint_zero.evaluate(x) * (1 - texel)
    np.testing.assert_allclose(metal.evaluate(uv, d), want, rtol=1e-12)


def test_half_red_metal_reddens_the_wall_near_it():
    # The gather sees the texel where its ray hits the metal: light bounced off the red half of
    # a metal floor reddens the wall beside it, the white half does not.
    wall = np.array([[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]], float)  # at y = 1, u along x, normal -y
    lamp = np.array([[0.3, 0.2, 0.9], [0.3, 0.6, 0.9], [0.7, 0.6, 0.9], [0.7, 0.2, 0.9]], float)
    def wall_radiance(texture):
        scene = bsgi.Scene()
        scene.add_bilinear_patch("metal", FLOOR, albedo=[0] * 3, emission=[0] * 3,
                                 bsdf=bsgi.GgxReflection(0.3, 0.3, [0.5] * 3))
        scene.add_bilinear_patch("wall", wall, albedo=[0.7] * 3, emission=[0] * 3)
        scene.add_bilinear_patch("lamp", lamp, albedo=[0] * 3, emission=[5.0] * 3, receiver=False, occluder=False)
        scene.set_specular_texture(0, texture)
        sol = bsgi.solve(scene, settings(bounces=4, coeffs=8))
        uv = texel_centres(5)
        return sol.surfaces[1].evaluate(uv, up(len(uv))).reshape(5, 5, 3)
    half = wall_radiance(np.array([[DARK, LIGHT]], np.float32))
    mean = wall_radiance(np.array([[np.mean([DARK, LIGHT], axis=0)]], np.float32))
    redness = half[..., 0] / half[..., 1]
    print(f"wall's red / green beside the red half {redness[:, 0].mean():.3f}, beside the white half "
          f"{redness[:, -1].mean():.3f}; the wall's total against a metal of the mean colour "
          f"{half.sum() / mean.sum():.4f}")
    assert redness[:, 0].mean() > 1.1 * redness[:, -1].mean()  # measured 1.20 times (1 if the texel were not seen)
    # The light bounced in all is about that of a metal of the mean colour (the halves' shares
    # of it differ by the wall's view of them).
    assert abs(half.sum() / mean.sum() - 1) < 0.01  # measured 2e-4


def test_specular_textures_need_a_ggx_colour():
    scene = bsgi.Scene()
    scene.add_bilinear_patch("paper", FLOOR, albedo=[0.5] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("glass", FLOOR, albedo=[0] * 3, emission=[0] * 3, bsdf=bsgi.RoughDielectric(1.5, 0.3, 0.3))
    scene.add_bilinear_patch("flat metal", FLOOR, albedo=[0] * 3, emission=[0] * 3,
                             bsdf=bsgi.GgxReflection(0.3, 0.3, [0.9] * 3), representation="diffuse")
    image = np.full((2, 2, 3), 0.5, np.float32)
    with pytest.raises(ValueError, match="surface 'paper': specular texture: its lambert BSDF has no glossy colour"):
        scene.set_specular_texture(0, image)
    with pytest.raises(ValueError, match="surface 'glass': specular texture: its rough_dielectric BSDF has no glossy"):
        scene.set_specular_texture(1, image)
    with pytest.raises(ValueError, match="surface 'flat metal': specular texture: needs the glossy representation"):
        scene.set_specular_texture(2, image)
    with pytest.raises(ValueError, match=r"surface 'flat metal': specular texture must be finite and in \[0, 1\]"):
        scene.set_specular_texture(2, np.full((2, 2, 3), 1.5))
    with pytest.raises(IndexError):
        scene.set_specular_texture(5, image)
    scene.add_bilinear_patch("plastic", FLOOR, albedo=[0] * 3, emission=[0] * 3,
                             bsdf=bsgi.DiffuseGgx([0.5] * 3, 0.3, 0.3, [0.04] * 3))
    with pytest.raises(ValueError, match="surface 'plastic': specular texture: its diffuse_ggx BSDF has no glossy"):
        scene.set_specular_texture(3, image)


def test_specular_textured_solution_round_trips_and_gives_no_form_factors(tmp_path):
    scene = bsgi.Scene()
    scene.add_bilinear_patch("metal", FLOOR, albedo=[0] * 3, emission=[0.1, 0, 0],
                             bsdf=bsgi.GgxReflection(0.3, 0.3, [0.5] * 3))
    scene.add_bilinear_patch("lamp", LAMP, albedo=[0] * 3, emission=[3.0] * 3, receiver=False, occluder=False)
    scene.set_specular_texture(0, stripes())
    s = settings(bounces=2)
    s.form_factors = True
    sol = bsgi.solve(scene, s)
    assert sol.stats["transport_terms"] == 0  # scalar rows cannot carry the texel's colour
    metal = sol.surfaces[0]
    # Constant emission stays out of the spline per unit colour, as a one-texel emission texture.
    np.testing.assert_allclose(metal.emission, [[[0.1, 0, 0]]], rtol=1e-7)
    path = tmp_path / "specular.npz"
    bsgi.save_solution(path, sol.surfaces, ["metal", "lamp"], s)
    stored = bsgi.load_solution(path).surfaces[0]
    rng = np.random.default_rng(2)
    uv, d = rng.uniform(0, 1, (30, 2)), views(np.zeros((30, 2)), rng)
    np.testing.assert_array_equal(stored.evaluate(uv, d), metal.evaluate(uv, d))
    np.testing.assert_array_equal(stored.specular, metal.specular)
