"""Smooth-shaded meshes as Cycles renders them (addon/geometry.py corner_normals; the core's
SurfacePoint::shading): a coarse smooth UV sphere on a floor under a sun and a grey world, baked and
rendered, against Cycles' path-traced render of the same camera."""
import math

import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

import scenes
from bsgi_addon import geometry, pipeline
from test_pipeline import render_exr
from test_world_light import world

RADIUS, ORTHO = 0.5, 1.3


def sphere_on_floor(context, segments=16):
    grey = scenes.diffuse_material("Grey", (0.7, 0.7, 0.7))
    scenes.add_quad("Floor", [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], grey)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=segments // 2, radius=RADIUS, location=(0, 0, RADIUS))
    ball = bpy.context.active_object
    ball.name = "Ball"
    ball.data.materials.append(grey)
    ball.data.shade_smooth()
    light = bpy.data.lights.new("Sun", "SUN")
    light.energy, light.angle = 3.0, math.radians(0.5)
    sun = bpy.data.objects.new("Sun", light)
    sun.rotation_euler = (0, math.radians(50), math.radians(30))
    context.scene.collection.objects.link(sun)
    world(context, color=(0.15, 0.15, 0.15), strength=1.0)
    cam = bpy.data.cameras.new("Side")
    cam.type, cam.ortho_scale = "ORTHO", ORTHO
    camera = bpy.data.objects.new("Side", cam)
    camera.location = (3.0, -1.5, 2.0)
    camera.rotation_euler = (Vector((0, 0, RADIUS)) - camera.location).to_track_quat("-Z", "Y").to_euler()
    context.scene.collection.objects.link(camera)
    context.view_layer.update()
    context.scene.camera = camera
    return ball, camera


def sphere_pixels(context, camera, n):
    """The pixels well inside the sphere's outline (0.85 of its radius: the facets' silhouette
    differs from the smooth one), row-major as the rendered image."""
    centre = world_to_camera_view(context.scene, camera, bpy.data.objects["Ball"].location)
    x = (np.arange(n) + 0.5) / n
    px, py = np.meshgrid(x, 1 - x)  # image rows run downwards
    return (np.hypot(px - centre.x, py - centre.y) < 0.85 * RADIUS / ORTHO).ravel()


# Measured at the preview preset against 2,048 samples of 12 bounces, mean relative difference
# over the sphere's pixels, solved smooth and with each face's own normal (as before):
# - a Diffuse BSDF: 1.01% and 5.9% (at final 0.84% and 6.6%; with the core's default settings
#   1.7% and 7.7%, the rest in the sphere's dark side: the floor's bounce);
# - Blender's default Principled BSDF (its coat solved, test_principled_materials.py): 1.13% and
#   5.8%, the base's cosine and the coat's lobe both following the interpolated normals, so its
#   highlight is round (with the lobe in each face's own frame it was a lit quad: 1.58%);
# - a rough glass (Glass BSDF, roughness 0.5, Multiscatter GGX): 12.9% and 15.4% (7 December;
#   the flat faces' bands gone). What is left is the light through the glass, not its normals:
#   the sphere's shadow on the floor, seen through it, is fainter than Cycles': the ball focuses
#   the sun inside its shadow, which the preview's 24 x 24 spatial coefficients on the ball blur
#   and the final's 48 x 48 resolve (bench/bench_glass_ball.py: the floor 21.5% from Cycles at
#   preview, 6.0% at final; the floor's mean within 0.8% at both).
# Each: (the figure, how much worse the flat faces must be).
SPHERE_MATERIALS = {"diffuse": (0.0101, 3), "default material": (0.0113, 3), "glass": (0.129, 1.1)}


@pytest.mark.slow
@pytest.mark.parametrize("material", sorted(SPHERE_MATERIALS))
def test_smooth_sphere_baked_matches_cycles(context, tmp_path, monkeypatch, material):
    from test_export import shader_material
    from test_principled_materials import principled

    scene = context.scene
    ball, camera = sphere_on_floor(context)
    if material == "default material":
        ball.data.materials.clear()
        ball.data.materials.append(principled("Default"))
    if material == "glass":
        ball.data.materials.clear()
        ball.data.materials.append(shader_material("Frosted", "ShaderNodeBsdfGlass", Roughness=0.5, IOR=1.5)[0])
    scene.bsgi.preset = "PREVIEW"
    reference = render_exr(scene, tmp_path / "reference.exr", samples=2048, bounces=12)
    mask = sphere_pixels(context, camera, reference.shape[0])
    ref = reference.reshape(-1, 3)[mask].sum(axis=1)

    def baked_difference(label):
        pipeline.solve_and_bake(context)
        baked = render_exr(scene, tmp_path / f"{label}.exr", samples=16, bounces=0)
        rel = np.abs(baked.reshape(-1, 3)[mask].sum(axis=1) - ref) / ref
        print(f"\n{material}, {label}: mean relative difference {rel.mean():.4f} over {mask.sum()} sphere pixels, "
              f"90th percentile {np.percentile(rel, 90):.4f}")
        return rel.mean()

    smooth = baked_difference("smooth")
    monkeypatch.setattr(geometry, "FLAT_FACE_DEGREES", 360.0)  # every face its own normal, as before
    flat = baked_difference("flat")
    assert mask.sum() > 1000
    measured, flat_worse = SPHERE_MATERIALS[material]
    assert smooth < (1.5 if material == "glass" else 2) * measured
    assert flat > flat_worse * smooth
