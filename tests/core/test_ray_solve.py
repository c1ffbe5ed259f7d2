"""The solve on Ray (bsgi.RayExecutor, issue 16): the gathers of each phase split over 2 local
workers give every coefficient the local solve gives; a cancel returns at once; a worker killed
mid-solve costs a retry, not the solve. Scenes pickle for the workers (bsgi.rebuildable)."""
import os
import pathlib
import pickle
import sys
import time

import numpy as np
import pytest

import bsgi
from bsgi import _core
from bsgi.rebuildable import SCENE_CALLS, SCENE_PROPERTIES

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install ray): the distributed solve is not tested")


def room():
    """A closed box lit by a ceiling lamp, with a rough metal plate (glossy 4D) and a coated
    block face (decomposed D + S) in it: several surfaces, light bouncing between them."""
    scene = bsgi.Scene()
    w = [0.7, 0.7, 0.7]
    quads = {
        "floor": [[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]],
        "ceiling": [[0, 0, 2], [0, 2, 2], [2, 2, 2], [2, 0, 2]],
        "left": [[0, 0, 0], [0, 2, 0], [0, 2, 2], [0, 0, 2]],
        "right": [[2, 0, 0], [2, 0, 2], [2, 2, 2], [2, 2, 0]],
        "back": [[0, 2, 0], [2, 2, 0], [2, 2, 2], [0, 2, 2]],
        "front": [[0, 0, 0], [0, 0, 2], [2, 0, 2], [2, 0, 0]],
    }
    for name, corners in quads.items():
        scene.add_bilinear_patch(name, np.array(corners, float), albedo=[0.8, 0.3, 0.3] if name == "left" else w,
                                 emission=[0, 0, 0])
    scene.add_bilinear_patch("lamp", np.array([[0.7, 0.7, 1.99], [0.7, 1.3, 1.99], [1.3, 1.3, 1.99], [1.3, 0.7, 1.99]]),
                             albedo=[0, 0, 0], emission=[8, 8, 8], receiver=False, occluder=False)
    plate = bsgi.BilinearPatch("plate", np.array([[0.3, 1.2, 0.4], [1.0, 1.2, 0.4], [1.0, 1.8, 0.6], [0.3, 1.8, 0.6]]))
    scene.add_surface(plate, albedo=[0.9, 0.9, 0.9], emission=[0, 0, 0],
                      bsdf=bsgi.GgxReflection(0.3, 0.3, np.array([0.9, 0.6, 0.3])))
    scene.add_triangle("block", np.array([[1.2, 0.3, 0.0], [1.8, 0.3, 0.0], [1.5, 0.3, 0.7]]), albedo=[0.5] * 3,
                       emission=[0, 0, 0], bsdf=bsgi.DiffuseGgx(np.array([0.5, 0.6, 0.5]), 0.4, 0.4, np.array([0.04] * 3)))
    return scene


def room_with_a_box():
    """The room with a block standing on its floor: the block's side faces are small and turned
    from the lamp, lit by the walls and the floor, so that with coeffs_from_size and a detail
    tolerance their finals are planned from their light after the bounces."""
    scene = room()
    x0, x1, y0, y1, h = 0.3, 0.7, 0.4, 0.8, 0.5
    faces = {"box top": [[x0, y0, h], [x1, y0, h], [x1, y1, h], [x0, y1, h]],
             "box -y": [[x0, y0, 0], [x1, y0, 0], [x1, y0, h], [x0, y0, h]],
             "box +y": [[x1, y1, 0], [x0, y1, 0], [x0, y1, h], [x1, y1, h]],
             "box -x": [[x0, y1, 0], [x0, y0, 0], [x0, y0, h], [x0, y1, h]],
             "box +x": [[x1, y0, 0], [x1, y1, 0], [x1, y1, h], [x1, y0, h]]}
    for name, corners in faces.items():
        scene.add_bilinear_patch(name, np.array(corners, float), albedo=[0.6] * 3, emission=[0, 0, 0])
    return scene


PLANNED_FROM_LIGHT = dict(coeffs_from_size=True, detail_tolerance=0.005, spatial_coeffs_min=3)


def settings(**kw):
    s = bsgi.SolverSettings()
    s.spatial_coeffs = 6
    s.hemisphere_nodes_theta, s.hemisphere_nodes_phi = 6, 12
    s.angular_coeffs_max = 7
    s.bsdf_samples = 4
    s.max_bounces, s.tolerance = 3, 0  # all three bounces
    s.final_gather, s.final_spatial_factor = True, 1
    s.threads = 1
    for k, v in kw.items():
        setattr(s, k, v)
    return s


