"""Textured materials in the core (texture.h, Scene.set_albedo_texture / set_emission_texture):
albedo and emission images over a surface's (u, v), against closed forms."""
import numpy as np
import pytest

import bsgi
from closed_forms import polygon_irradiance

FLOOR = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)  # normal +z
LAMP = np.array([[0.2, 0.2, 0.8], [0.2, 0.8, 0.8], [0.8, 0.8, 0.8], [0.8, 0.2, 0.8]], float)  # normal -z
LIGHT, DARK = np.array([0.9, 0.9, 0.9]), np.array([0.8, 0.1, 0.1])


def checker(n, light=LIGHT, dark=DARK):
    """(n, n, 3) image: light where column + row is even."""
    even = (np.add.outer(np.arange(n), np.arange(n)) % 2 == 0)[..., None]
    return np.where(even, light, dark).astype(np.float32)


def bilinear(corners, uv):
    p00, p10, p11, p01 = corners
    u, v = uv[:, :1], uv[:, 1:]
    return (1 - u) * (1 - v) * p00 + u * (1 - v) * p10 + u * v * p11 + (1 - u) * v * p01


def texel_centres(n):
    c = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(c, c)  # row along v, column along u
    return np.column_stack([u.ravel(), v.ravel()])


def settings(bounces=0, coeffs=16):
    s = bsgi.SolverSettings()
    s.max_bounces = bounces
    s.spatial_coeffs = coeffs
    return s


def up(n):
    return np.tile([0.0, 0.0, 1.0], (n, 1))


def test_textured_floor_is_albedo_map_times_irradiance_over_pi():
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", FLOOR, albedo=[0.5] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("lamp", LAMP, albedo=[0] * 3, emission=[3.0] * 3, receiver=False, occluder=False)
    image = checker(8)
    scene.set_albedo_texture(0, image)
    floor = bsgi.solve(scene, settings()).surfaces[0]
    uv = texel_centres(8)
    got = floor.evaluate(uv, up(len(uv)))
    E = np.array([polygon_irradiance(p, [0, 0, 1], list(LAMP), 3.0) for p in bilinear(FLOOR, uv)])
    want = image.reshape(-1, 3) * (E / np.pi)[:, None]
    err = np.abs(got / want - 1).max()
    print(f"checker floor under a lamp: max relative error {err:.2e} at the 64 texel centres")
    assert err <= 0.01
    # The spline is the smooth factor irradiance / pi; the texture is kept as given.
    np.testing.assert_array_equal(floor.albedo, image)
    assert floor.emission is None


@pytest.mark.parametrize("split", [2, 3])
def test_emission_texture_lights_with_its_pattern(split):
    # The lamp's left 1/split (u < 1/split) emits 2, the rest nothing: a small receiver below
    # gets the closed form of that part alone. 1/3 falls inside the emitter's quadrature cells.
    image = np.zeros((1, split, 3), np.float32)
    image[0, 0] = 2.0
    receiver = np.array([[0.45, 0.45, 0], [0.55, 0.45, 0], [0.55, 0.55, 0], [0.45, 0.55, 0]], float)
    scene = bsgi.Scene()
    scene.add_bilinear_patch("receiver", receiver, albedo=[0.6] * 3, emission=[0] * 3)
    # u runs along LAMP's first edge (y), v along x.
    scene.add_bilinear_patch("lamp", LAMP, albedo=[0] * 3, emission=[1.0] * 3, receiver=False, occluder=False)
    scene.set_emission_texture(1, image)
    sol = bsgi.solve(scene, settings(coeffs=6))
    y_edge = 0.2 + 0.6 / split
    part = [[0.2, 0.2, 0.8], [0.2, y_edge, 0.8], [0.8, y_edge, 0.8], [0.8, 0.2, 0.8]]
    uv = np.array([[0.1, 0.1], [0.5, 0.5], [0.9, 0.3], [0.2, 0.8]])
    want = np.array([0.6 / np.pi * polygon_irradiance(p, [0, 0, 1], part, 2.0) for p in bilinear(receiver, uv)])
    got = sol.radiance[0].evaluate(uv)[:, 0]
    err = np.abs(got / want - 1).max()
    print(f"lamp emitting on 1/{split} of it: max relative error {err:.2e}")
    # An edge on a cell boundary is exact to the quadrature; one inside a node's share of a cell
    # is weighted by the geometric factor at the node (1.5% here).
    assert err <= (6e-4 if split == 2 else 0.03)  # measured 2.9e-4 and 1.5e-2


