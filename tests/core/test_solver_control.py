"""Progress, cancellation, memory guard and settings validation of a solve (solver.cpp, progress.h)."""
import threading
import time

import numpy as np
import pytest

import bsgi


def grid_scene(n=12):
    """An n x n grid of floor tiles under a lamp, with a ceiling: enough work to watch."""
    scene = bsgi.Scene()
    for i in range(n):
        for j in range(n):
            x, y = i / n, j / n
            c = np.array([[x, y, 0], [x + 1 / n, y, 0], [x + 1 / n, y + 1 / n, 0], [x, y + 1 / n, 0]])
            scene.add_bilinear_patch(f"tile {i} {j}", c, albedo=[0.7] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("ceiling", np.array([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]], float),
                             albedo=[0.7] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("lamp", np.array([[0.4, 0.4, 0.9], [0.4, 0.6, 0.9], [0.6, 0.6, 0.9], [0.6, 0.4, 0.9]]),
                             albedo=[0] * 3, emission=[10] * 3, receiver=False, occluder=False)
    return scene


def test_progress_reports_stages_and_reaches_one():
    seen = []
    settings = bsgi.SolverSettings()
    settings.max_bounces = 2
    settings.tolerance = 0
    bsgi.solve(grid_scene(6), settings, on_progress=lambda f, stage: seen.append((f, stage)), poll_seconds=0.005)
    fractions = [f for f, _ in seen]
    assert fractions == sorted(fractions)
    assert seen[-1] == (1.0, "done")
    assert all(0 <= f <= 1 for f in fractions)


def test_cancel_stops_the_solve_and_raises():
    settings = bsgi.SolverSettings()
    settings.max_bounces = 50
    settings.tolerance = 0
    settings.hemisphere_nodes_theta = 32
    settings.hemisphere_nodes_phi = 64
    progress = bsgi.Progress()
    outcome = {}

    def run():
        try:
            bsgi.solve(grid_scene(), settings, progress)
            outcome["finished"] = True
        except bsgi.SolveCancelled:
            outcome["cancelled"] = time.perf_counter()

    worker = threading.Thread(target=run)
    worker.start()
    while progress.fraction == 0:
        time.sleep(0.01)
    time.sleep(0.2)
    cancel_time = time.perf_counter()
    progress.cancel()
    worker.join(timeout=30)
    assert not worker.is_alive()
    assert "cancelled" in outcome and "finished" not in outcome
    assert progress.cancelled
    print(f"\ncancellation returned after {outcome['cancelled'] - cancel_time:.3f} s")


def test_on_progress_returning_false_cancels():
    with pytest.raises(bsgi.SolveCancelled):
        bsgi.solve(grid_scene(6), bsgi.SolverSettings(), on_progress=lambda f, s: False, poll_seconds=0.001)


def test_memory_over_budget_is_refused_before_allocating():
    settings = bsgi.SolverSettings()
    settings.spatial_coeffs = 4096  # 4096^2 coefficients x 3 splines x 3 channels: about 1.2 GB a surface
    settings.memory_budget_mb = 512
    scene = grid_scene(2)
    needed = bsgi.estimate_solve_bytes(scene, settings)
    assert needed > 512 * 2**20
    with pytest.raises(RuntimeError, match=r"needs about \d+ MB, over the budget of 512 MB; the largest is surface 'tile"):
        bsgi.solve(scene, settings)


@pytest.mark.parametrize("name, value", [("spatial_coeffs", 2), ("spatial_degree", -1), ("epsilon", 0.6),
                                         ("hemisphere_nodes_theta", 0), ("emitter_coeffs", 1), ("tolerance", -1),
                                         ("final_passes", 5)])
def test_bad_settings_are_refused_by_name(name, value):
    settings = bsgi.SolverSettings()
    setattr(settings, name, value)
    with pytest.raises(ValueError, match=name.split("_")[0]):
        bsgi.solve(grid_scene(2), settings)


def test_scene_without_emitter_is_refused():
    scene = bsgi.Scene()
    scene.add_bilinear_patch("floor", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float),
                             albedo=[0.5] * 3, emission=[0] * 3)
    with pytest.raises(ValueError, match="no emitter"):
        bsgi.solve(scene)


@pytest.mark.parametrize("corners, problem", [
    ([[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 0, 0]], "zero area"),
    ([[0, 0, 0], [1, 0, 0], [1, np.nan, 0], [0, 1, 0]], "NaN"),
    ([[0, 0, 0], [1, 0, 0], [1, np.inf, 0], [0, 1, 0]], "infinite"),
])
def test_bad_geometry_is_refused_by_name(corners, problem):
    with pytest.raises(ValueError, match=f"surface 'bad'.*{problem}"):
        bsgi.Scene().add_bilinear_patch("bad", np.array(corners, float), albedo=[0.5] * 3, emission=[0] * 3)


@pytest.mark.parametrize("albedo, emission, problem", [([1.5, 0, 0], [0] * 3, "albedo"), ([0.5] * 3, [-1, 0, 0], "emission"),
                                                        ([np.nan, 0, 0], [0] * 3, "albedo")])
def test_bad_materials_are_refused_by_name(albedo, emission, problem):
    c = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    with pytest.raises(ValueError, match=f"surface 'm'.*{problem}"):
        bsgi.Scene().add_bilinear_patch("m", c, albedo=albedo, emission=emission)


def test_solve_uses_all_threads_and_releases_the_gil():
    # Another Python thread keeps running while the core solves.
    ticks = []
    stop = threading.Event()

    def ticker():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.005)

    t = threading.Thread(target=ticker)
    t.start()
    settings = bsgi.SolverSettings()
    settings.max_bounces = 3
    settings.tolerance = 0
    start = time.perf_counter()
    bsgi.solve(grid_scene(8), settings)
    elapsed = time.perf_counter() - start
    stop.set()
    t.join()
    during = [x for x in ticks if start <= x <= start + elapsed]
    assert elapsed < 0.05 or len(during) >= 3


def test_solution_surfaces_are_views_that_keep_the_solution_alive():
    # sol.surfaces[i] copied every surface's splines at each access (a loop over 2,000 points of
    # a rough glass took 5.4 s); now both lists are views into the solution, which they keep alive.
    sol = bsgi.solve(grid_scene(2), bsgi.SolverSettings.preset("draft"))
    first, again = sol.surfaces[0].upper.coefficients, sol.surfaces[0].upper.coefficients
    assert np.shares_memory(first, again)
    assert np.shares_memory(sol.radiance[0].coefficients, first)
    uv, up = np.array([[0.3, 0.6]]), np.array([[0.0, 0.0, 1.0]])
    expected = sol.surfaces[0].evaluate(uv, up)
    surface, spline = sol.surfaces[0], sol.radiance[0]
    del sol, first, again
    import gc

    gc.collect()
    np.testing.assert_array_equal(surface.evaluate(uv, up), expected)
    np.testing.assert_array_equal(spline.evaluate(uv), expected)