def splines(solution):
    for surface in solution.surfaces:
        if surface is None:
            continue
        for part in (surface.upper, surface.lower, surface.diffuse, surface.lower_diffuse):
            if part is not None:
                yield part.coefficients


def assert_same_coefficients(a, b):
    pairs = list(zip(splines(a), splines(b)))
    assert len(pairs) == len(list(splines(a))) == len(list(splines(b))) > 8
    for x, y in pairs:
        assert x.shape == y.shape
        np.testing.assert_allclose(y, x, rtol=1e-12, atol=0)
    assert a.stats["bounces"] == b.stats["bounces"] == 3
    assert a.stats["rays"] == b.stats["rays"]
    # The error estimate, its passes gathered in groups too: the same per surface, and its parts.
    assert a.stats["estimate_rays"] == b.stats["estimate_rays"]
    estimated = [(r["estimated_error"], *r["error_parts"].values()) for r in a.reports if r is not None]
    assert np.isfinite(estimated).any()
    np.testing.assert_allclose([(r["estimated_error"], *r["error_parts"].values()) for r in b.reports if r is not None], estimated,
                               rtol=1e-12, atol=0)


def test_scene_pickles_to_the_same_solve():
    scene = room()
    again = pickle.loads(pickle.dumps(scene))
    assert type(again) is bsgi.Scene and len(again) == len(scene)
    s = settings(max_bounces=1, final_gather=False)
    for x, y in zip(splines(bsgi.solve(scene, s)), splines(bsgi.solve(again, s))):
        np.testing.assert_array_equal(x, y)


def test_every_scene_member_that_changes_it_is_kept():
    # A new mutating member of the compiled Scene must be kept by bsgi.Scene, or workers would
    # solve another scene: every public member is either kept or known to only read.
    readers = {"is_thin_glass", "distant_lights", "surface", "name", "area", "evaluate_surface", "spatial_coeffs", "integration_factor",
               "MAX_INTEGRATION_FACTOR"}  # (a constant)
    public = {n for n in dir(_core.Scene) if not n.startswith("_")}
    assert public == readers | set(SCENE_CALLS) | set(SCENE_PROPERTIES)


