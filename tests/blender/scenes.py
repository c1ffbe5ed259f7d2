"""Small scenes built with bpy for the add-on tests."""
import pathlib
import runpy

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[2]


GENERATOR = runpy.run_path(str(ROOT / "example_blends" / "make_cornell_box.py"))


def cornell_box():
    """The example scene, built by its own generator script."""
    return GENERATOR["build"]()


def diffuse_material(name, rgb):
    return GENERATOR["diffuse_material"](name, rgb)


def add_quad(name, corners, material=None):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(c) for c in corners], [], [(0, 1, 2, 3)])
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_area_light(name="Lamp", location=(0, 0, 1), size=1.0, energy=50.0):
    light = bpy.data.lights.new(name, "AREA")
    light.shape = "SQUARE"
    light.size = size
    light.energy = energy
    obj = bpy.data.objects.new(name, light)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def floor_under_lamp():
    """A 2 x 2 floor with a grey material under a square area light."""
    mat = diffuse_material("Grey", (0.5, 0.5, 0.5))
    floor = add_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], mat)
    add_area_light()
    return floor


def metal_material(name, roughness, rgb=(0.9, 0.9, 0.9)):
    """A Principled BSDF metal: the add-on solves it as GGX reflection."""
    m = bpy.data.materials.new(name)
    if m.node_tree is None:  # Blender 4.x: materials start without nodes
        m.use_nodes = True
    node = next(n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    node.inputs["Metallic"].default_value = 1.0
    node.inputs["Roughness"].default_value = roughness
    node.inputs["Base Color"].default_value = (*rgb, 1)
    return m


def add_camera(location=(0.0, -5.0, 2.5), tilt_degrees=70.0):
    """The scene's camera, tilted about x from looking down."""
    import math

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = location
    camera.rotation_euler = (math.radians(tilt_degrees), 0.0, 0.0)
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera
    return camera
