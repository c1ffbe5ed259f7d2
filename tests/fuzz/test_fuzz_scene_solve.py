"""Fuzzing scenes and solves (issue 17, item 1): scenes of random and degenerate geometry
(collinear, coincident, huge and tiny, far from the origin), random materials, lights, textures
and settings, solved with tiny settings (milliseconds each). Each either solves to finite radiance
splines of the surfaces it receives on, or is refused by a ValueError naming the surface, light,
world or 'solver settings' and the problem."""
import numpy as np
from hypothesis import given, settings, strategies as st

import bsgi
from fuzz_support import any_float, arrays, case, examples, finite, refused, rgb, unit_float
from test_fuzz_surfaces import BSDFS, SURFACES, build, make_bsdf

SCALE = st.sampled_from([1.0, 1.0, 1e-3, 1e3, 1e-6, 1e5])
OFFSET = st.sampled_from([0.0, 0.0, 10.0, 1e4, -1e6])
UV = np.array([[0.5, 0.5], [0, 0], [1, 1], [0.1, 0.9], [1, 0]])


def tiny_settings(**values):
    """A solve of milliseconds: few coefficients, nodes and bounces."""
    s = bsgi.SolverSettings()
    s.spatial_coeffs, s.spatial_coeffs_min, s.spatial_degree = 3, 2, 1
    s.angular_coeffs_min, s.angular_coeffs_max, s.angular_degree = 2, 3, 1
    s.hemisphere_nodes_theta, s.hemisphere_nodes_phi, s.bsdf_samples = 2, 4, 2
    s.emitter_coeffs, s.emitter_degree, s.emitter_max_depth = 2, 1, 2
    s.max_bounces, s.threads, s.memory_budget_mb = 1, 2, 256
    for k, v in values.items():
        setattr(s, k, v)
    return s


@st.composite
def surface_entry(draw, index):
    """One call that adds a surface: (method, kwargs) with a name naming it in errors."""
    name = f"obj{index}"
    scale, offset = draw(SCALE), draw(OFFSET)
    emits = draw(st.booleans())
    material = dict(albedo=draw(rgb()), emission=draw(rgb(st.floats(0, 10))) if emits else [0.0] * 3)
    if draw(st.booleans()):
        material["bsdf"] = draw(BSDFS)
    material["receiver"], material["occluder"] = draw(st.booleans()), draw(st.booleans())
    material["representation"] = draw(st.sampled_from(["auto", "auto", "diffuse", "glossy", "decomposed", "bogus"]))
    material["spatial_coeffs"] = draw(st.sampled_from([0, 0, 2, 3, -1]))
    material["angular_coeffs"] = draw(st.sampled_from([0, 0, 2, 3, -1]))
    kind = draw(st.sampled_from(["bilinear", "triangle", "disk", "surface"]))
    c = draw(arrays((4, 3), st.one_of(st.floats(-1, 1), st.sampled_from([0.0, 1.0]), any_float))) * scale + offset
    if kind == "bilinear":
        return ("add_bilinear_patch", dict(name=name, corners=c, **material))
    if kind == "triangle":
        return ("add_triangle", dict(name=name, corners=c[:3], **material))
    if kind == "disk":
        return ("add_disk", dict(name=name, center=c[0], axis_a=c[1] - offset, axis_b=c[2] - offset, **material))
    spec = draw(SURFACES)
    extra = {}
    if draw(st.integers(0, 5)) == 0:
        extra = dict(thin_glass=draw(st.one_of(st.floats(1, 2), any_float)), one_interface=draw(st.booleans()),
                     shadow_transmittance=draw(st.one_of(st.none(), unit_float, any_float)))
    return ("add_surface", dict(surface=spec, **material, **extra))


@st.composite
def scenes(draw):
    entries = [draw(surface_entry(i)) for i in range(draw(st.integers(0, 4)))]
    if draw(st.booleans()):  # a lamp that certainly works, so most scenes reach the solver
        entries.append(("add_bilinear_patch", dict(name="lamp", corners=np.array([[0, 0, 2], [0, 1, 2], [1, 1, 2], [1, 0, 2]], float),
                                                   albedo=[0.0] * 3, emission=[5.0] * 3, receiver=False, occluder=False)))
    extras = dict(
        world=draw(st.one_of(st.none(), rgb(st.floats(0, 2)))),
        distant=draw(st.one_of(st.none(), st.tuples(rgb(st.floats(-1, 1)), rgb(st.floats(0, 3)), any_float))),
        spot=draw(st.one_of(st.none(), st.tuples(st.integers(-1, 5), rgb(st.floats(-1, 1)), any_float, any_float))),
        albedo_texture=draw(st.one_of(st.none(), st.tuples(st.integers(-1, 5), arrays(
            st.tuples(st.integers(0, 3), st.integers(0, 3), st.sampled_from([3, 3, 2])), st.one_of(unit_float, any_float))))),
        emission_texture=draw(st.one_of(st.none(), st.tuples(st.integers(-1, 5), arrays(
            st.tuples(st.integers(1, 3), st.integers(1, 3), st.just(3)), st.floats(0, 5))))),
    )
    return entries, extras


