"""Writes the small HDRI the world-map tests use: a sky brightening towards the zenith, a dim
ground and a sun of 2 x 2 pixels thousands of times brighter than the sky (what makes an HDRI's
light hard to sample). Equirectangular, Cycles' Environment Texture layout (row 0 at the zenith,
azimuth atan2(y, x) = pi (1 - 2 u) at column centre u), linear float RGB.

    .venv/bin/python tests/blender/make_test_hdri.py --out sky.exr
"""
import argparse
import math

import numpy as np
import OpenEXR

WIDTH, HEIGHT = 256, 128
SUN_PIXEL = (32, 100)  # (row, column) of the sun's top-left pixel
SUN_RADIANCE = np.array([3000.0, 2800.0, 2500.0])


def sun_direction(rotation_z=0.0):
    """Unit direction towards the centre of the sun's 2 x 2 pixels, turned about Z by rotation_z
    (radians; a Mapping node's Z rotation of the texture lookup turns the sky by -rotation_z)."""
    r, c = SUN_PIXEL
    theta = math.pi * (r + 1) / HEIGHT
    phi = math.pi * (1 - 2 * (c + 1) / WIDTH) - rotation_z
    return np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])


def hdri_pixels():
    """(HEIGHT, WIDTH, 3) radiance, row 0 at the zenith."""
    theta = math.pi * (np.arange(HEIGHT) + 0.5) / HEIGHT
    cos_t = np.cos(theta)[:, None, None]
    sky = np.array([0.25, 0.4, 0.8]) * (0.3 + 0.7 * np.clip(cos_t, 0, 1))
    ground = np.array([0.2, 0.16, 0.12])
    image = np.where(cos_t > 0, sky, ground) * np.ones((HEIGHT, WIDTH, 3))
    r, c = SUN_PIXEL
    image[r:r + 2, c:c + 2] = SUN_RADIANCE
    return image


def write_hdri(path):
    rgb = hdri_pixels().astype(np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": np.ascontiguousarray(rgb)}).write(str(path))
    return path


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="test_hdri.exr")
    write_hdri(parser.parse_args().out)
