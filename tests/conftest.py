import pytest


def pytest_addoption(parser):
    parser.addoption("--skip-slow", action="store_true", help="skip slow reference comparisons (CI runs them)")
    parser.addoption("--fuzz-profile", default=None, choices=["ci", "long"],
                     help="hypothesis profile of tests/fuzz (default: $BSGI_FUZZ_PROFILE or ci)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--skip-slow"):
        skip = pytest.mark.skip(reason="--skip-slow")
        for item in items:
            if "slow" in item.keywords:
                item.add_marker(skip)


@pytest.fixture(scope="module")
def ray_cluster():
    """A local Ray of 2 CPUs for the module's tests (its start-up costs seconds); skips them
    without Ray installed."""
    ray = pytest.importorskip("ray", reason="Ray is not installed (pip install ray): the distributed solve is not tested")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()
