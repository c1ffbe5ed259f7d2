"""Mitsuba 3 references of the core tests, committed in tests/reference/data/<name>.npz (spaces as
underscores; as the study's and the validation scenes' are in bench/): the pairs of mitsuba_reference.visible_pairs and
the radiance (and standard error) Mitsuba's path tracer finds along them, made once instead of at
every test run (tens of seconds each).

Each file holds a key: the SHA-256 of everything the reference is made from (the scene spec, the
pair and sample settings, mitsuba_reference.py, and for a test's own Mitsuba scene the source of
the function that builds it and the inputs it reads). A test whose scene, settings or reference
code changed finds another key and fails, naming the command that remakes the stale files:

    make test-references     (BSGI_MAKE_REFERENCES=1 pytest -m mitsuba_reference tests/core)

BSGI_MAKE_REFERENCES=1 makes the missing and stale references as the tests ask for them (and
writes them); =all remakes every one. The pairs' (u, v) and directions are kept exactly (float64),
the radiance and its standard error in single precision (their relative rounding, 6e-8, is far below
the tests' bounds); the points are recomputed from the spec and (u, v) as visible_pairs computes
them, the eye points (used only to trace the reference) are not kept."""
from __future__ import annotations

import hashlib
import inspect
import json
import os
import pathlib
import time

import numpy as np

from . import mitsuba_reference

HERE = pathlib.Path(__file__).resolve().parent
DATA = HERE / "data"
REMAKE = "make test-references"


class StaleReference(AssertionError):
    pass


def _spec_description(spec) -> list:
    return [{**{k: (np.asarray(v, float).tolist() if k == "corners" else v) for k, v in vars(p).items()}}
            for p in spec.patches]


def _update(h, name, value):
    h.update(name.encode() + b"\0")
    if isinstance(value, np.ndarray):
        h.update(f"{value.dtype.str}{value.shape}".encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif callable(value):
        h.update(inspect.getsource(value).encode())
    else:
        h.update(json.dumps(value, sort_keys=True, default=lambda x: np.asarray(x).tolist()).encode())


def key(spec, settings: dict, scene=None, inputs: dict | None = None) -> str:
    """SHA-256 of what the reference is made from."""
    h = hashlib.sha256()
    _update(h, "spec", _spec_description(spec))
    _update(h, "settings", settings)
    h.update(pathlib.Path(mitsuba_reference.__file__).read_bytes())
    if scene is not None:
        _update(h, "scene", scene)
    for name, value in sorted((inputs or {}).items()):
        _update(h, f"input {name}", value)
    return h.hexdigest()


def points(spec, patch, uv) -> np.ndarray:
    """The pairs' points, as visible_pairs computes them from (u, v)."""
    return np.array([mitsuba_reference._point(spec.patches[int(i)].corners, *p)[0] for i, p in zip(patch, uv)])


def _make(path, spec, settings, k, scene):
    start = time.perf_counter()
    pairs = mitsuba_reference.visible_pairs(spec, settings["pairs"], seed=settings["pair_seed"],
                                            margin=settings["margin"])
    loaded = scene(spec) if scene is not None else mitsuba_reference.to_mitsuba(spec)
    ref, stderr = mitsuba_reference.radiance_along(loaded, pairs["eye"], pairs["point"], spp=settings["spp"],
                                                   seed=settings["seed"])
    mi = mitsuba_reference.load_mitsuba()
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, key=k, settings=json.dumps(settings, sort_keys=True), mitsuba=mi.__version__,
                        seconds=time.perf_counter() - start, patch=pairs["patch"].astype(np.uint16),
                        uv=pairs["uv"], direction=pairs["direction"], reference=ref.astype(np.float32),
                        stderr=stderr.astype(np.float32))
    print(f"\n{path.name}: made in {time.perf_counter() - start:.1f} s", flush=True)


def reference(name: str, spec, *, pairs: int, pair_seed: int, spp: int, seed: int, margin: float = 0.02, scene=None,
              inputs: dict | None = None):
    """(pairs, reference radiance, its standard error) of `spec` from tests/reference/data/<name>.npz (spaces as underscores):
    what mitsuba_reference.visible_pairs(spec, pairs, pair_seed, margin) and radiance_along at `spp`
    samples with `seed` give, in the Mitsuba scene to_mitsuba(spec) or `scene(spec)` (a function:
    its source counts in the key, and so do `inputs`, the values and functions it reads besides).
    pairs is a dict of patch, uv, point and direction."""
    settings = {"pairs": pairs, "pair_seed": pair_seed, "spp": spp, "seed": seed, "margin": margin}
    k = key(spec, settings, scene, inputs)
    path = DATA / f"{name.replace(' ', '_')}.npz"
    remake = os.environ.get("BSGI_MAKE_REFERENCES", "")
    stored = str(np.load(path)["key"]) if path.exists() else None
    if remake == "all" or (remake and stored != k):
        _make(path, spec, settings, k, scene)
    elif stored != k:
        raise StaleReference(f"the committed Mitsuba reference {path.relative_to(HERE.parents[1])} is "
                             f"{'missing' if stored is None else 'stale (its scene, settings or reference code changed)'}: "
                             f"`{REMAKE}` remakes it")
    data = np.load(path)
    out = {"patch": data["patch"].astype(np.int64), "uv": data["uv"], "direction": data["direction"]}
    out["point"] = points(spec, out["patch"], out["uv"])
    return out, data["reference"].astype(np.float64), data["stderr"].astype(np.float64)
