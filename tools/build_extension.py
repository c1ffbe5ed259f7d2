"""Zip the add-on as a Blender extension with the core wheel for one Python version.

    python tools/build_extension.py build/wheels/bsgi-0.1.0-cp311-...whl --out-dir dist
    -> dist/bsgi-0.1.0-linux-x64-py311.zip

The zip holds addon/'s files at its root (blender_manifest.toml, __init__.py, the modules) and
wheels/<the wheel>. The manifest is rewritten to list that wheel and to name the Blender versions
whose Python matches it, so Blender refuses the wrong zip with a clear message instead of failing
at `import bsgi`. (Blender's `extension build` would need a Blender executable; the format is
simple enough to write directly, and tests/packaging installs the result with Blender's own code.)
"""
from __future__ import annotations

import argparse
import pathlib
import re
import sys
import zipfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
ADDON = ROOT / "addon"

# Python of each Blender series: 4.2 LTS to 5.0 embed 3.11, 5.1 onwards 3.13.
# blender_version_max is exclusive.
BLENDER_RANGE = {"cp311": ("4.2.0", "5.1.0"), "cp313": ("5.1.0", None)}
PLATFORM = "linux-x64"
SKIP_DIRS = {"__pycache__", "tests", "wheels"}
SKIP_SUFFIXES = {".pyc", ".pyo", ".blend1"}


def manifest_for(text: str, wheel_name: str, blender_min: str, blender_max: str | None) -> str:
    def replace(pattern: str, new: str, text: str, flags=re.MULTILINE) -> str:
        text, count = re.subn(pattern, new, text, count=1, flags=flags)
        if count != 1:
            sys.exit(f"build_extension: blender_manifest.toml has no line matching {pattern!r}")
        return text

    text = replace(r"^wheels\s*=\s*\[.*?\]", f'wheels = ["./wheels/{wheel_name}"]', text, re.MULTILINE | re.DOTALL)
    text = replace(r'^blender_version_min\s*=\s*"[^"]*"', f'blender_version_min = "{blender_min}"', text)
    text = re.sub(r'^blender_version_max\s*=.*\n', "", text, flags=re.MULTILINE)
    if blender_max:
        text = replace(r'^(blender_version_min\s*=.*)$', rf'\1\nblender_version_max = "{blender_max}"', text)
    return text


def addon_files() -> list[pathlib.Path]:
    files = []
    for path in sorted(ADDON.rglob("*")):
        rel = path.relative_to(ADDON)
        if path.is_file() and not SKIP_DIRS.intersection(rel.parts[:-1]) and path.suffix not in SKIP_SUFFIXES \
                and path.name != "blender_manifest.toml":
            files.append(path)
    return files


def build(wheel: pathlib.Path, out_dir: pathlib.Path) -> pathlib.Path:
    # {distribution}-{version}-{python tag}-{abi tag}-{platform tag}.whl
    _, wheel_version, python_tag, _, platform_tag = wheel.name[:-4].split("-")
    if python_tag not in BLENDER_RANGE or not platform_tag.endswith("x86_64"):
        sys.exit(f"build_extension: no Blender target for {wheel.name}")
    manifest = (ADDON / "blender_manifest.toml").read_text()
    addon_version = re.search(r'^version\s*=\s*"([^"]+)"', manifest, re.MULTILINE).group(1)
    if addon_version != wheel_version:
        sys.exit(f"build_extension: add-on version {addon_version} differs from the wheel's {wheel_version}")
    manifest = manifest_for(manifest, wheel.name, *BLENDER_RANGE[python_tag])

    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"bsgi-{addon_version}-{PLATFORM}-py{python_tag[2:]}.zip"
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("blender_manifest.toml", manifest)
        for path in addon_files():
            z.write(path, path.relative_to(ADDON).as_posix())
        # Wheels are zips already: storing them saves time and nothing else.
        z.write(wheel, f"wheels/{wheel.name}", compress_type=zipfile.ZIP_STORED)
    print(f"build_extension: {target} ({target.stat().st_size / 1e6:.1f} MB)")
    return target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("wheels", type=pathlib.Path, nargs="+")
    parser.add_argument("--out-dir", type=pathlib.Path, default=ROOT / "dist")
    args = parser.parse_args()
    for wheel in args.wheels:
        build(wheel, args.out_dir)


if __name__ == "__main__":
    main()