def test_emission_texture_is_what_the_surface_shows():
    scene = bsgi.Scene()
    scene.add_bilinear_patch("screen", FLOOR, albedo=[0] * 3, emission=[0] * 3)
    image = np.array([[[1.0, 0.0, 0.0], [0.0, 0.0, 4.0]]], np.float32)  # red at u < 1/2, blue beyond
    scene.set_emission_texture(0, image)
    screen = bsgi.solve(scene, settings()).surfaces[0]
    uv = np.array([[0.1, 0.5], [0.9, 0.5], [0.5, 0.5]])
    np.testing.assert_allclose(screen.evaluate(uv, up(3)), [[1, 0, 0], [0, 0, 4], [0.5, 0, 2]], atol=1e-12)


def test_two_sided_emission_texture_shows_on_both_sides_and_lights_below(tmp_path):
    # Cycles' Emission shader on a mesh emits from both faces: a textured screen made two-sided
    # shows its texture from behind too, lights a floor below it by its back, and keeps that
    # through a solution file.
    scene = bsgi.Scene()
    screen = FLOOR + [0, 0, 1.0]  # normal +z, the floor under its back
    scene.add_bilinear_patch("screen", screen, albedo=[0] * 3, emission=[0] * 3, receiver=False)
    scene.add_bilinear_patch("floor", FLOOR, albedo=[0.5] * 3, emission=[0] * 3)
    image = np.array([[[2.0, 2.0, 2.0], [2.0, 2.0, 2.0]]], np.float32)
    scene.set_emission_texture(0, image)
    one_sided = bsgi.solve(scene, settings()).surfaces[1].evaluate(np.array([[0.5, 0.5]]), up(1))[0, 0]
    scene.set_two_sided_emission(0)
    sol = bsgi.solve(scene, settings())
    centre = np.array([[0.5, 0.5]])
    want = 0.5 / np.pi * polygon_irradiance([0.5, 0.5, 0], [0, 0, 1], screen[::-1], 2.0)
    got = sol.surfaces[1].evaluate(centre, up(1))[0, 0]
    print(f"floor under a two-sided textured screen: {got:.5f}, closed form {want:.5f}; one-sided {one_sided:.2e}")
    assert one_sided == 0 and abs(got / want - 1) < 5e-3  # measured 2.6e-3 (the emitter cells' quadrature)
    textured = bsgi.SurfaceRadiance("diffuse", 1.0, sol.surfaces[1].upper, emission=image, two_sided_emission=True)
    np.testing.assert_allclose(textured.evaluate(centre, -up(1))[0], [2, 2, 2])
    path = tmp_path / "two_sided.npz"
    bsgi.save_solution(path, [textured], ["screen"], settings())
    loaded = bsgi.load_solution(path).surfaces[0]
    assert loaded.two_sided_emission
    np.testing.assert_allclose(loaded.evaluate(centre, -up(1))[0], [2, 2, 2])