def names_of(entries):
    return [e[1]["name"] if "name" in e[1] else "'S'" for e in entries]


def add_all(scene, entries, extras):
    """Builds the scene; every refusal must name the thing refused. Returns the indices added."""
    added = []
    for method, kwargs in entries:
        kwargs = dict(kwargs)
        name = kwargs.get("name", "S")
        try:
            if "bsdf" in kwargs:
                kwargs["bsdf"] = make_bsdf(kwargs["bsdf"])
            if "surface" in kwargs:
                kwargs["surface"] = build(kwargs["surface"])
            added.append(getattr(scene, method)(**kwargs))
        except ValueError as e:
            refused(e, f"'{name}'", "albedo", "kd", "ks", "rd", "rs", "exponent", "GGX", "eta", "dielectric", "Lambert", "Phong", "Ashikhmin")
    assert len(scene) == len(added) and added == list(range(len(added)))
    for what, args, method, names in (
            ("world", extras["world"], "world", ("world",)),
            ("distant", extras["distant"], "add_distant_light", ("distant light 'sun'",)),
            ("spot", extras["spot"], "set_spot_cone", ("spot light", "set_spot_cone")),
            ("albedo_texture", extras["albedo_texture"], "set_albedo_texture", ("albedo texture", "set_albedo_texture")),
            ("emission_texture", extras["emission_texture"], "set_emission_texture", ("emission texture", "set_emission_texture"))):
        if args is None:
            continue
        try:
            if what == "world":
                scene.world_radiance = args
            elif what == "distant":
                scene.add_distant_light("sun", args[0], args[1], args[2])
            elif args[0] < 0:
                continue  # a negative index is not a size_t: pybind11's TypeError, not ours
            else:
                getattr(scene, method)(*args)
        except (ValueError, IndexError) as e:
            refused(e, *names)
    return added


def check_solution(scene, solution):
    assert len(solution.radiance) == len(scene) == len(solution.surfaces)
    for i, (spline, surface) in enumerate(zip(solution.radiance, solution.surfaces)):
        if spline is None:
            continue
        finite(spline.coefficients, f"surface {i}'s coefficients")
        if spline.dims == 2:
            finite(spline.evaluate(UV), f"surface {i}'s radiance")
        else:
            finite(surface.evaluate(UV, np.tile([0.0, 0.3, 0.9], (len(UV), 1))), f"surface {i}'s radiance")
    for key, value in solution.stats.items():
        assert np.isfinite(value) or key == "estimated_error", (key, value)


def solve_or_refuse(scene, s):
    try:
        estimate = bsgi.estimate_solve_bytes(scene, s)
        assert estimate >= 0
        return bsgi.solve(scene, s)
    except ValueError as e:
        names = [f"'{scene.name(i)}'" for i in range(len(scene))]
        refused(e, "solver settings", "no emitter", "world", "distant light", *names)
    except (RuntimeError, MemoryError) as e:  # over the memory budget
        assert "budget" in str(e) and "surface '" in str(e), e
    return None


@settings(max_examples=examples(700))
@given(scene_spec=scenes(), bounces=st.integers(0, 2), form_factors=st.booleans(), adaptive=st.booleans(),
       discontinuity=st.booleans(), near_contacts=st.booleans())
def test_random_scenes_solve_or_are_refused(scene_spec, bounces, form_factors, adaptive, discontinuity, near_contacts):
    entries, extras = scene_spec
    case(entries=entries, extras=extras, bounces=bounces, form_factors=form_factors, adaptive=adaptive,
         discontinuity=discontinuity, near_contacts=near_contacts)
    scene = bsgi.Scene()
    add_all(scene, entries, extras)
    solution = solve_or_refuse(scene, tiny_settings(max_bounces=bounces, form_factors=form_factors,
                                                    adaptive_knots=adaptive, discontinuity_knots=discontinuity,
                                                    near_contact_knots=near_contacts,
                                                    emitter_shadow_depth=3 if discontinuity else 0))
    if solution is not None:
        check_solution(scene, solution)


