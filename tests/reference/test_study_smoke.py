"""The study's machinery (bench/study, `make study`) on its smallest case, so that a change that
breaks it is caught: the Cornell box, the draft preset and one knob, a tiny Cycles bake and a tiny
Mitsuba reference (run_study --quick), in a temporary folder."""
from __future__ import annotations

import csv
import math
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.mark.blender
def test_quick_study_writes_results_plots_and_tables(tmp_path):
    subprocess.run([sys.executable, str(ROOT / "bench" / "study" / "run_study.py"), "--quick", "--scene", "cornell_box",
                    "--out", str(tmp_path), "--cache", str(tmp_path / "references"), "--work", str(tmp_path / "work")],
                   check=True, timeout=600)
    with open(tmp_path / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert {r["method"] for r in rows} == {"bsgi", "cycles bake"}
    for r in rows:
        assert r["scene"] == "cornell_box"
        assert int(r["pairs"]) >= 150  # of 200: few pairs lost to geometry differences
        # Loose bounds: only a broken pipeline (lookup, units, pairs) leaves them.
        assert 0 < float(r["rel_rmse"]) < 0.5, r
        assert float(r["seconds"]) > 0
    draft = next(r for r in rows if r["setting"] == "draft")
    assert int(draft["coefficients"]) > 0 and float(draft["peak_mb"]) > 0
    assert (tmp_path / "plots" / "cornell_box.png").stat().st_size > 10_000
    assert "| draft |" in (tmp_path / "README.md").read_text()
    # The cache is used on a second look-up and knows its key.
    sys.path.insert(0, str(ROOT / "bench" / "study"))
    import references

    blend = ROOT / "example_blends" / "cornell_box.blend"
    cached = references.load_cached(blend, True, tmp_path / "references")
    assert cached is not None and math.isclose(float(cached["spp"]), references.QUICK["spp"])
    # --setting reruns those rows in place and keeps the others as they were (no Cycles bake):
    # every row marked, only the draft's mark replaced.
    for r in rows:
        r["seconds"] = "-1"
    with open(tmp_path / "results.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    subprocess.run([sys.executable, str(ROOT / "bench" / "study" / "run_study.py"), "--quick", "--scene", "cornell_box",
                    "--setting", "draft", "--out", str(tmp_path), "--cache", str(tmp_path / "references"),
                    "--work", str(tmp_path / "work")], check=True, timeout=600)
    with open(tmp_path / "results.csv", newline="") as f:
        again = list(csv.DictReader(f))
    assert [r["setting"] for r in again] == [r["setting"] for r in rows]
    for before, after in zip(rows, again):
        if before["setting"] != "draft":
            assert after == before
    draft_again = next(r for r in again if r["setting"] == "draft")
    assert draft_again["coefficients"] == draft["coefficients"] and float(draft_again["seconds"]) > 0


def test_stale_reference_is_detected(tmp_path):
    """A reference made for other scene contents (or settings) is not used."""
    sys.path.insert(0, str(ROOT / "bench" / "study"))
    import numpy as np
    import references

    blend = tmp_path / "scene.blend"
    blend.write_bytes(b"one")
    np.savez(references.cache_path(blend, True, tmp_path), key=references.cache_key(blend, references.QUICK))
    assert references.load_cached(blend, True, tmp_path) is not None
    blend.write_bytes(b"two")
    assert references.load_cached(blend, True, tmp_path) is None
