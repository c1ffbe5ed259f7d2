"""The wheel's core binds to its bundled Embree 3 even where Embree 4's `rtc*` symbols are
already global, as in Blender's executable (simulated with LD_PRELOAD of bpy's libembree4).

Control: the same wheel before tools/isolate_embree.py renamed the symbols does bind to Embree 4
under the same preload, so the simulation is real and the renaming is what prevents it."""
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

from artifacts import blender_python, wheel

# Runs in the child: solve a small lit scene, report which Embree the core reached and which
# Embree/TBB libraries the process mapped.
PROBE = """
import json, sys
import numpy as np
import bsgi

info = {"bsgi": bsgi.__file__, "embree_version": bsgi._core.embree_version(),
        "embree_library": bsgi._core.embree_library()}
info["maps"] = sorted({line.split()[-1] for line in open("/proc/self/maps")
                       if "embree" in line or "libtbb" in line})
if "--solve" in sys.argv:
    scene = bsgi.Scene()
    floor = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    wall = np.array([[-1, 1, 0], [1, 1, 0], [1, 1, 2], [-1, 1, 2]], float)
    blocker = np.array([[-0.3, -0.3, 0.5], [0.3, -0.3, 0.5], [0.3, 0.3, 0.5], [-0.3, 0.3, 0.5]], float)
    lamp = np.array([[-0.5, -0.5, 1.5], [-0.5, 0.5, 1.5], [0.5, 0.5, 1.5], [0.5, -0.5, 1.5]], float)
    scene.add_bilinear_patch("floor", floor, albedo=[0.6] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("wall", wall, albedo=[0.5] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("blocker", blocker, albedo=[0.4] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("lamp", lamp, albedo=[0] * 3, emission=[5] * 3, receiver=False, occluder=False)
    settings = bsgi.SolverSettings()
    settings.spatial_coeffs = 8
    settings.max_bounces = 2
    solution = bsgi.solve(scene, settings)
    uv = np.stack(np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 9)), -1).reshape(-1, 2)
    info["radiance"] = [solution.radiance[i].evaluate(uv).tolist() for i in range(3)]
print("PROBE" + json.dumps(info))
"""


def bpy_embree4(python: pathlib.Path) -> pathlib.Path:
    """Blender's own Embree 4, shipped inside that interpreter's bpy module (found without importing bpy)."""
    where = subprocess.run([str(python), "-c", "import importlib.util; "
                            "print(importlib.util.find_spec('bpy').submodule_search_locations[0])"],
                           capture_output=True, text=True, check=True).stdout.strip()
    found = sorted(pathlib.Path(where, "lib").glob("libembree4.so*"))
    assert found, f"no libembree4 in {where}/lib"
    return found[0]


@pytest.fixture(scope="module", params=["311", "313"])
def installed(request, tmp_path_factory):
    """For one Python version: its interpreter with bpy, and both wheels pip-installed into folders of their own."""
    tag = request.param
    python, _ = blender_python(tag)
    folders = {}
    for isolated in (True, False):
        target = tmp_path_factory.mktemp(f"cp{tag}-" + ("isolated" if isolated else "control"))
        subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", "--target", str(target),
                        str(wheel(tag, isolated))], check=True)
        folders[isolated] = target
    return python, folders


def probe(python: pathlib.Path, target: pathlib.Path, preload: pathlib.Path | None, solve: bool) -> dict:
    env = dict(os.environ, PYTHONPATH=str(target))  # ahead of the venv's own development bsgi
    env.pop("LD_PRELOAD", None)
    if preload:
        env["LD_PRELOAD"] = str(preload)
    proc = subprocess.run([str(python), "-c", PROBE] + (["--solve"] if solve else []), env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"exit status {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    (line,) = [x for x in proc.stdout.splitlines() if x.startswith("PROBE")]
    info = json.loads(line[len("PROBE"):])
    assert pathlib.Path(info["bsgi"]).is_relative_to(target), info["bsgi"]
    return info


def bundled(info: dict, target: pathlib.Path) -> list[str]:
    return [m for m in info["maps"] if "libembree3" in m and pathlib.Path(m).is_relative_to(target / "bsgi.libs")]


@pytest.mark.slow
def test_preloaded_embree4_does_not_capture_the_core(installed):
    python, folders = installed
    target, embree4 = folders[True], bpy_embree4(python)
    alone = probe(python, target, None, solve=True)
    with_blender = probe(python, target, embree4, solve=True)
    print(f"{python}: without preload: Embree {alone['embree_version']} from {alone['embree_library']}")
    print(f"with {embree4.name} preloaded: Embree {with_blender['embree_version']} from "
          f"{with_blender['embree_library']}; mapped {with_blender['maps']}")
    # The preload took effect: Blender's Embree 4 is in the process ...
    assert any(pathlib.Path(m).name.startswith("libembree4") for m in with_blender["maps"]), with_blender["maps"]
    # ... and the core still runs the bundled Embree 3, which the process maps.
    for info in (alone, with_blender):
        assert info["embree_version"].startswith("3."), info
        assert pathlib.Path(info["embree_library"]).resolve().parent == target / "bsgi.libs", info
        assert bundled(info, target), info["maps"]
    # Same rays, same answer: the solve (direct light with a shadowing blocker, two bounces).
    a, b = np.array(alone["radiance"]), np.array(with_blender["radiance"])
    assert a.min() >= 0 and a.max() > 0.1
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-12)


@pytest.mark.slow
def test_control_without_renaming_is_captured_by_embree4(installed):
    """Without the renaming the same preload hijacks the core: the test above is not vacuous."""
    python, folders = installed
    target, embree4 = folders[False], bpy_embree4(python)
    assert probe(python, target, None, solve=False)["embree_version"].startswith("3.")
    captured = probe(python, target, embree4, solve=False)
    assert captured["embree_version"].startswith("4."), captured
    assert pathlib.Path(captured["embree_library"]).name.startswith("libembree4"), captured
