"""Atomic, deterministic output files.

Every file is written to a temporary file in the target directory, flushed, fsync'ed and renamed
over the target (``os.replace``), so a reader sees the old file or the new one, never a part.
A stage that writes several files uses :func:`commit_files`: it first removes its primary file and
sets aside every file of another stage that depends on it (:func:`set_aside`: moved under
``stale/<time>/``, never deleted), then writes the others, and the primary last, so that whenever a
primary file exists, the files written with it are from the same run.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, Mapping

from ..errors import OutputError
from ..results import to_jsonable

__all__ = ["make_dir", "check_writable_dir", "writable_dir", "output_error", "atomic_write", "remove_files", "set_aside", "STALE_DIR", "to_jsonable", "json_bytes", "mat_bytes", "commit_files", "sha256", "SCHEMA_VERSION", "record_header"]

SCHEMA_VERSION = 1


def record_header() -> dict[str, Any]:
    """What every JSON record robustsynth writes begins with, any plant: the schema and the version that wrote it."""
    from .. import __version__

    return {"schema_version": SCHEMA_VERSION, "robustsynth_version": __version__}


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def output_error(path: Path, exc: OSError) -> OutputError:
    """One line naming the output place and the OS reason (exit 2)."""
    return OutputError(f"{path}: cannot write ({exc.strerror or exc})")


def make_dir(path: str | Path) -> Path:
    """Create an output directory (and its parents) or raise :class:`OutputError`."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(path, exc) from None
    return path


def check_writable_dir(path: str | Path) -> Path:
    """Create the directory ``path`` now, before any work, and prove it writable with a temporary file
    (removed); OutputError naming the place otherwise."""
    path = make_dir(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=".write-check.", dir=path)
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise output_error(path, exc) from None
    return path


@contextmanager
def writable_dir(path: str | Path) -> Iterator[Path]:
    """:func:`check_writable_dir` for work that fills the directory later: when the work fails (an
    exception, Ctrl-C), the directories this made are removed again if they are still empty, so a
    failed command leaves no empty output place behind."""
    path = Path(path)
    made = [p for p in (path, *path.parents) if not p.exists()]  # deepest first
    try:
        yield check_writable_dir(path)
    except BaseException:
        for p in made:
            try:
                p.rmdir()  # only empty ones; a file the work wrote keeps its directory
            except OSError:
                break
        raise


def atomic_write(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file in the same directory, then rename).

    The file gets the mode an ordinary ``open`` would give (0666 less the umask), not the 0600 of
    a temporary file; any OS failure (permission, read-only, no space, file too large) becomes an
    :class:`OutputError` naming the path, with the temporary file removed."""
    path = Path(path)
    make_dir(path.parent)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise output_error(path.parent, exc) from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise output_error(path, exc) from None
        raise


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


def remove_files(outdir: Path, names: tuple[str, ...] | list[str]) -> None:
    """Remove ``outdir/name`` for each name that exists; OutputError (one line) if one cannot be."""
    for name in names:
        try:
            (outdir / name).unlink()
        except FileNotFoundError:
            pass
        except OSError as exc:
            raise output_error(outdir / name, exc) from None


STALE_DIR = "stale"  # OUTDIR/stale/<UTC time>/: the results a stage set aside (set_aside)


def set_aside(outdir: str | Path, names: tuple[str, ...] | list[str], reason: str) -> tuple[str, ...]:
    """Move the files ``names`` (relative to ``outdir``, e.g. ``figures/path.png``) that exist into a new
    ``outdir/stale/<UTC time>/`` (same relative paths) with a ``STALE.txt`` saying ``reason``: a stage
    never deletes what another stage wrote (issue 50: a rebuild had removed 14 files of results), and
    nothing left beside a new primary file reads as its own.  Returns the moved files' new paths,
    relative to ``outdir`` (empty when none existed).  A failure to move: OutputError naming the file."""
    import time

    outdir = Path(outdir)
    present = [n for n in names if (outdir / n).is_file()]
    if not present:
        return ()
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    dest, k = outdir / STALE_DIR / stamp, 1
    while dest.exists():  # two stages within one second
        k += 1
        dest = outdir / STALE_DIR / f"{stamp}-{k}"
    moved = []
    for name in present:
        target = dest / name
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(outdir / name, target)
        except FileNotFoundError:  # another process took it meanwhile
            continue
        except OSError as exc:
            raise output_error(target, exc) from None
        moved.append(str(target.relative_to(outdir)))
    atomic_write(dest / "STALE.txt", (f"Set aside by robustsynth at {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}: "
                                      f"{reason}.\nKept for reference; no robustsynth command reads them. Delete the directory "
                                      "when you no longer need them.\n").encode("utf-8"))
    return tuple(moved)


def commit_files(
    outdir: str | Path,
    files: Mapping[str, bytes],
    primary: str,
    invalidate: tuple[str, ...] = (),
    reason: str = "they belonged to the earlier result the new one replaced",
) -> list[Path]:
    """Write a stage's files: remove ``primary`` and set ``invalidate`` aside first (:func:`set_aside`,
    with ``reason``), write the others, then ``primary`` last.  Returns the written paths."""
    outdir = make_dir(outdir)
    remove_stale_temps(outdir)
    remove_files(outdir, (primary,))
    set_aside(outdir, invalidate, reason)
    written: list[Path] = []
    try:
        for name, data in files.items():
            if name != primary:
                atomic_write(outdir / name, data)
                written.append(outdir / name)
        if primary in files:
            atomic_write(outdir / primary, files[primary])
            written.append(outdir / primary)
    except OutputError:
        # nothing of a stage that could not be completed stays behind
        for p in written:
            try:
                p.unlink()
            except OSError:
                pass
        raise
    return written