@pytest.mark.slow  # starts Ray workers (kept out of test-fast and of the sanitizer run: Ray is not built for it)
# (The coarse correction's bounces are at most the solve's three: 8 takes three.)
@pytest.mark.parametrize("final_passes, late_bounces_after, corrections", [(1, 0, 0), (2, 1, 0), (4, 1, 0), (4, 1, 2), (2, 1, 8)])
def test_ray_solve_equals_the_local_solve(ray_cluster, final_passes, late_bounces_after, corrections):
    scene, s = room(), settings(final_passes=final_passes, final_spatial_factor=2, late_bounces_after=late_bounces_after,
                                final_correction_bounces=corrections)
    local = bsgi.solve(scene, s)
    kinds = {r["representation"].split(",")[0] for r in local.reports}
    assert {"diffuse 2D", "glossy 4D", "decomposed 2D + 4D (38)"} <= kinds
    executor = bsgi.RayExecutor(workers=2)
    assert_same_coefficients(local, bsgi.solve(scene, s, executor=executor))
    # Each phase sent once: the direct light (nothing), three bounces (L), the final gather (Le),
    # a regather (the finals' Le) each further pass (after the coarse correction's late bounces),
    # and the error estimate's two passes (the finals' and the coarse Le, then also the first
    # pass's records).
    taken = min(corrections, s.max_bounces)
    assert len(executor.bytes_sent) == 6 + final_passes + taken and executor.bytes_sent[0] == 0
    assert executor.bytes_sent[-1] > executor.bytes_sent[-2] > executor.bytes_sent[1]
    # Each phase's times (bench/ray_phases.py prints them): in order, a group's seconds each.
    bounces = ["bounce", "late bounce", "late bounce"] if late_bounces_after else ["bounce"] * 3
    assert [p[0] for p in executor.phase_times] == ["probing sides", "direct", *bounces, "final", *["late bounce"] * taken,
                                                    *["regather"] * (final_passes - 1), "estimate checks", "estimate input"]
    assert all(began < ended and len(seconds) >= 2 for _, began, ended, seconds in executor.phase_times), executor.phase_times
    # The sides probe, in two parts on the workers, sends a bit for each cell of each side of
    # each surface (36 a side) each round of settling, and once more for the parts' sides.
    assert executor.probe_rounds >= 1
    assert executor.probe_bytes == (executor.probe_rounds + 1) * -(-2 * 36 * len(scene) // 8)


@pytest.mark.parametrize("late_bounces_after,unpacked", [(0, False), (2, False), (2, True)])
def test_steps_gathered_in_groups_equal_the_solve_with_a_regather(late_bounces_after, unpacked):
    # What a worker does, here: another SolveSteps of the scene gathers each phase in two groups.
    # `unpacked`: the second group reads the input the first unpacked (given zeros in its place,
    # which would be unpacked otherwise; the estimate's input pass reads its scales and records).
    scene, s = room(), settings(final_passes=2, final_spatial_factor=2, late_bounces_after=late_bounces_after)
    local = bsgi.solve(scene, s)
    worker = bsgi.SolveSteps(scene, s, bsgi.Progress())
    phases, records = [], [None]

    def runner(phase, coefficients, nodes):
        phases.append(phase)
        half = len(nodes) // 2
        second = np.zeros_like(coefficients) if unpacked and phase != "estimate input" else coefficients
        if phase == "estimate input":
            # It ends with the count of the checks pass's records, which must be what the finals' checks hold.
            assert coefficients[-1] == records[0]
            wrong = np.array(coefficients)
            wrong[-1] -= 1
            with pytest.raises(ValueError, match=r"the error estimate's checks have \d+ record values, given \d+"):
                worker.gather(phase, 0, half, wrong, bsgi.Progress())
        parts = [worker.gather(phase, 0, half, coefficients, bsgi.Progress()),
                 worker.gather(phase, half, len(nodes), second, bsgi.Progress(), unpacked=unpacked)]
        out = np.concatenate([p[0] for p in parts])
        if phase == "estimate checks":
            # A receiver's record: its count of checks (`nodes` here), then 11 fields a check.
            assert len(out) == sum(1 + 11 * c for c in nodes)
            records[0] = len(out)
        return out, sum(p[1] for p in parts)

    steps = bsgi.SolveSteps(scene, s, bsgi.Progress())
    assert_same_coefficients(local, steps.solve(bsgi.Progress(), runner))
    bounces = ["bounce", "bounce", "late bounce"] if late_bounces_after else ["bounce"] * 3
    assert phases == ["direct", *bounces, "final", "regather", "estimate checks", "estimate input"]
    with pytest.raises(ValueError, match="one final pass, no regather"):
        bsgi.SolveSteps(scene, settings(), bsgi.Progress()).gather("regather", 0, 1, np.zeros(0), bsgi.Progress())


def test_finals_planned_from_the_coarse_light_on_fresh_workers():
    # With a detail tolerance the finals' coefficients follow the light after the bounces; a
    # worker that starts at any later phase (a retry on a new process) plans the same finals
    # from the coarse light its phase reads.
    scene, s = room_with_a_box(), settings(final_passes=2, final_spatial_factor=2, **PLANNED_FROM_LIGHT)
    local = bsgi.solve(scene, s)
    raised = [r["name"] for r in local.reports if r and "its light after the bounces asked for more" in r["reason"]]
    assert raised and all(name.startswith("box") for name in raised)
    phases = []

    def runner(phase, coefficients, nodes):
        phases.append(phase)
        worker = bsgi.SolveSteps(scene, s, bsgi.Progress())
        part, rays = worker.gather(phase, 0, len(nodes), coefficients, bsgi.Progress())
        return part, rays

    assert_same_coefficients(local, bsgi.SolveSteps(scene, s, bsgi.Progress()).solve(bsgi.Progress(), runner))
    assert phases == ["direct", "bounce", "bounce", "bounce", "final", "regather", "estimate checks", "estimate input"]


@pytest.mark.slow  # starts Ray workers (kept out of test-fast and of the sanitizer run: Ray is not built for it)
def test_ray_solve_with_finals_planned_from_the_light_equals_the_local_solve(ray_cluster):
    scene, s = room_with_a_box(), settings(final_spatial_factor=2, **PLANNED_FROM_LIGHT)
    assert_same_coefficients(bsgi.solve(scene, s), bsgi.solve(scene, s, executor=bsgi.RayExecutor(workers=2)))


@pytest.mark.slow  # starts Ray workers (kept out of test-fast and of the sanitizer run: Ray is not built for it)
def test_ray_solve_with_form_factors_equals_the_local_solve(ray_cluster):
    scene, s = room(), settings(form_factors=True, final_gather=False)
    local = bsgi.solve(scene, s)
    assert local.stats["transport_terms"] > 0
    assert_same_coefficients(local, bsgi.solve(scene, s, executor=bsgi.RayExecutor(workers=2)))


@pytest.mark.slow  # starts Ray workers (kept out of test-fast and of the sanitizer run: Ray is not built for it)
def test_ray_solve_of_a_bumped_floor_and_a_green_pane_equals_the_local_solve(ray_cluster):
    # The floor under a normal map (4D over its bumped normal) and a tinted pane hung in the room:
    # the workers replay both, and the solution's floor keeps its map.
    scene = room()
    a = np.radians(30) * np.sin(2 * np.pi * (np.arange(8) + 0.5) / 8)
    scene.set_normal_texture(0, np.tile(np.stack([np.sin(a), np.zeros_like(a), np.cos(a)], -1), (2, 1, 1)).astype(np.float32))
    scene.add_surface(bsgi.BilinearPatch("pane", np.array([[1.2, 1.0, 0.2], [1.8, 1.0, 0.2], [1.8, 1.0, 0.8], [1.2, 1.0, 0.8]])),
                      albedo=[0] * 3, emission=[0] * 3, thin_glass=1.5, transmission_tint=[0.6, 1.0, 0.7])
    s = settings()
    local = bsgi.solve(scene, s)
    assert local.reports[0]["representation"].startswith("bumped 4D")
    distributed = bsgi.solve(scene, s, executor=bsgi.RayExecutor(workers=2))
    assert_same_coefficients(local, distributed)
    np.testing.assert_array_equal(distributed.surfaces[0].normals, local.surfaces[0].normals)


@pytest.mark.slow  # starts Ray workers (kept out of test-fast and of the sanitizer run: Ray is not built for it)
def test_cancelled_ray_solve_returns_within_a_second(ray_cluster):
    scene = room()
    s = settings(spatial_coeffs=10, max_bounces=20, hemisphere_nodes_theta=12, hemisphere_nodes_phi=24)
    cancel_at = []

    def on_progress(fraction, stage):
        if stage.startswith("indirect bounce") and not cancel_at:
            cancel_at.append(time.monotonic())
        return not cancel_at

    with pytest.raises(bsgi.SolveCancelled):
        bsgi.solve(scene, s, on_progress=on_progress, executor=bsgi.RayExecutor(workers=2), poll_seconds=0.02)
    assert cancel_at and time.monotonic() - cancel_at[0] < 1.0


@pytest.mark.slow  # starts Ray workers (kept out of test-fast and of the sanitizer run: Ray is not built for it)
def test_worker_killed_mid_solve_is_retried(ray_cluster):
    scene, s = room(), settings()
    local = bsgi.solve(scene, s)
    executor = bsgi.RayExecutor(workers=2)
    killed, pids = [], []

    def pid_of_worker_0():
        return ray.get(executor.actors[0].__ray_call__.remote(lambda worker: os.getpid()))

    def on_progress(fraction, stage):
        # Kill a worker while the first bounce's groups are being gathered: Ray restarts it (the
        # scene rebuilt from the object store) and gathers its group again.
        # (Stages are polled: a short one may pass unseen, so any stage before and after will do.)
        if not pids and not killed and executor.actors:
            pids.append(pid_of_worker_0())
        if stage.startswith("indirect bounce") and not killed and pids:
            ray.kill(executor.actors[0], no_restart=False)
            killed.append(stage)
        elif killed and stage != killed[0] and len(pids) == 1:
            pids.append(pid_of_worker_0())

    solution = bsgi.solve(scene, s, on_progress=on_progress, executor=executor, poll_seconds=0.01)
    assert killed and len(pids) == 2 and pids[0] != pids[1]  # a new process took over
    assert_same_coefficients(local, solution)


@pytest.mark.slow  # starts Ray workers (kept out of test-fast and of the sanitizer run: Ray is not built for it)
def test_worker_lost_for_good_leaves_its_groups_to_the_others(ray_cluster):
    scene, s = room(), settings()
    local = bsgi.solve(scene, s)
    executor = bsgi.RayExecutor(workers=2, max_retries=0)  # Ray does not restart it
    killed = []

    def on_progress(fraction, stage):
        # Any bounce: stages are polled, and the first bounce may pass unseen (it failed once so).
        if stage.startswith("indirect bounce") and not killed and executor.actors:
            ray.kill(executor.actors[0])
            killed.append(stage)

    solution = bsgi.solve(scene, s, on_progress=on_progress, executor=executor, poll_seconds=0.01)
    assert killed and executor.lost == {0}
    assert_same_coefficients(local, solution)


@pytest.mark.slow  # starts Ray workers (kept out of test-fast and of the sanitizer run: Ray is not built for it)
@pytest.mark.parametrize("retries", [3, 0])
def test_worker_killed_mid_probe_costs_its_part_a_retry(ray_cluster, monkeypatch, retries):
    # Worker 0 killed as the sides probe's first round of settling starts: Ray restarts it (its
    # part built afresh there, from the cells lit so far) or, with no retries left, its part goes
    # to the other worker; either way the sides are the one probe's.
    import bsgi.ray_executor as ray_executor
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "bench"))
    import interior_core

    scene, s = interior_core.build_scene(30)[0], settings()
    executor = bsgi.RayExecutor(workers=2, max_retries=retries)
    killed = []
    sides_of_parts = ray_executor.sides_of_parts

    def killing(surfaces, parts, each_part):
        def each_part_killing(method, lit):
            if method == "probe" and lit is not None and not killed:
                ray.kill(executor.actors[0], no_restart=retries == 0)
                killed.append(method)
            return each_part(method, lit)
        return sides_of_parts(surfaces, parts, each_part_killing)

    monkeypatch.setattr(ray_executor, "sides_of_parts", killing)
    sides = executor.probe_sides(scene, s, bsgi.Progress())
    one, _ = bsgi.probe_sides(scene, s)
    assert killed and executor.lost == (set() if retries else {0})
    assert [(a[0], a[1], a[4]) for a in sides] == [(b[0], b[1], b[4]) for b in one]


