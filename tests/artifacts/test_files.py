"""Atomic writes and deterministic JSON."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.artifacts.files import atomic_write, commit_files, json_bytes, to_jsonable
from robustsynth.report.markdown import table


def test_atomic_write_replaces_and_leaves_no_temp(tmp_path) -> None:
    p = tmp_path / "a.json"
    atomic_write(p, b"old")
    atomic_write(p, b"new")
    assert p.read_bytes() == b"new"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.json"]


def test_failed_write_keeps_old_file(tmp_path, monkeypatch) -> None:
    p = tmp_path / "a.json"
    atomic_write(p, b"old")

    def boom(*_a, **_k):
        raise OSError("disk full")

    monkeypatch.setattr("os.replace", boom)
    with pytest.raises(OSError):
        atomic_write(p, b"new")
    assert p.read_bytes() == b"old"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.json"]


def test_commit_files_writes_primary_last_and_invalidates(tmp_path) -> None:
    (tmp_path / "verification.json").write_text("{}")
    (tmp_path / ".gains.json.x.tmp").write_text("half")  # left by a killed writer
    written = commit_files(tmp_path, {"gains.json": b"{}", "synthesis.md": b"#"}, primary="gains.json",
                           invalidate=("verification.json",))
    assert [p.name for p in written] == ["synthesis.md", "gains.json"]
    assert not (tmp_path / "verification.json").exists()
    (kept,) = (tmp_path / "stale").iterdir()  # set aside, not deleted
    assert (kept / "verification.json").read_text() == "{}" and (kept / "STALE.txt").is_file()
    assert not (tmp_path / ".gains.json.x.tmp").exists()


def test_json_is_deterministic_and_maps_nan_to_null() -> None:
    obj = {"b": np.array([[1.0, 2.0]]), "a": np.float64(0.1), "t": (1, 2), "n": np.int64(3), "f": np.bool_(True)}
    assert json_bytes(obj) == json_bytes(obj)
    assert to_jsonable(obj) == {"b": [[1.0, 2.0]], "a": 0.1, "t": [1, 2], "n": 3, "f": True}
    assert to_jsonable({"x": math.nan}) == {"x": None}


def test_markdown_table_escapes_pipes() -> None:
    assert "\\|e_y\\|" in table(["q"], [["|e_y|"]])


def _reference_jsonable(obj):
    """to_jsonable as it was written before its fast paths: one call per element."""
    if isinstance(obj, np.ndarray):
        return _reference_jsonable(obj.tolist())
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, dict):
        return {str(k): _reference_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_reference_jsonable(v) for v in obj]
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


_floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
_leaves = st.one_of(_floats, st.integers(-10, 10), st.booleans(), st.none(), st.text(max_size=3),
                    _floats.map(np.float64), st.integers(-5, 5).map(np.int64), st.booleans().map(np.bool_),
                    st.lists(_floats, max_size=4).map(np.array),
                    st.lists(st.integers(-5, 5), max_size=4).map(lambda x: np.array(x, dtype=np.int64)),
                    st.lists(st.booleans(), max_size=3).map(np.array),
                    st.lists(st.floats(width=32), max_size=4).map(lambda x: np.array(x, dtype=np.float32)))
_trees = st.recursive(_leaves, lambda kids: st.one_of(st.lists(kids, max_size=4), st.tuples(kids, kids),
                                                      st.dictionaries(st.integers(0, 5) | st.text(max_size=2), kids,
                                                                      max_size=3)), max_leaves=20)


@settings(max_examples=300, deadline=None)
@given(_trees)
def test_fast_paths_give_what_one_call_per_element_gives(obj) -> None:
    """The plain types, finite arrays and lists of finite floats taken as they are: the same values, of the same
    Python types, as the per-element reference (NaN compared by its repr)."""
    assert repr(to_jsonable(obj)) == repr(_reference_jsonable(obj))
