"""What the bake records and adds on the user's objects, which the export and the bake both read:
the user's own material per slot (a solve must read these, never the baked emission materials), the
splines' material indices as the user set them, and the name of the UV map the bake adds."""
from __future__ import annotations

import bpy

UV_NAME = "BSGI Radiance"
PROP_SLOTS = "bsgi_slot_links"  # the slots' links before the bake, to restore them
PROP_SPLINE_INDICES = "bsgi_spline_material_indices"  # their splines' material indices before the bake


def user_spline_material_index(obj, k: int) -> int:
    """Spline k's material index as the user set it (the bake of several splines changes it)."""
    indices = obj.get(PROP_SPLINE_INDICES)
    return int(indices[k]) if indices is not None and k < len(indices) else int(obj.data.splines[k].material_index)


def is_baked(obj) -> bool:
    return PROP_SLOTS in obj


def user_materials(obj) -> list:
    """The user's material in each slot, whether or not the bake is shown: a solve must read
    these, never the baked emission materials."""
    if not is_baked(obj):
        return [slot.material for slot in obj.material_slots]
    data = obj.data.materials
    return [(data[i] if link == "DATA" else bpy.data.materials.get(object_material))
            for i, (link, object_material) in enumerate(obj[PROP_SLOTS])]
