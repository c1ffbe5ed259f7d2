"""Scene settings of a solve, shown in the panels and read by the operators."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty

import bsgi


def _show_baked_update(self, context):
    from . import bake

    for obj in context.scene.objects:
        bake.show_baked(obj, self.show_baked)


class BSGISceneSettings(bpy.types.PropertyGroup):
    spatial_coeffs: IntProperty(
        name="Spatial Coefficients", default=16, min=1, max=256,
        description="B-spline coefficients per surface direction (u and v): more resolve finer light detail, "
        "cost grows with their square")
    spatial_degree: IntProperty(
        name="Degree", default=2, min=0, max=5,
        description="Degree of the radiance splines (2, quadratic, is the paper's choice)")
    max_bounces: IntProperty(
        name="Bounces", default=4, min=0, max=64,
        description="Indirect bounces after direct light; the solve stops earlier once a bounce adds less than the tolerance")
    tolerance: FloatProperty(
        name="Tolerance", default=1e-3, min=0.0, max=1.0, precision=4,
        description="Stop bouncing when the largest increment is below this fraction of the radiance")
    hemisphere_nodes: IntProperty(
        name="Hemisphere Nodes", default=12, min=1, max=256,
        description="Integration nodes in the polar direction of the hemispherical gather (twice as many around)")
    show_baked: BoolProperty(
        name="Show Baked Radiance", default=True, update=_show_baked_update,
        description="Show the solved radiance, or the objects' own materials")

    def solver_settings(self) -> bsgi.SolverSettings:
        s = bsgi.SolverSettings()
        s.spatial_coeffs = max(self.spatial_coeffs, self.spatial_degree + 1)
        s.spatial_degree = self.spatial_degree
        s.max_bounces = self.max_bounces
        s.tolerance = self.tolerance
        s.hemisphere_nodes_theta = self.hemisphere_nodes
        s.hemisphere_nodes_phi = 2 * self.hemisphere_nodes
        return s


classes = (BSGISceneSettings,)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.bsgi = bpy.props.PointerProperty(type=BSGISceneSettings)


def unregister():
    del bpy.types.Scene.bsgi
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
