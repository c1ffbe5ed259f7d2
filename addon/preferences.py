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
    ray_threads_per_worker: bpy.props.IntProperty(
        name="Threads per Worker",
        description="CPUs each Ray worker reserves and gathers on. 1: a single-threaded worker a CPU; a "
                    "machine's cores: one worker a machine, which shares one copy of the scene and is faster "
                    "(README, Solving on a Ray cluster)",
        default=1, min=1, soft_max=256,
    )

    def draw(self, context):
        self.layout.prop(self, "ray_address")
        row = self.layout.row()
        row.enabled = bool(self.ray_address.strip())
        row.prop(self, "ray_threads_per_worker")


def ray_cluster(context) -> tuple[str, int]:
    """The preferences' Ray address and threads per worker ('' and 1 where the add-on is not
    enabled as such, e.g. in the CLI)."""
    addon = context.preferences.addons.get(__package__)
    if not (addon and addon.preferences):
        return "", 1
    return addon.preferences.ray_address.strip(), addon.preferences.ray_threads_per_worker


def register():
    bpy.utils.register_class(BSGIPreferences)


def unregister():
    bpy.utils.unregister_class(BSGIPreferences)
