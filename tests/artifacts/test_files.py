"""Atomic writes and deterministic JSON."""

from __future__ import annotations

import math

import numpy as np
import pytest

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
