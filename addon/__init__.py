"""B-spline GI: solve global illumination as tensor-product B-spline radiance (Stark et al.) and
bake it into the scene for Material Preview and renders.

Thin Blender layer over the `bsgi` core: export.py reads the scene (through geometry.py, materials.py
and lights.py), pipeline.py runs the solve, bake.py writes images and materials (user_materials.py is
its record of the user's materials, which the export reads too), operators.py/ui.py/properties.py
are the interface."""

from . import operators, preferences, properties, ui

_modules = (preferences, properties, operators, ui)


def register():
    for m in _modules:
        m.register()


def unregister():
    for m in reversed(_modules):
        m.unregister()
