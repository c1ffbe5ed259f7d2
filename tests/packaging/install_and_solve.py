"""Child process (any Python with the `bpy` module): install a bsgi extension zip with Blender's
own extension machinery, enable it, solve a floor under an area light and report what happened
in `result`. argv[3] is the zip. Run through tests/blender/subprocess_render.run_bpy, which gives
the child its own HOME and BLENDER_USER_RESOURCES."""
import os
import pathlib
import sys

zip_path = sys.argv[3]
version = f"{sys.version_info.major}.{sys.version_info.minor}"
site_packages = pathlib.Path(os.environ["BLENDER_USER_RESOURCES"], "extensions", ".local", "lib",
                             f"python{version}", "site-packages")
# Blender puts the extensions' site-packages ahead of the interpreter's if it exists at start-up
# (any Blender after a first extension with wheels). The test venv has a development bsgi of its
# own in site-packages: without this, the add-on would import that one instead of the zip's wheel.
site_packages.mkdir(parents=True, exist_ok=True)

import bpy  # noqa: E402

install = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
result = {
    "bpy": bpy.app.version_string.split()[0],
    "install": sorted(install),
    "enabled": "bl_ext.user_default.bsgi" in bpy.context.preferences.addons,
    "operator": hasattr(bpy.types, "BSGI_OT_solve"),
    "site_packages": str(site_packages),
}
if result["enabled"]:
    import bsgi

    result.update(bsgi_file=bsgi.__file__, embree_version=bsgi._core.embree_version(),
                  embree_library=bsgi._core.embree_library())

    # Not read_factory_settings: it would also reset the preferences and so disable the add-on.
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    grey = bpy.data.materials.new("Grey")
    if grey.node_tree is None:  # Blender 4.x; 5.x materials come with a node tree
        grey.use_nodes = True
    nodes = grey.node_tree.nodes
    for node in [n for n in nodes if n.type != "OUTPUT_MATERIAL"]:
        nodes.remove(node)
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")  # exactly Lambertian: albedo 0.5, no specular part
    diffuse.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
    output = next(n for n in nodes if n.type == "OUTPUT_MATERIAL")
    grey.node_tree.links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(grey)
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("Floor", mesh))
    lamp = bpy.data.lights.new("Lamp", "AREA")
    lamp.shape, lamp.size, lamp.energy = "SQUARE", 1.0, 50.0
    lamp_object = bpy.data.objects.new("Lamp", lamp)
    lamp_object.location = (0, 0, 1)
    bpy.context.scene.collection.objects.link(lamp_object)

    result["solve"] = sorted(bpy.ops.bsgi.solve())
    image = bpy.data.images.get("BSGI Floor")
    if image is not None:
        import numpy as np

        pixels = np.array(image.pixels[:], np.float32).reshape(-1, 4)[:, :3]
        result.update(image_size=list(image.size), finite=bool(np.isfinite(pixels).all()),
                      max=float(pixels.max()), nonzero=float((pixels > 0).mean()))
