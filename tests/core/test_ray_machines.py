"""RayExecutor against the machines of a Ray cluster, simulated on this one
(ray.cluster_utils.Cluster: two machines of 1 CPU, apart from test_ray_solve.py's single local
Ray): workers that no machine can hold are refused with a message, not waited for; workers
spread over both machines give the local solve's coefficients."""
import pytest

import bsgi

ray = pytest.importorskip("ray", reason="Ray is not installed (pip install ray): the distributed solve is not tested")

from test_ray_solve import assert_same_coefficients, room, settings  # noqa: E402


@pytest.mark.slow  # starts a cluster of two simulated machines
def test_workers_go_to_machines_that_can_hold_them():
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    cluster.add_node(num_cpus=1)
    try:
        ray.init(address=cluster.address, log_to_driver=False)
        cluster.wait_for_nodes()
        # 2 CPUs in the cluster, but on two machines: a worker of 2 threads fits on neither.
        with pytest.raises(ValueError, match="a worker of 2 threads needs a machine of as many CPUs; the largest "
                                             "in the Ray cluster has 1"):
            bsgi.solve(room(), settings(), executor=bsgi.RayExecutor(workers=1, threads_per_worker=2))
        with pytest.raises(ValueError, match="3 workers of 1 threads need 3 CPUs; the Ray cluster has 2"):
            bsgi.solve(room(), settings(), executor=bsgi.RayExecutor(workers=3))
        # One worker a machine (the default: one a CPU).
        executor = bsgi.RayExecutor()
        assert_same_coefficients(bsgi.solve(room(), settings()), bsgi.solve(room(), settings(), executor=executor))
        assert len(executor.worker_cpu_seconds) == 2
    finally:
        ray.shutdown()
        cluster.shutdown()