def test_steps_gathered_in_groups_equal_the_solve_without_a_final_gather():
    # Without a final gather the estimate checks the coarse splines, in one pass (no input read).
    scene, s = room(), settings(final_gather=False)
    local = bsgi.solve(scene, s)
    worker = bsgi.SolveSteps(scene, s, bsgi.Progress())
    phases = []

    def runner(phase, coefficients, nodes):
        phases.append(phase)
        parts = [worker.gather(phase, b, e, coefficients, bsgi.Progress()) for b, e in ((0, 3), (3, len(nodes)))]
        return np.concatenate([p[0] for p in parts]), sum(p[1] for p in parts)

    assert_same_coefficients(local, bsgi.SolveSteps(scene, s, bsgi.Progress()).solve(bsgi.Progress(), runner))
    assert phases == ["direct", "bounce", "bounce", "bounce", "estimate checks"]


def test_receiver_groups_balance_the_measured_cost():
    from bsgi.ray_executor import receiver_groups

    # Equal costs: equal nodes a group; every receiver in exactly one group, in order.
    assert receiver_groups([10] * 8, 4) == [(0, 2, 20), (2, 4, 20), (4, 6, 20), (6, 8, 20)]
    assert receiver_groups([], 3) == [] and receiver_groups([5], 4) == [(0, 1, 5)]
    # Two glossy receivers whose nodes cost ten times a diffuse one's: each in a group of its
    # own cost, where equal nodes would put both in the last group.
    nodes, cost = [4] * 10, [1] * 8 + [10] * 2
    assert receiver_groups(nodes, 2) == [(0, 5, 20), (5, 10, 20)]
    groups = receiver_groups(nodes, 3, cost)
    assert [(b, e) for b, e, _ in groups] == [(0, 8), (8, 9), (9, 10)]


