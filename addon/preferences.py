"""The add-on's preferences: where solves run (this machine, or a Ray cluster)."""
import bpy


class BSGIPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    ray_address: bpy.props.StringProperty(
        name="Ray Cluster",
        description="Solve on a Ray cluster at this address ('auto': the cluster this machine joined with "
                    "`ray start`; 'ray://host:10001': a remote one). Empty: solve on this machine. Needs "
                    "`pip install ray` into Blender's Python, and bsgi on every node",
        default="",
    )

    def draw(self, context):
        self.layout.prop(self, "ray_address")


def ray_address(context) -> str:
    """The preferences' Ray address ('' where the add-on is not enabled as such, e.g. in the CLI)."""
    addon = context.preferences.addons.get(__package__)
    return addon.preferences.ray_address.strip() if addon and addon.preferences else ""


def register():
    bpy.utils.register_class(BSGIPreferences)


def unregister():
    bpy.utils.unregister_class(BSGIPreferences)
