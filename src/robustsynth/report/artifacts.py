"""Atomic, deterministic output files.

Every file is written to a temporary file in the target directory, flushed, fsync'ed and renamed
over the target (``os.replace``), so a reader sees the old file or the new one, never a part.
A stage that writes several files uses :func:`commit_files`: it first removes its primary file and
every file that depends on it, then writes the others, and the primary last, so that whenever a
primary file exists, the files written with it are from the same run.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Mapping

import numpy as np

__all__ = ["atomic_write", "to_jsonable", "json_bytes", "mat_bytes", "commit_files", "sha256", "SCHEMA_VERSION"]

SCHEMA_VERSION = 1


def atomic_write(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file in the same directory, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def to_jsonable(obj: Any) -> Any:
    """numpy arrays -> lists of rows, numpy scalars -> Python numbers, tuples -> lists."""
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def json_bytes(obj: Any) -> bytes:
    """Deterministic JSON (insertion order, 2-space indent, no NaN) with a final newline."""
    return (json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n").encode("utf-8")


def mat_bytes(variables: Mapping[str, Any]) -> bytes:
    """A MATLAB .mat (v5) file as bytes (scipy.io.savemat)."""
    from scipy.io import savemat

    buf = io.BytesIO()
    savemat(buf, dict(variables), do_compression=True, oned_as="column")
    return buf.getvalue()


def sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def remove_stale_temps(outdir: Path) -> None:
    """Remove temp files that a killed writer left behind (``.<name>.<random>.tmp``)."""
    for p in list(outdir.glob(".*.tmp")) + list(outdir.glob("figures/.*.tmp")):
        try:
            p.unlink()
        except FileNotFoundError:
            pass


def commit_files(
    outdir: str | Path,
    files: Mapping[str, bytes],
    primary: str,
    invalidate: tuple[str, ...] = (),
) -> list[Path]:
    """Write a stage's files: remove ``primary`` and ``invalidate`` first, write the others,
    then ``primary`` last.  Returns the written paths."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(outdir)
    for name in (primary, *invalidate):
        try:
            (outdir / name).unlink()
        except FileNotFoundError:
            pass
    written = []
    for name, data in files.items():
        if name != primary:
            atomic_write(outdir / name, data)
            written.append(outdir / name)
    if primary in files:
        atomic_write(outdir / primary, files[primary])
        written.append(outdir / primary)
    return written
