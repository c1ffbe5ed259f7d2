"""Hardening (issue 17): the fuzzing profile of CI and the sanitizer run.

Figures: ``fuzz_cases`` (generated inputs the ci profile of tests/fuzz ran), ``fuzz_failures``
(failed fuzz tests: inputs that crashed, hung or were refused without naming the object and the
problem; must be 0), ``fuzz_seconds``, ``sanitizer_findings`` (AddressSanitizer and UBSan reports
of tests/core and tests/fuzz under the instrumented core, tools/test_sanitize.py; must be 0),
``sanitizer_pytest_status`` and ``sanitizer_seconds``. Each runs in a subprocess: a crash is
counted, not fatal to the benchmark.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def fuzz() -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        count = Path(tmp) / "cases"
        start = time.monotonic()
        run = subprocess.run([sys.executable, "-m", "pytest", "tests/fuzz", "-q", "-p", "no:cacheprovider",
                              "--fuzz-profile=ci"], cwd=ROOT, capture_output=True, text=True,
                             env=dict(os.environ, BSGI_FUZZ_COUNT_FILE=str(count)))
        seconds = time.monotonic() - start
        cases = int(count.read_text()) if count.exists() else 0
    summary = run.stdout.strip().splitlines()[-1] if run.stdout.strip() else ""
    failed = sum(int(n) for n in re.findall(r"(\d+) (?:failed|error)", summary))
    if run.returncode not in (0, 1) or (run.returncode == 1 and not failed):
        failed = max(failed, 1)  # the process died (a crash or the hang watchdog)
    return {"fuzz_cases": cases, "fuzz_failures": failed, "fuzz_seconds": round(seconds, 1)}


def sanitize() -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "report.json"
        subprocess.run([sys.executable, "tools/test_sanitize.py", "--report", str(report)], cwd=ROOT)
        if not report.exists():
            return {"sanitizer_findings": -1}  # the build failed
        figures = json.loads(report.read_text())
    return {"sanitizer_findings": figures["sanitizer_findings"], "sanitizer_pytest_status": figures["pytest_status"],
            "sanitizer_seconds": round(figures["seconds"], 1)}


def run() -> dict:
    return {**fuzz(), **sanitize()}


if __name__ == "__main__":
    for key, value in run().items():
        print(f"{key}: {value}")
