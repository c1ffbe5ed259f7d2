"""Headless Blender (the `bpy` module) with the add-on registered, a fresh scene per test."""
import os
import pathlib
import sys

import pytest

from subprocess_render import SHADER_CACHE, session_folder

# Blender writes its config under HOME and Mesa its shader cache: keep both out of the user's.
os.environ["HOME"] = session_folder("bsgi-home-")
os.environ.setdefault("MESA_SHADER_CACHE_DIR", SHADER_CACHE)
bpy = pytest.importorskip("bpy")

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "addon"))
import cli  # noqa: E402  (addon/cli.py: loads the add-on package as bsgi_addon)

addon = cli.load_addon()
addon.register()


@pytest.fixture
def context():
    """An empty scene with the add-on's settings."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context


def pytest_collection_modifyitems(items):
    for item in items:
        if "tests/blender" in str(item.fspath):
            item.add_marker(pytest.mark.blender)
