"""Run a snippet with the `bpy` module in a fresh Python process.

GPU engines (EEVEE, Workbench) need an EGL driver; without one Blender aborts the whole process
instead of raising, which would take pytest down with it. A child process turns that into a
non-zero exit status the test can report. The child also gets its own HOME and Blender user
folder, and the test session's Mesa shader cache (llvmpipe's compiled shaders: about a third of
an EEVEE child's first render), so nothing leaks into the user's configuration.

    run = run_bpy("import bpy\\nresult = bpy.app.version_string")
    assert run.ok, run.log
    run.result  # whatever the snippet assigned to `result` (JSON-serialisable)
"""
from __future__ import annotations

import atexit
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass

# Executes the snippet, then writes its `result` as JSON where the parent asked.
_BOOTSTRAP = """\
import json, os, sys
namespace = {"__name__": "__bpy_snippet__"}
exec(compile(open(sys.argv[1]).read(), "<snippet>", "exec"), namespace)
with open(sys.argv[2], "w") as f:
    json.dump(namespace.get("result"), f)
"""


def session_folder(prefix: str) -> str:
    """A temporary folder for this process, removed when it exits."""
    folder = tempfile.mkdtemp(prefix=prefix)
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return folder


# One per test session, gone at its end (the in-process bpy of conftest.py uses it too).
SHADER_CACHE = session_folder("bsgi-mesa-")


@dataclass
class BpyRun:
    returncode: int
    stdout: str
    stderr: str
    result: object  # the snippet's `result`, None if it did not finish

    @property
    def ok(self) -> bool:
        return self.returncode == 0

    @property
    def log(self) -> str:
        """Exit status and the end of both streams, for assertion messages."""
        return f"exit status {self.returncode}\n--- stdout\n{self.stdout[-4000:]}\n--- stderr\n{self.stderr[-4000:]}"


def isolated_env(folder: pathlib.Path, extra: dict | None = None) -> dict:
    """The environment for a Blender child: HOME and user resources under `folder`, the session's
    shader cache."""
    env = dict(os.environ)
    env.update({
        "HOME": str(folder / "home"),
        "BLENDER_USER_RESOURCES": str(folder / "blender"),
        "MESA_SHADER_CACHE_DIR": SHADER_CACHE,
    })
    env.update(extra or {})
    for key in ("HOME", "BLENDER_USER_RESOURCES", "MESA_SHADER_CACHE_DIR"):
        pathlib.Path(env[key]).mkdir(parents=True, exist_ok=True)
    return env


def run_bpy(code: str, *, python: str | os.PathLike = sys.executable, args: list[str] = (),
            env: dict | None = None, timeout: float = 600) -> BpyRun:
    """Run `code` (which imports bpy itself) in a child `python`; extra `args` follow in sys.argv[3:]."""
    with tempfile.TemporaryDirectory(prefix="bsgi-bpy-") as tmp:
        tmp = pathlib.Path(tmp)
        snippet, out = tmp / "snippet.py", tmp / "result.json"
        snippet.write_text(code)
        proc = subprocess.run(
            [str(python), "-c", _BOOTSTRAP, str(snippet), str(out), *args],
            env=env if env is not None else isolated_env(tmp),
            capture_output=True, text=True, timeout=timeout,
        )
        result = json.loads(out.read_text()) if out.exists() else None
        return BpyRun(proc.returncode, proc.stdout, proc.stderr, result)