def test_guided_groups_fall_in_cost_and_cover_every_receiver_once():
    from bsgi.ray_executor import guided_groups

    # 100 equal receivers, 2 workers: each group a quarter of what is left, down to 1/32 of the
    # whole, so the phase ends on groups of 4 receivers (a worker waits at most that long).
    groups = guided_groups([10] * 100, 2)
    assert [e - b for b, e, _ in groups] == [25, 19, 14, 11, 8, 6, 5, 4, 4, 4]
    assert [b for b, _, _ in groups] == [0] + [e for _, e, _ in groups[:-1]] and groups[-1][1] == 100
    assert all(n == 10 * (e - b) for b, e, n in groups)
    # Measured costs: the dear glossy receivers (ten times a diffuse node) get groups of their own.
    assert [(b, e) for b, e, _ in guided_groups([4] * 10, 2, [1] * 8 + [10] * 2)] == [(0, 7), (7, 9), (9, 10)]
    assert guided_groups([], 2) == [] and guided_groups([0, 0, 0], 2) == [(0, 3, 0)]  # all settled: one group
    # A phase whose cost is mostly its last receiver's still goes to both workers (it was one
    # group, and the Ray solve's phase times showed a single group under load).
    assert [(b, e) for b, e, _ in guided_groups([1] * 5, 2, [1, 1, 1, 1, 100])] == [(0, 4), (4, 5)]
    assert [(b, e) for b, e, _ in guided_groups([1, 1, 1, 0], 2, [1, 1, 100, 1])] == [(0, 2), (2, 3), (3, 4)]
    assert guided_groups([1, 1], 1, [1, 100]) == [(0, 2, 2)]  # one worker: one group is right