def bounce_onto_wall(floor_albedo, texture=None, form_factors=False):
    """A wall facing a floor lit from above; the wall's radiance at a grid of points."""
    wall = np.array([[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]], float)  # at y = 1, u along x, normal -y
    lamp = np.array([[0.3, 0.2, 0.9], [0.3, 0.6, 0.9], [0.7, 0.6, 0.9], [0.7, 0.2, 0.9]], float)
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", FLOOR, albedo=floor_albedo, emission=[0] * 3)
    scene.add_bilinear_patch("wall", wall, albedo=[0.7] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("lamp", lamp, albedo=[0] * 3, emission=[5.0] * 3, receiver=False, occluder=False)
    if texture is not None:
        scene.set_albedo_texture(0, texture)
    s = settings(bounces=8, coeffs=12)
    s.form_factors = form_factors
    sol = bsgi.solve(scene, s)
    uv = texel_centres(5)
    return sol, sol.surfaces[1].evaluate(uv, up(len(uv)))


def test_fine_checker_bounces_its_mean_colour():
    image = checker(32)
    _, textured = bounce_onto_wall([0.5] * 3, image)
    _, uniform = bounce_onto_wall(image.reshape(-1, 3).mean(axis=0))
    rows = np.abs(textured / uniform - 1).max(axis=1).reshape(5, 5).max(axis=1)  # by height on the wall
    print(f"wall lit by a 32 x 32 checker floor against its mean colour: max relative difference by height "
          f"{np.array2string(rows, precision=1)}")
    # Above its lowest row. The wall's lowest nodes, at epsilon above the floor, see the one 3 cm
    # texel beside them (as they should: a wall's base takes the colour of the floor it stands
    # on), and the sharpened fit carries an eighth of that into the lowest row (1.3%; 3.5e-4
    # with Schoenberg's fit).
    assert rows[1:].max() <= 1e-3  # measured 4.0e-4
    assert rows[0] <= 0.026


def test_half_red_floor_reddens_the_wall_near_it():
    # A coarse texture is not its mean: red at u < 1/2 (x < 0.5) reddens that half of the wall.
    image = np.array([[DARK, LIGHT]], np.float32)
    _, wall = bounce_onto_wall([0.5] * 3, image)
    wall = wall.reshape(5, 5, 3)  # rows along the wall's v (height), columns along u (x)
    redness = wall[..., 0] / wall[..., 1]
    print(f"wall's red / green beside the red half {redness[:, 0].mean():.3f}, beside the white half "
          f"{redness[:, -1].mean():.3f}")
    assert redness[:, 0].mean() > 1.1 * redness[:, -1].mean()


def test_decomposed_surface_with_constant_texture_equals_its_constant_albedo():
    # DiffuseGgx whose base colour is a one-texel texture: the same light as the plain BSDF,
    # for the diffuse base D (times the texture) and the glossy part S.
    def solve(textured):
        scene = bsgi.Scene()
        albedo = [0.3, 0.5, 0.7]
        bsdf = bsgi.DiffuseGgx([1.0] * 3 if textured else albedo, 0.3, 0.3, [0.04] * 3)
        scene.add_bilinear_patch("floor", FLOOR, albedo=[0] * 3, emission=[0] * 3, bsdf=bsdf, spatial_coeffs=6,
                                 angular_coeffs=6)
        scene.add_bilinear_patch("lamp", LAMP, albedo=[0] * 3, emission=[3.0] * 3, receiver=False, occluder=False)
        if textured:
            scene.set_albedo_texture(0, np.array([[albedo]], np.float32))
        return bsgi.solve(scene, settings()).surfaces[0]
    plain, textured = solve(False), solve(True)
    assert plain.kind == textured.kind == "decomposed"
    rng = np.random.default_rng(1)
    uv = rng.uniform(0, 1, (40, 2))
    d = rng.normal(size=(40, 3))
    d[:, 2] = np.abs(d[:, 2])
    np.testing.assert_allclose(textured.evaluate(uv, d), plain.evaluate(uv, d), rtol=1e-6)  # float32 texels


@pytest.mark.parametrize("image, message", [
    (np.full((2, 2, 3), np.nan), "finite"),
    (np.full((2, 2, 3), -0.1), r"\[0, 1\]"),
    (np.full((2, 2, 3), 1.5), r"\[0, 1\]"),
    (np.full((2, 2), 0.5), r"shape \(height, width, 3\)"),
    (np.zeros((0, 2, 3)), "at least one texel"),
])
def test_bad_albedo_textures_are_refused_by_name(image, message):
    scene = bsgi.Scene()
    scene.add_bilinear_patch("Checker floor", FLOOR, albedo=[0.5] * 3, emission=[0] * 3)
    with pytest.raises(ValueError, match=f"surface 'Checker floor': albedo texture.*{message}"):
        scene.set_albedo_texture(0, image)


def test_textures_need_a_diffuse_base_and_non_negative_emission():
    scene = bsgi.Scene()
    scene.add_bilinear_patch("metal", FLOOR, albedo=[0] * 3, emission=[0] * 3, bsdf=bsgi.GgxReflection(0.3, 0.3, [0.9] * 3))
    with pytest.raises(ValueError, match="surface 'metal': albedo texture: its ggx BSDF has no diffuse base"):
        scene.set_albedo_texture(0, np.full((2, 2, 3), 0.5))
    with pytest.raises(ValueError, match="surface 'metal': emission texture must be finite and in"):
        scene.set_emission_texture(0, np.full((2, 2, 3), -1.0))
    with pytest.raises(IndexError):
        scene.set_albedo_texture(3, np.full((2, 2, 3), 0.5))


def test_textured_solution_round_trips(tmp_path):
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", FLOOR, albedo=[0.5] * 3, emission=[0.1, 0, 0])
    scene.add_bilinear_patch("lamp", LAMP, albedo=[0] * 3, emission=[3.0] * 3, receiver=False, occluder=False)
    scene.set_albedo_texture(0, checker(4))
    s = settings()
    sol = bsgi.solve(scene, s)
    floor = sol.surfaces[0]
    # Constant emission beside a texture stays out of the spline, as a one-texel emission texture.
    np.testing.assert_allclose(floor.emission, [[[0.1, 0, 0]]], rtol=1e-7)
    path = tmp_path / "textured.npz"
    bsgi.save_solution(path, sol.surfaces, ["floor", "lamp"], s)
    stored = bsgi.load_solution(path).surfaces[0]
    uv = np.random.default_rng(2).uniform(0, 1, (30, 2))
    np.testing.assert_array_equal(stored.evaluate(uv, up(30)), floor.evaluate(uv, up(30)))
    np.testing.assert_array_equal(stored.albedo, floor.albedo)


def test_form_factors_give_way_to_textures():
    # Rows of scalar weights cannot colour the light by a texel: with textures the bounces gather.
    image = checker(8)
    plain, wall = bounce_onto_wall([0.5] * 3, image)
    rows, wall_rows = bounce_onto_wall([0.5] * 3, image, form_factors=True)
    assert rows.stats["transport_terms"] == 0
    np.testing.assert_array_equal(wall_rows, wall)
