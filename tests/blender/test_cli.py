"""The headless entries for users of the `bpy` module: `python -m addon` (addon/__main__.py, which
is addon/cli.py), run as a user runs them, in a child process, judged by exit status and output."""
import os
import subprocess
import sys
import tempfile

import bpy
import pytest

import scenes


def run_module(*args, timeout=300):
    """`python -m addon ARGS` from the repository root, with its own HOME (Blender's config)."""
    with tempfile.TemporaryDirectory(prefix="bsgi-cli-home-") as home:
        env = dict(os.environ, HOME=home, MESA_SHADER_CACHE_DIR=os.path.join(home, "mesa"))
        return subprocess.run([sys.executable, "-m", "addon", *map(str, args)], cwd=scenes.ROOT, env=env,
                              capture_output=True, text=True, timeout=timeout)


def test_python_m_entry_solves_saves_and_prints_progress(context, tmp_path):
    scenes.floor_under_lamp()
    source = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(source))
    out = tmp_path / "solved.blend"
    run = run_module(source, "--out", out, "--preset", "draft")
    assert run.returncode == 0, run.stdout + run.stderr
    lines = run.stdout.splitlines()
    assert any(line.startswith("bsgi: ") and "%" in line for line in lines), run.stdout  # progress as lines
    assert any(line.startswith("bsgi: solved 2 surfaces") for line in lines), run.stdout
    assert out.exists()
    # The saved scene holds the bake: the floor shows its baked material, the splines are stored.
    bpy.ops.wm.open_mainfile(filepath=str(out))
    floor = bpy.data.objects["Floor"]
    assert "bsgi_radiance" in floor and floor.material_slots[0].material.name == "BSGI Floor"


def test_python_m_entry_refines_to_an_error_target(context, tmp_path):
    floor = scenes.floor_under_lamp()
    scenes.add_quad("Wall", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], floor.data.materials[0])
    source = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(source))
    run = run_module(source, "--out", tmp_path / "solved.blend", "--preset", "draft", "--refine-to-error", "0.0001",
                     "--refine-passes", "1", "--refine-budget", "50")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "surfaces refined in 1 more solves" in run.stdout, run.stdout
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "solved.blend"))
    assert bpy.context.scene.bsgi.refine_cost == pytest.approx(50)  # what the solve ran with, saved
    assert bpy.context.scene.bsgi.refinement == "TO_ERROR"


def test_python_m_entry_refuses_a_budget_without_a_target(context, tmp_path):
    scenes.floor_under_lamp()
    source = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(source))
    run = run_module(source, "--out", tmp_path / "solved.blend", "--preset", "final", "--refine-budget", "2")
    assert run.returncode == 2, run.stdout + run.stderr
    assert "--refine-budget need --refine-to-error" in run.stderr, run.stderr
    assert not (tmp_path / "solved.blend").exists()


def test_python_m_entry_solves_with_adaptive_coefficients_and_flat_bumps(context, tmp_path):
    scenes.floor_under_lamp()
    source, out = tmp_path / "scene.blend", tmp_path / "solved.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(source))
    run = run_module(source, "--out", out, "--preset", "draft", "--adaptive-coefficients", "0.005", "--bumps", "flat")
    assert run.returncode == 0, run.stdout + run.stderr
    bpy.ops.wm.open_mainfile(filepath=str(out))
    saved = bpy.context.scene.bsgi  # what the solve ran with
    assert saved.adaptive_coefficients == "TOLERANCE" and saved.detail_tolerance == pytest.approx(0.005)
    assert saved.bumps == "FLAT"


def test_python_m_entry_refuses_workers_of_no_threads():
    run = run_module("--ray-address", "auto", "--ray-threads-per-worker", "0")
    assert run.returncode == 2 and "--ray-threads-per-worker must be at least 1" in run.stderr, run.stderr


def test_python_m_entry_fails_with_status_1_and_a_message_on_a_scene_without_emitters(context, tmp_path):
    scenes.add_quad("Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    source = tmp_path / "dark.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(source))
    out = tmp_path / "solved.blend"
    run = run_module(source, "--out", out)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "bsgi: error:" in run.stderr and "no emitter" in run.stderr, run.stderr
    assert "Traceback" not in run.stderr
    assert not out.exists()


def test_python_m_entry_fails_with_status_1_on_a_missing_file(tmp_path):
    run = run_module(tmp_path / "missing.blend")
    assert run.returncode == 1 and "cannot open" in run.stderr and "missing.blend" in run.stderr, run.stderr