def test_costs_learned_from_a_phase_rebalance_the_next():
    executor = bsgi.RayExecutor(workers=2)
    nodes = [4] * 10
    executor.cost_per_node = np.ones(10)
    # Measured: the second half of the receivers took five times the first half's seconds.
    executor.learn_costs([(0, 5, 1.0), (5, 10, 5.0)], nodes)
    np.testing.assert_allclose(executor.cost_per_node, [0.05] * 5 + [0.25] * 5)
    groups = bsgi.ray_executor.receiver_groups(nodes, 2, executor.cost_per_node)
    assert groups[0][:2] == (0, 7)  # 5 cheap and 2 dear receivers (1 + 2 s) against 3 dear ones (3 s)
    # A receiver that did not gather (settled, 0 nodes) keeps its cost on the phase's scale.
    executor.cost_per_node = np.ones(4)
    executor.learn_costs([(0, 4, 6.0)], [2, 2, 2, 0])
    np.testing.assert_allclose(executor.cost_per_node, [1.0, 1.0, 1.0, 1.0])
    executor.learn_costs([(0, 2, 4.0), (2, 4, 8.0)], [2, 2, 2, 0])  # predicted 4 s and 2 s: the phase 2x dearer
    np.testing.assert_allclose(executor.cost_per_node, [1.0, 1.0, 4.0, 2.0])


def test_solve_steps_check_what_they_are_given():
    scene, s = room(), settings(max_bounces=1, final_gather=False)
    steps = bsgi.SolveSteps(scene, s, bsgi.Progress())
    assert len(steps.sides) == len(scene)
    with pytest.raises(ValueError, match="sides of 0 surfaces given for a scene of 9"):
        bsgi.SolveSteps(scene, s, bsgi.Progress(), [])
    with pytest.raises(ValueError, match="coefficients given for receivers"):
        steps.gather("bounce", 0, 1, np.zeros(5), bsgi.Progress())
    with pytest.raises(ValueError, match="phase must be"):
        steps.gather("indirect", 0, 1, np.zeros(0), bsgi.Progress())
    # A regather reads the finals' Le and the coarse Le it corrects, both whole.
    two = bsgi.SolveSteps(scene, settings(max_bounces=1, final_passes=2), bsgi.Progress())
    with pytest.raises(ValueError, match=r"a regather reads the finals' Le \(\d+ coefficients\) and the coarse Le"):
        two.gather("regather", 0, 1, np.zeros(7), bsgi.Progress())
    # The estimate's passes read the estimated splines (and the coarse ones), the input pass
    # also the scales and the checks' records; without a final gather there is no input pass.
    with pytest.raises(ValueError, match="the error estimate's pass reads"):
        two.gather("estimate checks", 0, 1, np.zeros(7), bsgi.Progress())
    with pytest.raises(ValueError, match="has no input pass"):
        steps.gather("estimate input", 0, 1, np.zeros(0), bsgi.Progress())
    with pytest.raises(ValueError, match="ends with the count of its records"):
        two.gather("estimate input", 0, 1, np.full(7, 0.5), bsgi.Progress())
    with pytest.raises(ValueError, match="estimate no error"):
        bsgi.SolveSteps(scene, settings(estimate_error=False), bsgi.Progress()).gather("estimate checks", 0, 1, np.zeros(0),
                                                                                       bsgi.Progress())
    steps.solve(bsgi.Progress())
    with pytest.raises(RuntimeError, match="runs once"):
        steps.solve(bsgi.Progress())
