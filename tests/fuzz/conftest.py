"""Hypothesis profiles of the fuzz tests (issue 17, item 1).

``ci`` (the default, run by ``make test``): a fixed number of examples per test, together more than
10,000 cases, derandomized so CI is reproducible. ``long`` (local use): 20 times the examples, fresh
random ones on every run, failures kept in .hypothesis/. Select with ``BSGI_FUZZ_PROFILE=long`` or
``pytest --fuzz-profile=long``. Every test body counts its case (fuzz_support.case); the total is
printed at the end and written to ``$BSGI_FUZZ_COUNT_FILE`` when set (bench/bench_hardening.py).
"""
import faulthandler
import os
import sys

import pytest
from hypothesis import HealthCheck, settings

import fuzz_support

COMMON = dict(deadline=None, print_blob=True, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                                                     HealthCheck.filter_too_much])
settings.register_profile("ci", derandomize=True, database=None, **COMMON)
settings.register_profile("long", **COMMON)


def pytest_configure(config):
    name = config.getoption("--fuzz-profile") or os.environ.get("BSGI_FUZZ_PROFILE", "ci")
    fuzz_support.PROFILE = name
    settings.load_profile(name)


@pytest.fixture(autouse=True)
def hang_watchdog():
    """A test hung in the core (no Python frame to interrupt) ends the run with every thread's
    traceback instead of blocking CI: no fuzz test takes minutes."""
    faulthandler.dump_traceback_later(fuzz_support.HANG_SECONDS, exit=True, file=sys.__stderr__)
    yield
    faulthandler.cancel_dump_traceback_later()


def pytest_terminal_summary(terminalreporter):
    if fuzz_support.CASES:
        terminalreporter.write_line(f"fuzz: {fuzz_support.CASES} cases (profile {fuzz_support.PROFILE})")
    path = os.environ.get("BSGI_FUZZ_COUNT_FILE")
    if path:
        with open(path, "w") as f:
            f.write(f"{fuzz_support.CASES}\n")
