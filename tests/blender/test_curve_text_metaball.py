"""Curve, text and metaball objects (addon/geometry.py EVALUATED_ONLY): solved through their
evaluated mesh, so they cast shadows and reflect light, but not baked (their mesh exists only
while Blender evaluates them), with a warning naming the object and what to do."""
import bpy
import numpy as np

import scenes
from bsgi_addon import bake, pipeline


def add_text(name="Text", body="BSGI", location=(-0.6, -0.2, 0.5)):
    curve = bpy.data.curves.new(name, "FONT")
    curve.body = body
    curve.size = 0.5
    curve.extrude = 0.02
    obj = bpy.data.objects.new(name, curve)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_bevelled_curve(name="Ring", location=(0, 0, 0.35)):
    bpy.ops.curve.primitive_bezier_circle_add(radius=0.5, location=location)
    obj = bpy.context.object
    obj.name = obj.data.name = name
    obj.data.bevel_depth = 0.06
    return obj


def floor_mean_radiance(context):
    """The lit floor's radiance averaged over a grid of its (u, v), and the job."""
    job = pipeline.prepare(context)
    solution = pipeline.run(job)
    floor = next(o for o in job.export.objects if o.name == "Floor")
    u, v = np.meshgrid(np.linspace(0.05, 0.95, 19), np.linspace(0.05, 0.95, 19))
    spline = solution.radiance[floor.patches[0][1]]
    return spline.evaluate(np.stack([u.ravel(), v.ravel()], axis=1))[:, 0].mean(), job, solution


def _curve_state(obj):
    data = obj.data
    return (obj.type, list(obj.keys()), [(s.link, s.material.name if s.material else None) for s in obj.material_slots],
            len(data.materials), getattr(data, "body", None), data.bevel_depth, data.extrude,
            [tuple(p.co) for s in getattr(data, "splines", []) for p in s.bezier_points])


def test_text_and_bevelled_curve_shadow_the_floor_and_are_not_baked(context):
    scenes.floor_under_lamp()
    context.scene.bsgi.preset = "DRAFT"
    alone, _, _ = floor_mean_radiance(context)
    text, ring = add_text(), add_bevelled_curve()
    before = {o.name: _curve_state(o) for o in (text, ring)}
    shadowed, job, solution = floor_mean_radiance(context)
    print(f"\nfloor mean radiance {alone:.4f} alone, {shadowed:.4f} under a text and a bevelled curve")
    assert shadowed < 0.97 * alone  # both stand between the lamp and the floor
    names = [job.export.scene.name(i) for i in range(len(job.export.scene))]
    # Of many faces (the text 994, the ring 576), each is one UV chart (the ring over its own UV
    # map, the text over one generated on a copy) as a mesh would be.
    assert "Text: chart 0" in names and "Ring: chart 0" in names
    # They receive light too (and so reflect it): their solved radiance is not all zero.
    u, v = np.meshgrid(np.linspace(0.05, 0.95, 10), np.linspace(0.05, 0.95, 10))
    grid = np.stack([u.ravel(), v.ravel()], axis=1)
    for name in ("Text: chart 0", "Ring: chart 0"):
        assert solution.radiance[names.index(name)].evaluate(grid)[:, 0].max() > 0.01 * alone
    assert not any("Smart UV Project" in w for w in job.export.warnings)  # a map only the solve sees
    assert [o.name for o in job.export.objects] == ["Floor"]  # only the floor is baked
    for name, kind in (("Text", "text"), ("Ring", "curve")):
        warning = next(w for w in job.export.warnings if f"object '{name}'" in w and "not baked" in w)
        assert f"{kind} objects" in warning and "Object > Convert > Mesh" in warning
    rep = pipeline.solve_and_bake(context)
    assert any("object 'Text'" in w for w in rep["warnings"])
    assert {o.name: _curve_state(o) for o in (text, ring)} == before  # the user's curves as they were
    assert not bake.is_baked(text) and not bake.is_baked(ring) and bake.is_baked(bpy.data.objects["Floor"])


def test_small_text_is_solved_per_face(context):
    scenes.floor_under_lamp()
    add_text(body="-")
    context.scene.bsgi.preset = "DRAFT"
    job = pipeline.prepare(context)
    names = [job.export.scene.name(i) for i in range(len(job.export.scene))]
    assert "Text: face 0" in names and len(names) < 2 + 64  # under Chart Above Faces
    assert any("object 'Text'" in w and "not baked" in w for w in job.export.warnings)


def test_metaball_is_solved_and_not_baked(context):
    scenes.floor_under_lamp()
    bpy.ops.object.metaball_add(radius=0.3, location=(0, 0, 0.5))
    ball = context.object
    context.scene.bsgi.preset = "DRAFT"
    rep = pipeline.solve_and_bake(context)
    assert any(f"object '{ball.name}'" in w and "metaball objects" in w and "not baked" in w for w in rep["warnings"])
    assert rep["surfaces"] > 2 and not bake.is_baked(ball)
