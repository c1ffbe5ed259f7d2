"""Fuzzing solution files (issue 17, item 1): a solved file truncated anywhere, with bits flipped,
of another format version or with records changed either loads to splines that evaluate to finite
values, or raises a ValueError naming the file and the problem."""
import io
import json
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import bsgi
from fuzz_support import any_float, case, examples, finite, refused


@pytest.fixture(scope="module")
def solved_file(tmp_path_factory):
    """A small solved scene with a diffuse, a glossy and a transmitting surface and an emitter."""
    scene = bsgi.Scene()
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    scene.add_bilinear_patch("floor", quad, albedo=[0.5] * 3, emission=[0] * 3)
    scene.add_bilinear_patch("metal", quad + [0, 0, 0.2], albedo=[0.5] * 3, emission=[0] * 3,
                             bsdf=bsgi.GgxReflection(0.3, 0.3, [0.8] * 3))
    scene.add_bilinear_patch("glass", quad[::-1] + [0, 0, 0.4], albedo=[0.5] * 3, emission=[0] * 3,
                             bsdf=bsgi.RoughDielectric(1.5, 0.4, 0.4))
    scene.add_bilinear_patch("lamp", quad[::-1] + [0, 0, 1], albedo=[0] * 3, emission=[2] * 3, receiver=False, occluder=False)
    s = bsgi.SolverSettings()
    s.spatial_coeffs, s.angular_coeffs_min, s.angular_coeffs_max, s.max_bounces = 3, 3, 3, 1
    s.hemisphere_nodes_theta, s.hemisphere_nodes_phi, s.bsdf_samples = 2, 4, 2
    solution = bsgi.solve(scene, s)
    path = tmp_path_factory.mktemp("solution") / "good.npz"
    bsgi.save_solution(path, solution.surfaces, [scene.name(i) for i in range(len(scene))], s, solution.stats)
    return path.read_bytes()


def load_checked(path):
    """Loads the file; a loaded solution must be usable: finite radiance everywhere."""
    try:
        stored = bsgi.load_solution(path)
    except ValueError as e:
        refused(e, str(path))
        return None
    assert len(stored.radiance) == len(stored.surfaces) == len(stored.names)
    uv = np.array([[0.5, 0.5], [0.0, 1.0]])
    directions = np.array([[0.0, 0.0, 1.0], [0.3, 0.1, -0.9]])
    for surface in stored.surfaces:
        if surface is not None:
            finite(surface.evaluate(uv, directions), "loaded radiance")
    return stored


@settings(max_examples=examples(400))
@given(data=st.data())
def test_truncated_files(solved_file, tmp_path_factory, data):
    cut = data.draw(st.integers(0, len(solved_file)))
    case(cut=cut)
    path = tmp_path_factory.getbasetemp() / "truncated.npz"
    path.write_bytes(solved_file[:cut])
    stored = load_checked(path)
    assert stored is None or cut == len(solved_file)


@settings(max_examples=examples(700))
@given(data=st.data())
def test_bit_flipped_files(solved_file, tmp_path_factory, data):
    flips = data.draw(st.lists(st.tuples(st.integers(0, len(solved_file) - 1), st.integers(0, 7)), min_size=1, max_size=4))
    case(flips=flips)
    damaged = bytearray(solved_file)
    for byte, bit in flips:
        damaged[byte] ^= 1 << bit
    path = tmp_path_factory.getbasetemp() / "flipped.npz"
    path.write_bytes(bytes(damaged))
    load_checked(path)


def rewrite(original: bytes, change) -> bytes:
    """The file with its records changed by change(meta, arrays), written again as save_solution does."""
    with np.load(io.BytesIO(original)) as data:
        arrays = {k: data[k] for k in data.files}
    meta = json.loads(bytes(arrays.pop("meta")).decode())
    change(meta, arrays)
    out = io.BytesIO()
    np.savez_compressed(out, meta=np.frombuffer(json.dumps(meta).encode(), np.uint8), **arrays)
    return out.getvalue()


JSON = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=False), st.text(max_size=5)),
                    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=5), inner, max_size=3)),
                    max_leaves=6)
META_KEYS = ["format", "names", "settings", "stats", "solved", "kinds", "disc_radii"]


@settings(max_examples=examples(500))
@given(data=st.data())
def test_changed_records(solved_file, tmp_path_factory, data):
    """Other versions, records of the wrong type or length, arrays of the wrong shape or dtype."""
    action = data.draw(st.sampled_from(["meta", "drop meta key", "version", "array", "drop array", "settings"]))
    if action == "meta":
        key, value = data.draw(st.sampled_from(META_KEYS)), data.draw(JSON)
        change = lambda meta, arrays: meta.__setitem__(key, value)  # noqa: E731
    elif action == "drop meta key":
        key = data.draw(st.sampled_from(META_KEYS))
        change = lambda meta, arrays: meta.pop(key)  # noqa: E731
    elif action == "version":
        value = data.draw(st.sampled_from(["bsgi-solution-0", "bsgi-solution-2", "", None, 1]))
        change = lambda meta, arrays: meta.__setitem__("format", value)  # noqa: E731
    elif action == "settings":
        key = data.draw(st.sampled_from(["spatial_coeffs", "epsilon", "final_gather", "nonsense"]))
        value = data.draw(JSON)
        change = lambda meta, arrays: meta["settings"].__setitem__(key, value)  # noqa: E731
    else:
        keys = sorted(k for k in np.load(io.BytesIO(solved_file)).files if k != "meta")
        key = data.draw(st.sampled_from(keys))
        shape = data.draw(st.lists(st.integers(0, 4), max_size=5).map(tuple))
        dtype = data.draw(st.sampled_from([np.float64, np.float32, np.int64, np.uint8, np.bool_]))
        fill = data.draw(any_float)
        value = np.full(shape, fill).astype(dtype) if np.isfinite(fill) or dtype in (np.float64, np.float32) else np.zeros(shape, dtype)
        if action == "drop array":
            change = lambda meta, arrays: arrays.pop(key)  # noqa: E731
        else:
            change = lambda meta, arrays: arrays.__setitem__(key, value)  # noqa: E731
    case(action=action)
    path = tmp_path_factory.getbasetemp() / "changed.npz"
    path.write_bytes(rewrite(solved_file, change))
    load_checked(path)


def test_the_unchanged_file_loads(solved_file, tmp_path):
    path = tmp_path / "same.npz"
    path.write_bytes(solved_file)
    stored = load_checked(path)
    assert stored is not None and stored.names == ["floor", "metal", "glass", "lamp"]
    assert [s.kind if s else None for s in stored.surfaces] == ["diffuse", "glossy", "glossy", None]


def test_other_files_name_the_file(tmp_path):
    for name, content in (("empty.npz", b""), ("text.npz", b"hello"), ("zip.npz", None)):
        path = tmp_path / name
        if content is None:
            with zipfile.ZipFile(path, "w") as z:
                z.writestr("x.txt", "not an array")
        else:
            path.write_bytes(content)
        with pytest.raises(ValueError, match=name):
            bsgi.load_solution(path)
