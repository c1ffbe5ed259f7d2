"""Panels: Render Properties and the 3D view sidebar show the same controls."""
from __future__ import annotations

import bpy

from . import error_view


def draw_controls(layout, scene, obj=None):
    settings = scene.bsgi
    layout.operator("bsgi.solve", icon="LIGHT_AREA")
    layout.prop(settings, "preset")
    col = layout.column(align=True)
    col.enabled = settings.preset == "CUSTOM"  # shown for reference, used only by Custom
    col.prop(settings, "spatial_coeffs")
    col.prop(settings, "spatial_degree")
    col.prop(settings, "max_bounces")
    col.prop(settings, "tolerance")
    col.prop(settings, "hemisphere_nodes")
    layout.prop(settings, "refinement")
    row = layout.row(align=True)
    row.enabled = settings.refinement == "TO_ERROR"  # shown for reference, used only by To Error
    row.prop(settings, "refine_to_error")
    row.prop(settings, "refine_passes", text="Passes")
    row.prop(settings, "refine_cost", text="Budget")
    layout.prop(settings, "coats")
    layout.prop(settings, "bumps")
    layout.prop(settings, "adaptive_coefficients")
    row = layout.row()
    row.enabled = settings.adaptive_coefficients == "TOLERANCE"  # shown for reference, used only by To Tolerance
    row.prop(settings, "detail_tolerance")
    layout.prop(settings, "chart_min_faces")
    layout.prop(settings, "texture_texels")
    layout.prop(settings, "world_map_width")
    row = layout.row(align=True)
    row.prop(settings, "show_baked", toggle=True)
    row.operator("bsgi.rebake", text="", icon="FILE_REFRESH")
    row.operator("bsgi.clear", text="", icon="X")
    layout.prop(settings, "show_error", toggle=True)
    if obj is not None and error_view.PROP_ERROR in obj:
        layout.label(text=f"{obj.name}: estimated error {100 * float(obj[error_view.PROP_ERROR]):.1f}%")
    row = layout.row(align=True)
    row.operator("bsgi.export_solution", text="Export", icon="EXPORT")
    row.operator("bsgi.import_solution", text="Import", icon="IMPORT")


class BSGI_PT_render(bpy.types.Panel):
    bl_label = "B-spline GI"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    def draw(self, context):
        draw_controls(self.layout, context.scene, context.object)


class BSGI_PT_sidebar(bpy.types.Panel):
    bl_label = "B-spline GI"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "B-spline GI"

    def draw(self, context):
        draw_controls(self.layout, context.scene, context.object)


class BSGI_PT_object(bpy.types.Panel):
    """Object properties: how the solver represents this object's radiance."""

    bl_label = "B-spline GI"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type in {"MESH", "SURFACE", "CURVE", "FONT", "META"}

    def draw(self, context):
        settings = context.object.bsgi
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "representation")
        col = layout.column(align=True)
        col.prop(settings, "spatial_coeffs")
        row = col.row()
        row.enabled = settings.representation != "DIFFUSE"
        row.prop(settings, "angular_coeffs")
        if context.object.type != "SURFACE":  # curves, texts and metaballs are solved as meshes
            layout.prop(settings, "mesh_surfaces")
            layout.prop(settings, "glass")


classes = (BSGI_PT_render, BSGI_PT_sidebar, BSGI_PT_object)

register, unregister = bpy.utils.register_classes_factory(classes)
