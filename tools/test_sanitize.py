"""make test-sanitize (issue 17, item 3): builds the core with AddressSanitizer and
UndefinedBehaviorSanitizer into build/sanitize (CMake option BSGI_SANITIZE) and runs tests under it.

Python is not instrumented: libasan is preloaded into it (LD_PRELOAD), the instrumented module is
found first on PYTHONPATH, leak checking is off (CPython keeps its objects at exit), and every
report goes to a log file under build/sanitize/logs. UBSan stops at the first finding like ASan
(-fno-sanitize-recover, halt_on_error). Embree and TBB are not instrumented. Exit status: non-zero
if pytest failed or any sanitizer reported anything; the reports are printed.

    python tools/test_sanitize.py [--report FILE.json] [-- pytest arguments]
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BUILD = ROOT / "build" / "sanitize"
# tests/core under the sanitizers, without the slow reference comparisons (Mitsuba, Cycles), and
# the fuzzing profile: every entry point of the core with random and broken input.
DEFAULT_TESTS = ["tests/core", "tests/fuzz", "--skip-slow"]
# -O1, as AddressSanitizer's documentation advises for reasonable speed with accurate reports. (A
# faster build was hoped for; a fresh clone's sanitized build still took about 9 minutes.)
OPTIMISATION = "-O1 -DNDEBUG"


def build() -> Path:
    """Configures and builds the instrumented module; returns the directory to put on PYTHONPATH."""
    import pybind11

    subprocess.run(["cmake", "-S", str(ROOT / "core_cpp"), "-B", str(BUILD), "-DBSGI_SANITIZE=ON",
                    "-DCMAKE_BUILD_TYPE=RelWithDebInfo", f"-DCMAKE_CXX_FLAGS_RELWITHDEBINFO={OPTIMISATION}",
                    f"-DPython_EXECUTABLE={sys.executable}",
                    f"-Dpybind11_DIR={pybind11.get_cmake_dir()}"], check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", str(BUILD), "--target", "_core", "-j", str(os.cpu_count() or 2)], check=True)
    package = BUILD / "python" / "bsgi"
    shutil.rmtree(package, ignore_errors=True)
    shutil.copytree(ROOT / "python" / "bsgi", package)
    (module,) = BUILD.glob("_core*.so")
    shutil.copy2(module, package / module.name)
    return package.parent


def runtime_libraries() -> str:
    """libasan first, then libstdc++: ASan resolves its __cxa_throw interceptor when it starts,
    and a C program like python has no libstdc++ loaded yet (a CHECK failure at the first throw)."""
    paths = []
    for name in ("libasan.so", "libstdc++.so"):
        path = subprocess.run(["g++", f"-print-file-name={name}"], capture_output=True, text=True, check=True).stdout.strip()
        if not os.path.isabs(path):
            raise SystemExit(f"{name} not found (g++ installs it)")
        paths.append(os.path.realpath(path))
    return " ".join(paths)


def findings(logs: Path) -> list[str]:
    """One entry per sanitizer report (each process writes its own log file)."""
    reports = []
    for log in sorted(logs.glob("*")):
        text = log.read_text(errors="replace")
        count = text.count("ERROR: AddressSanitizer") + text.count("runtime error:")
        reports += [f"{log.name}:\n{text}"] * max(count, 1 if text.strip() else 0)
    return reports


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--report", help="write {'sanitizer_findings', 'pytest_status', 'seconds'} here")
    parser.add_argument("pytest_args", nargs="*", help="after --: what pytest runs (default: %(default)s)",
                        default=DEFAULT_TESTS)
    args = parser.parse_args(argv)
    pythonpath = build()
    logs = BUILD / "logs"
    shutil.rmtree(logs, ignore_errors=True)
    logs.mkdir(parents=True)
    env = dict(os.environ)
    env.update(
        LD_PRELOAD=runtime_libraries(),
        PYTHONPATH=os.pathsep.join([str(pythonpath)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else [])),
        ASAN_OPTIONS=f"detect_leaks=0:halt_on_error=1:log_path={logs}/asan",
        UBSAN_OPTIONS=f"halt_on_error=1:print_stacktrace=1:log_path={logs}/ubsan",
        BSGI_SANITIZED="1",
    )
    start = time.monotonic()
    # --capture=sys: reports written to fd 2 by the sanitizers reach the pipe even when the process
    # halts (pytest's fd capture would keep them in a temporary file that dies with it).
    process = subprocess.Popen([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--capture=sys",
                                *args.pytest_args], cwd=ROOT, env=env, stderr=subprocess.PIPE, text=True, errors="replace")
    stderr = []
    for line in process.stderr:
        sys.stderr.write(line)
        stderr.append(line)
    status = process.wait()
    seconds = time.monotonic() - start
    text = "".join(stderr)
    reports = findings(logs) + ["stderr"] * (text.count("ERROR: AddressSanitizer") + text.count("runtime error:"))
    for report in reports[:5]:
        if report != "stderr":
            print(report, file=sys.stderr)
    print(f"test-sanitize: {len(reports)} sanitizer findings, pytest exit status {status}, {seconds:.0f} s")
    if args.report:
        Path(args.report).write_text(json.dumps({"sanitizer_findings": len(reports), "pytest_status": status,
                                                 "seconds": seconds}))
    return 1 if reports or status else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
