"""Scene settings of a solve, shown in the panels and read by the operators."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty

import bsgi


def _show_error_update(self, context):
    from . import error_view

    error_view.refresh(context.scene)


def _show_baked_update(self, context):
    from . import bake

    for obj in context.scene.objects:
        bake.show_baked(obj, self.show_baked)


# The core's presets (bsgi.SolverSettings.preset): each iterates the bounces on a coarse
# representation and refines it in a final gather; the README lists their measured time
# and error. CUSTOM solves with the individual settings below instead. The numbers are what a
# .blend stores: REFERENCE, added after CUSTOM, took the next one.
PRESETS = [
    ("DRAFT", "Draft", "Fastest: 8 spatial coefficients per direction, few integration nodes, 1% tolerance; "
     "blurry shadows and highlights, for checking the light set-up", "NONE", 0),
    ("PREVIEW", "Preview", "Balanced: 12 spatial coefficients per direction, the default integration nodes, "
     "0.3% tolerance; a few times slower than Draft", "NONE", 1),
    ("FINAL", "Final", "16 spatial coefficients with knots clustered at shadow edges and on contact lines, "
     "finer glossy lobes, 0.1% tolerance, then the surfaces whose estimated error is over 1% refined and solved "
     "again (Refinement As the Quality); many times slower than Preview and more memory", "NONE", 2),
    ("REFERENCE", "Reference", "Final's bounces, and in one solve a final gather with 4 times the coefficients "
     "per direction and twice the integration nodes everywhere; 5-8 times slower than Final's first solve, and "
     "for glossy surfaces much more memory", "NONE", 4),
    ("CUSTOM", "Custom", "The coefficients, degree, bounces, tolerance and nodes set below, without a final gather",
     "NONE", 3),
]

# Refinement driven by the error estimate (bsgi.refine): the quality's (Final refines, within a
# budget; bsgi.SolverSettings.preset says how), none, or the user's target and budgets.
REFINEMENTS = [
    ("QUALITY", "As the Quality", "Final refines the surfaces whose estimated error is over 1% and solves again, "
     "tracing at most 5 times the first solve's rays (the worst surfaces first): under 1% on diffuse scenes for "
     "3 to 5 times the time; the other qualities solve once", "NONE", 0),
    ("OFF", "Off", "One solve, whatever its estimated error", "NONE", 1),
    ("TO_ERROR", "To Error", "Refine to the error, passes and budget below", "NONE", 2),
]

# A Principled BSDF's glossy coat over its diffuse base (materials.py): solved as Cycles layers it
# (2D base + 4D coat) where its highlight is strong enough for the quality, else folded into the
# diffuse colour (2D); the thresholds and their measured errors are materials.COAT_THRESHOLDS'.
BUMPS = [
    ("SOLVED", "Solved", "Normal maps and bumps on diffuse surfaces are solved over the bumped normal, as Cycles "
     "shades them (a 4D spline on each such surface: at Preview about 100x a flat surface's coefficients and 5-7x "
     "its solve)", "NONE", 0),
    ("FLAT", "Flat", "Solve bumped surfaces with their own normals: 2D, fastest; the bumps' shading is lost (a "
     "bumped floor under a sun: 17% off per pixel)", "NONE", 1),
]

COATS = [
    ("QUALITY", "As the Quality", "Draft and Preview solve a Principled BSDF's glossy coat where its highlight "
     "reaches 5% of its base's light (the default material's: 20%) and fold weaker ones into the diffuse colour "
     "(up to about 3% off); Final and Reference from 1.5% (folded: under 1% off)", "NONE", 0),
    ("ALL", "Every Coat", "Solve every Principled coat, however rough (a 4D spline on each such surface)", "NONE", 1),
    ("FOLDED", "Folded", "Fold every coat into the diffuse colour: 2D only, fastest; highlights are lost (the default "
     "material under a lamp: 8% off)", "NONE", 2),
]

ADAPTIVE_COEFFICIENTS = [
    ("QUALITY", "As the Quality", "Preview gives each surface coefficients from its size and the detail of its light "
     "(tolerance 0.005); the other qualities give every surface the quality's", "NONE", 0),
    ("OFF", "Off", "Every surface the quality's coefficients per direction, whatever its size", "NONE", 1),
    ("TOLERANCE", "To Tolerance", "Coefficients from each surface's size and its light's detail, to the tolerance "
     "below", "NONE", 2),
]


class BSGISceneSettings(bpy.types.PropertyGroup):
    preset: EnumProperty(
        name="Quality", items=PRESETS, default="PREVIEW",
        description="Speed against accuracy of the solve")
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
    refinement: EnumProperty(
        name="Refinement", items=REFINEMENTS, default="QUALITY",
        description="Whether surfaces whose estimated error is high are refined and the scene solved again")
    refine_to_error: FloatProperty(
        name="Refine to Error", default=0.01, min=0.0, max=1.0, precision=3,
        description="With Refinement To Error: after the solve, surfaces whose estimated relative error is above "
        "this get more spatial coefficients (or, where the final gather's integration errs, more of its nodes) and "
        "the scene is solved again (each pass costs a solve), up to Refine Passes times, the budget or the memory "
        "budget; 0: off")
    refine_passes: IntProperty(
        name="Refine Passes", default=2, min=0, max=8,
        description="With Refinement To Error: at most this many solves after the first while surfaces are over "
        "Refine to Error")
    refine_cost: FloatProperty(
        name="Refine Budget", default=5.0, min=0.0, max=100.0, precision=1,
        description="With Refinement To Error: the solves after the first may trace at most this many times the "
        "first's rays; where refining every surface over Refine to Error would overrun it, those with the highest "
        "estimated errors are refined first. 0: no limit")
    bumps: EnumProperty(
        name="Bumps", items=BUMPS, default="SOLVED",
        description="Whether normal maps and bumps (a diffuse shader's Normal input) are solved, as Cycles shades "
        "them, or the surfaces solved flat")
    coats: EnumProperty(
        name="Glossy Coats", items=COATS, default="QUALITY",
        description="Which Principled BSDF coats (the highlight of a dielectric over its base colour) are solved "
        "view-dependent, as Cycles shows them, and which are folded into the diffuse colour")
    adaptive_coefficients: EnumProperty(
        name="Adaptive Coefficients", items=ADAPTIVE_COEFFICIENTS, default="QUALITY",
        description="Whether small or evenly lit surfaces get fewer spatial coefficients than the quality's "
        "(a furnished interior at Preview: 0.28x the time of the same coefficients everywhere, the same error "
        "over its area; the README's figures)")
    detail_tolerance: FloatProperty(
        name="Detail Tolerance", default=0.005, min=0.0, max=0.1, precision=3,
        description="With Adaptive Coefficients To Tolerance: each surface gets spatial coefficients from its size "
        "and the detail of its light, planned for the final gather from the light after the bounces, so that a "
        "quadratic spline's error stays under this fraction of the surface's brightest light; 0: from its size "
        "alone")
    chart_min_faces: IntProperty(
        name="Chart Above Faces", default=64, min=0, max=10**7,
        description="A mesh with at least this many faces (of one material) is solved as one UV chart: one "
        "radiance spline over its UV map (or a generated one; the mesh's own UV maps are not changed) instead of "
        "a spline per face. 0: always per face")
    texture_texels: IntProperty(
        name="Texture Texels", default=32, min=4, max=4096,
        description="Texels per face side (four times as many per UV chart side) at which Blender's evaluation of "
        "node-driven colours and emission (image and procedural textures, colour ramps, vertex colours) is baked for "
        "the solve and shown in the bake; cost grows with their square")
    world_map_width: IntProperty(
        name="World Map Width", default=512, min=8, max=8192,
        description="Pixels around the horizon of the image a textured world (HDRI, sky) is rendered into "
        "for the solve (half as many from pole to pole); a one-colour world needs none")
    show_baked: BoolProperty(
        name="Show Baked Radiance", default=True, update=_show_baked_update,
        description="Show the solved radiance, or the objects' own materials")
    show_error: BoolProperty(
        name="Show Estimated Error", default=False, update=_show_error_update,
        description="Colour each baked object by the solver's estimate of its relative error: green at 1% or "
        "less, yellow, red at 10% or more (grey: not estimated); off shows the baked radiance again")

    def solver_settings(self) -> bsgi.SolverSettings:
        """The preset's settings, or with CUSTOM the core's defaults with the individual settings."""
        s = self.preset_settings()
        if self.adaptive_coefficients == "OFF":
            s.coeffs_from_size, s.detail_tolerance = False, 0.0
        elif self.adaptive_coefficients == "TOLERANCE":
            s.coeffs_from_size, s.detail_tolerance = True, self.detail_tolerance
        if self.refinement == "OFF":
            s.refine_to_error = 0
        elif self.refinement == "TO_ERROR":
            s.refine_to_error, s.refine_passes, s.refine_cost = self.refine_to_error, self.refine_passes, self.refine_cost
        return s

    def preset_settings(self) -> bsgi.SolverSettings:
        if self.preset != "CUSTOM":
            return bsgi.SolverSettings.preset(self.preset.lower())
        s = bsgi.SolverSettings()
        s.spatial_coeffs = max(self.spatial_coeffs, self.spatial_degree + 1)
        s.spatial_degree = self.spatial_degree
        s.max_bounces = self.max_bounces
        s.tolerance = self.tolerance
        s.hemisphere_nodes_theta = self.hemisphere_nodes
        s.hemisphere_nodes_phi = 2 * self.hemisphere_nodes
        return s


def object_setting(obj, name: str):
    """One of an object's settings below, read from the original object without writing to it:
    reading obj.bsgi creates the object's settings in the .blend, and a solve (or a refused one)
    must leave the .blend unchanged. Objects the user never set read the defaults."""
    original = obj.original
    system = (original.bl_system_properties_get(do_create=False) if hasattr(original, "bl_system_properties_get")
              else original)  # Blender 4.x keeps add-on settings with the custom properties
    if system is None or "bsgi" not in system.keys():
        return BSGIObjectSettings.bl_rna.properties[name].default
    return getattr(original.bsgi, name)


class BSGIObjectSettings(bpy.types.PropertyGroup):
    """Per-object options of the object's surfaces (every face of a mesh, every spline of a NURBS
    surface); 0 and Automatic leave the choice to the solver."""

    representation: EnumProperty(
        name="Representation", default="AUTO",
        items=[("AUTO", "Automatic", "Diffuse (2D) for Lambertian materials, glossy (4D) for the others"),
               ("DIFFUSE", "Diffuse", "A 2D spline over the surface: radiance the same in every direction (cheap)"),
               ("GLOSSY", "Glossy", "A 4D spline over the surface and the hemisphere: view-dependent radiance "
                "(costs the angular coefficients squared times more)")],
        description="How the radiance leaving the object's surfaces is represented")
    spatial_coeffs: IntProperty(
        name="Spatial Coefficients", default=0, min=0, max=256,
        description="Coefficients per surface direction for this object (0: the scene's quality setting)")
    mesh_surfaces: EnumProperty(
        name="Mesh Surfaces", default="AUTO",
        items=[("AUTO", "Automatic", "One UV chart if the mesh has at least the scene's Chart Above Faces faces, "
                "else a surface per face"),
               ("FACES", "Per Face", "A surface and a spline per face (exact for few faces, costly for many)"),
               ("CHART", "UV Chart", "One surface over a UV map, one spline for the whole mesh (its UV map if it "
                "is a chart, else one generated on a copy); meshes of several materials stay per face")],
        description="How a mesh object's faces (a curve's, text's or metaball's as Blender evaluates them) become "
        "surfaces of the solve")
    angular_coeffs: IntProperty(
        name="Angular Coefficients", default=0, min=0, max=64,
        description="Coefficients per direction of the hemisphere disc of glossy surfaces (0: from the "
        "material's lobe width)")
    glass: EnumProperty(
        name="Glass", default="AUTO",
        items=[("AUTO", "Automatic", "Smooth glass (roughness below 0.1) on a single plane or a thin closed slab is a "
                "thin pane; other glass is solid"),
               ("THIN", "Thin Pane", "A window pane: light passes straight through it, attenuated by Fresnel "
                "reflection at its faces, and it reflects a little; no spline, not baked (cheap, sharp)"),
               ("SOLID", "Solid", "A rough dielectric with radiance splines for both hemispheres (costly; blurs "
                "light through smooth glass)")],
        description="How the object's glass (a transmitting material) is solved")


classes = (BSGISceneSettings, BSGIObjectSettings)


def register():
    for c in classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.bsgi = bpy.props.PointerProperty(type=BSGISceneSettings)
    bpy.types.Object.bsgi = bpy.props.PointerProperty(type=BSGIObjectSettings)


def unregister():
    del bpy.types.Object.bsgi
    del bpy.types.Scene.bsgi
    for c in reversed(classes):
        bpy.utils.unregister_class(c)
