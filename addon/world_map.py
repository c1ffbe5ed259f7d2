"""A world's node tree as Blender evaluates it (an Environment Texture, a Sky Texture, any tree):
rendered by Cycles through a panoramic camera into an equirectangular image in the layout of
bsgi.Scene.world_map (row 0 at the zenith, +X at the centre: Cycles' Environment Texture layout)."""
from __future__ import annotations

import math
import os
import tempfile

import bpy
import numpy as np

from .errors import ExportError

# An equirectangular camera turned so that its image is the Environment Texture's layout: the
# image's top towards +Z (the camera's local +Y turned up by X 90 degrees) and its centre towards
# +X (turned by Z -90 degrees); checked against Cycles' own directions in tests/blender/test_world_map.py.
CAMERA_ROTATION = (math.pi / 2, 0.0, -math.pi / 2)
SAMPLES = 16
# Pixels brighter than this many times the sky's mean (the mean of the map clipped at that level)
# hold a sun: rendered again with many samples, since a sun disc smaller than a pixel is found
# by few of a pixel's samples (the Sky Texture's sun, 512 pixels wide: 16 samples 20% off, 256
# samples 2%, 1024 samples 0.06%).
BRIGHT_FACTOR = 20.0
BRIGHT_SAMPLES = 4096
BRIGHT_BUDGET = 1_000_000  # samples of the second pass at most (its box of pixels x samples)


def light_path_nodes(tree, seen=None) -> list[str]:
    """Names of the Light Path nodes in a node tree and the groups it uses."""
    seen = set() if seen is None else seen
    if tree is None or tree.name in seen:
        return []
    seen.add(tree.name)
    names = []
    for node in tree.nodes:
        if node.type == "LIGHT_PATH":
            names.append(node.name)
        elif node.type == "GROUP":
            names += light_path_nodes(node.node_tree, seen)
    return names


def render_world(world, width: int, samples: int = SAMPLES) -> np.ndarray:
    """The world as Cycles shines it along each direction (its camera rays): a (width / 2, width, 3)
    float image, row 0 at the zenith; the box around its bright pixels (a sun) rendered again with
    many samples. A temporary scene links the world; everything made here is removed afterwards,
    and the world's camera visibility and sampling method are put back."""
    height = max(1, width // 2)
    images_before = set(bpy.data.images)
    scene = bpy.data.scenes.new("BSGI World Map")
    cam_data = bpy.data.cameras.new("BSGI World Map")
    camera = bpy.data.objects.new("BSGI World Map", cam_data)
    visible_to_camera, sampling = world.cycles_visibility.camera, world.cycles.sampling_method
    try:
        cam_data.type, cam_data.panorama_type = "PANO", "EQUIRECTANGULAR"
        camera.rotation_euler = CAMERA_ROTATION
        scene.collection.objects.link(camera)
        scene.camera = camera
        scene.world = world
        world.cycles_visibility.camera = True  # the map is what diffuse and glossy rays see
        world.cycles.sampling_method = "NONE"  # no importance map: camera rays alone see the world
        r = scene.render
        if not hasattr(scene, "cycles"):  # Cycles' settings are there when its add-on is enabled
            raise ExportError(f"world '{world.name}': a textured world is evaluated by a Cycles render, and Cycles "
                              "is not enabled (Preferences > Add-ons > Cycles)")
        r.engine = "CYCLES"
        r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
        r.film_transparent = False
        r.use_compositing = r.use_sequencer = False
        c = scene.cycles
        c.device = "CPU"
        c.use_adaptive_sampling = False
        c.use_denoising = False
        c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
        # A box filter one pixel wide: each pixel is the mean over its own rectangle of directions.
        c.pixel_filter_type, c.filter_width = "BOX", 1.0
        scene.view_settings.view_transform = "Standard"
        r.image_settings.file_format = "OPEN_EXR"
        r.image_settings.color_depth = "32"
        r.image_settings.color_mode = "RGB"
        with tempfile.TemporaryDirectory(prefix="bsgi-world-") as folder:
            r.filepath = os.path.join(folder, "world.exr")
            image = _render(scene, samples)
            box = _bright_box(image)
            if box is not None:
                (r0, r1), (c0, c1) = box
                more = int(min(BRIGHT_SAMPLES, BRIGHT_BUDGET / ((r1 - r0) * (c1 - c0))))
                if more > samples:
                    # Blender's border runs upwards from the bottom; a pixel of margin against rounding.
                    border = ((c0 - 1) / width, (c1 + 1) / width, 1 - (r1 + 1) / height, 1 - (r0 - 1) / height)
                    image[r0:r1, c0:c1] = _render(scene, more, border)[r0:r1, c0:c1]
    finally:
        world.cycles_visibility.camera, world.cycles.sampling_method = visible_to_camera, sampling
        bpy.data.objects.remove(camera)
        bpy.data.cameras.remove(cam_data)
        bpy.data.scenes.remove(scene)
        for made in set(bpy.data.images) - images_before:  # the Render Result, if the render made it
            bpy.data.images.remove(made)
    return image


def _render(scene, samples, border=None) -> np.ndarray:
    """One render of the world scene (only inside `border`: (min x, max x, min y, max y) as
    fractions, if given), read back as (height, width, 3) float, row 0 at the top."""
    r = scene.render
    scene.cycles.samples = samples
    r.use_border = border is not None
    if border is not None:
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = (min(max(b, 0.0), 1.0) for b in border)
        r.use_crop_to_border = False
    bpy.ops.render.render(write_still=True, scene=scene.name)
    image = bpy.data.images.load(r.filepath)
    try:
        width, height = image.size
        pixels = np.empty(width * height * image.channels, np.float32)
        image.pixels.foreach_get(pixels)
        channels = image.channels
    finally:
        bpy.data.images.remove(image)
    # Blender's rows run upwards from the bottom: the zenith row is its last.
    return pixels.reshape(height, width, channels)[::-1, :, :3].astype(np.float64)


def _bright_box(image):
    """((first row, end row), (first column, end column)) around the pixels brighter than
    BRIGHT_FACTOR times the sky's mean, with a margin of two pixels; None without any."""
    height, width, _ = image.shape
    edges = np.linspace(0.0, math.pi, height + 1)
    solid_angle = (np.cos(edges[:-1]) - np.cos(edges[1:]))[:, None] * np.ones((1, width))
    brightness = image.max(axis=2)
    level = np.inf
    for _ in range(20):  # the level: BRIGHT_FACTOR x the mean of the map clipped at the level
        new = BRIGHT_FACTOR * (np.minimum(brightness, level) * solid_angle).sum() / solid_angle.sum()
        settled = abs(new - level) <= 1e-3 * new
        level = new
        if settled:
            break
    rows, cols = np.nonzero(brightness > level)
    if not (level > 0) or len(rows) == 0:
        return None
    return ((max(rows.min() - 2, 0), min(rows.max() + 3, height)), (max(cols.min() - 2, 0), min(cols.max() + 3, width)))
