"""The add-on's solve on Ray (pipeline.prepare with a Ray address, as `cli.py --ray-address`
and the add-on's preferences give it): the exported scene pickles to the workers and solves to
the coefficients of the local solve."""
import numpy as np
import pytest

import bsgi
import scenes
from bsgi_addon import pipeline

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install ray): the distributed solve is not tested")


@pytest.mark.slow  # starts Ray workers
def test_exported_scene_solves_on_ray_as_here(context, ray_cluster):
    scenes.cornell_box()
    bpy_scene = context.scene
    bpy_scene.bsgi.preset = "DRAFT"
    here = pipeline.prepare(context, ray_address="")
    assert here.executor is None
    job = pipeline.prepare(context, ray_address="auto")  # Ray is running in this process: it is used
    assert isinstance(job.executor, bsgi.RayExecutor)
    job.executor.workers = 2
    local, remote = pipeline.run(here), pipeline.run(job)
    assert remote.stats["bounces"] == local.stats["bounces"] >= 2
    compared = 0
    for a, b in zip(local.surfaces, remote.surfaces):
        assert (a is None) == (b is None)
        if a is None:
            continue
        for x, y in ((a.upper, b.upper), (a.lower, b.lower)):
            if x is not None:
                np.testing.assert_allclose(y.coefficients, x.coefficients, rtol=1e-12, atol=0)
                compared += 1
    assert compared >= 8


def test_threads_per_worker_reach_the_executor(context):
    """cli.py --ray-threads-per-worker and the preferences' Threads per Worker: one worker a machine
    of all its cores (README, Solving on a Ray cluster)."""
    scenes.floor_under_lamp()
    assert pipeline.prepare(context, ray_address="auto", ray_threads_per_worker=2).executor.threads_per_worker == 2
    # Not given: the preferences say (1 where the add-on is not enabled as an add-on, as here).
    assert pipeline.prepare(context, ray_address="auto").executor.threads_per_worker == 1