FIELDS = {
    "spatial_coeffs": st.integers(-2, 6), "spatial_degree": st.integers(-1, 6), "epsilon": any_float,
    "coeffs_from_size": st.booleans(), "spatial_coeffs_min": st.integers(-1, 4), "adaptive_knots": st.booleans(),
    "discontinuity_knots": st.booleans(), "near_contact_knots": st.booleans(), "emitter_shadow_depth": st.integers(-1, 13),
    "detail_tolerance": any_float, "knot_detail_share": any_float,
    "angular_degree": st.integers(-1, 6), "angular_delta": any_float, "angular_resolution": any_float,
    "angular_coeffs_min": st.integers(-1, 4), "angular_coeffs_max": st.integers(-1, 5),
    "emitter_coeffs": st.integers(-1, 4), "emitter_degree": st.integers(-1, 4), "emitter_cell_ratio": any_float,
    "emitter_max_depth": st.integers(-1, 25), "hemisphere_nodes_theta": st.integers(-1, 4),
    "hemisphere_nodes_phi": st.integers(-1, 6), "bsdf_samples": st.integers(-1, 4), "max_bounces": st.integers(-1, 3),
    "form_factors": st.booleans(), "tolerance": any_float, "extrapolate": st.booleans(), "final_gather": st.booleans(),
    "final_spatial_factor": st.integers(-1, 2), "final_integration_factor": st.integers(-1, 2),
    "threads": st.integers(-2, 3), "memory_budget_mb": any_float,
}


def two_surface_scene(glossy):
    scene = bsgi.Scene()
    bsdf = bsgi.GgxReflection(0.3, 0.3, [0.5] * 3) if glossy else None
    scene.add_bilinear_patch("floor", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), albedo=[0.5] * 3,
                             emission=[0] * 3, bsdf=bsdf)
    scene.add_bilinear_patch("lamp", np.array([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]], float), albedo=[0.5] * 3,
                             emission=[1] * 3)
    return scene


@settings(max_examples=examples(700))
@given(values=st.fixed_dictionaries({}, optional=FIELDS), glossy=st.booleans())
def test_random_settings_solve_or_are_refused(values, glossy):
    case(values=values, glossy=glossy)
    s = tiny_settings()
    for k, v in values.items():
        setattr(s, k, v)
    scene = two_surface_scene(glossy)
    solution = solve_or_refuse(scene, s)
    if solution is not None:
        check_solution(scene, solution)


HUGE = st.sampled_from([10**4, 10**6, 2**31 - 1])


@settings(max_examples=examples(60))
@given(field=st.sampled_from(["spatial_coeffs", "angular_coeffs_min", "angular_coeffs_max", "emitter_coeffs",
                              "final_spatial_factor", "spatial_coeffs_min"]), value=HUGE, glossy=st.booleans())
def test_absurd_sizes_are_refused_before_they_allocate(field, value, glossy):
    """Sizes that would take gigabytes are refused by the memory budget, quickly, naming it."""
    case(field=field, value=value, glossy=glossy)
    s = tiny_settings(final_gather=field == "final_spatial_factor")
    if field == "angular_coeffs_min":
        s.angular_coeffs_max = value
    setattr(s, field, value)
    scene = two_surface_scene(glossy)
    solution = solve_or_refuse(scene, s)
    if solution is not None:
        check_solution(scene, solution)


@settings(max_examples=examples(300))
@given(index=st.integers(-2, 4), u=any_float, v=any_float)
def test_scene_accessors_with_any_index(index, u, v):
    case(index=index, u=u, v=v)
    scene = two_surface_scene(False)
    for call in (lambda: scene.surface(index), lambda: scene.name(index), lambda: scene.area(index),
                 lambda: scene.is_thin_glass(index), lambda: scene.evaluate_surface(index, u, v)):
        try:
            out = call()
        except (IndexError, TypeError) as e:  # TypeError: a negative index is no size_t (pybind11)
            assert index < 0 or index >= len(scene), e
            continue
        assert 0 <= index < len(scene)
        if isinstance(out, dict) and 0 <= u <= 1 and 0 <= v <= 1:
            for value in out.values():
                finite(value)
