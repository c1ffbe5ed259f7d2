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
