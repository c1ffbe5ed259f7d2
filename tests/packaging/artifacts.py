"""Where `make extension` / `make venv313` put what the packaging tests use.

The tests fail (not skip) when an artifact is missing: `make test` builds them all first. On a
machine without Python 3.13 (a stock Debian 12) `make test` skips the 3.13 packaging steps and
sets BSGI_SKIP_PY313=1: the tests of the 3.13 artifacts are then skipped, saying why."""
from __future__ import annotations

import os
import pathlib
import sys
import tomllib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
VERSION = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
WHEELS = ROOT / "build" / "wheels"

# Shared test helpers living beside the tests that use them first.
for folder in ("blender", "core"):
    if str(ROOT / "tests" / folder) not in sys.path:
        sys.path.insert(0, str(ROOT / "tests" / folder))

# Python tag -> (interpreter with the bpy module, the bpy version `make test` installs there).
BLENDER_PYTHONS = {
    "311": (pathlib.Path(sys.executable), "5.0.1"),
    "313": (pathlib.Path(os.environ.get("BSGI_VENV313", ROOT / ".venv313")) / "bin" / "python", "5.2.3"),
}


def _skip_if_no_313(tag: str) -> None:
    if "313" in tag and os.environ.get("BSGI_SKIP_PY313") == "1":
        pytest.skip("no Python 3.13 on this machine: the extension for Blender 5.1+ is not built or tested")


def _existing(path: pathlib.Path, how: str) -> pathlib.Path:
    if not path.exists():
        pytest.fail(f"{path} is missing: run `{how}` (make test does)")
    return path


def extension_zip(tag: str) -> pathlib.Path:
    _skip_if_no_313(tag)
    return _existing(ROOT / "dist" / f"bsgi-{VERSION}-linux-x64-py{tag}.zip", "make extension")


def blender_python(tag: str) -> tuple[pathlib.Path, str]:
    _skip_if_no_313(tag)
    python, bpy_version = BLENDER_PYTHONS[tag]
    return _existing(python, "make venv313"), bpy_version


def wheel(tag: str, isolated: bool = True) -> pathlib.Path:
    """The distributed wheel, or (isolated=False) the same wheel before its Embree symbols were renamed."""
    _skip_if_no_313(tag)
    folder = WHEELS if isolated else WHEELS / "repaired"
    found = sorted(folder.glob(f"bsgi-{VERSION}-cp{tag}-cp{tag}-*.whl"))
    if len(found) != 1:
        pytest.fail(f"expected one cp{tag} wheel in {folder}, found {found}: run `make extension`")
    return found[0]
