"""The robot log: what `identify` and `check-log` read, and what `verify --log` writes.

One CSV file per run, one row per sampling instant t_k, with a header line naming the columns
(any order; extra columns are ignored):

=========  ======  ================================================================================
column     unit    meaning
=========  ======  ================================================================================
t          s       sampling instant t_k (strictly increasing)
x, y       m       measured position at t_k
theta      rad     measured heading at t_k (unwrapped or wrapped: both are read)
seq        —       sequence number of the command sent at t_k (increasing by 1)
rho_r      rad/s   commanded right track (motor) speed of that command
rho_l      rad/s   commanded left track speed
sent       s       when the command left the controller
applied    s       when it started acting on the robot (empty or NaN: lost, it never acted)
enc_r/l    rad/s   optional: measured track speeds (read, not used yet)
mu_hat_r/l —       optional, a slip-compensated law (docs/theory.md §18): the estimated tractions the command
                   of t_k was divided by
condition  —       optional, with mu_hat_r/l: 1 where the certificate's condition was sure to hold for that
                   command (the estimate's half-width + lag within its error), else 0
=========  ======  ================================================================================

The file ends with a line break (one that ends within a row was cut short, and is refused).  Errors name the file,
the row (1-based, header = row 1) and the column, in one line.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .files import atomic_write

__all__ = ["RobotLog", "read_log", "write_log", "log_text", "LOG_COLUMNS", "ESTIMATE_COLUMNS"]

LOG_COLUMNS = ("t", "x", "y", "theta", "seq", "rho_r", "rho_l", "sent", "applied")
OPTIONAL_COLUMNS = ("enc_r", "enc_l")
ESTIMATE_COLUMNS = ("mu_hat_r", "mu_hat_l", "condition")  # a slip-compensated law's (written and read together)
_MAX_STEP_S = 10.0  # a median time step above this is taken for milliseconds (or another unit)


@dataclass(frozen=True)
class RobotLog:
    """One run's log (arrays of equal length, one entry per sampling instant)."""

    path: str
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    seq: np.ndarray
    rho_r: np.ndarray
    rho_l: np.ndarray
    sent: np.ndarray
    applied: np.ndarray  # NaN: lost
    # a slip-compensated law: per row the estimate the command was divided by and the condition (n, 3); None: none
    estimate: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def delays(self) -> np.ndarray:
        """applied - sent of every received command (NaN where lost)."""
        return self.applied - self.sent


def _cell(path: Path, row: int, col: str, text: str, allow_empty: bool) -> float:
    s = text.strip()
    if s == "" or s.lower() == "nan":
        if allow_empty:
            return math.nan
        raise InputError(f"{path}: row {row}, column {col!r}: {'empty' if s == '' else 'NaN'} (a number is required)")
    try:
        v = float(s)
    except ValueError:
        raise InputError(f"{path}: row {row}, column {col!r}: {s[:30]!r} is not a number") from None
    if not math.isfinite(v):
        raise InputError(f"{path}: row {row}, column {col!r}: {s!r} is not finite")
    return v


def read_log(path: str | Path) -> RobotLog:
    """Read and validate one log file; InputError (exit 2) with file, row and column otherwise."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{p}: log file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: cannot read ({exc})") from None
    if text.strip() and not text.endswith(("\n", "\r")):
        # a file cut short (a copy interrupted, a logger killed) ends within a row, whose last number may still
        # read as one: its row is not taken for a sampling instant
        n = len([ln for ln in text.splitlines() if ln.strip()])
        raise InputError(f"{p}: row {n}: not ended by a line break (a truncated file?); a log ends with a newline")
    rows = list(csv.reader(io.StringIO(text)))
    rows = [r for r in rows if any(c.strip() for c in r)]
    if not rows:
        raise InputError(f"{p}: empty (expected a header line with the columns {', '.join(LOG_COLUMNS)})")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in LOG_COLUMNS if c not in header]
    if missing:
        raise InputError(f"{p}: row 1: column {missing[0]!r} is missing (a log needs {', '.join(LOG_COLUMNS)})")
    if len(rows) < 3:
        raise InputError(f"{p}: {len(rows) - 1} data rows; a log needs at least 2 sampling instants")
    given = [c for c in ESTIMATE_COLUMNS if c in header]
    if given and len(given) < len(ESTIMATE_COLUMNS):
        gone = next(c for c in ESTIMATE_COLUMNS if c not in header)
        raise InputError(f"{p}: row 1: column {gone!r} is missing (the estimate's columns come together: "
                         f"{', '.join(ESTIMATE_COLUMNS)})")
    read = LOG_COLUMNS + (ESTIMATE_COLUMNS if given else ())
    idx = {c: header.index(c) for c in read}
    cols: dict[str, list[float]] = {c: [] for c in read}
    for r, raw in enumerate(rows[1:], start=2):
        if len(raw) < len(header):
            raise InputError(f"{p}: row {r}: {len(raw)} fields, the header has {len(header)}")
        for c in read:
            cols[c].append(_cell(p, r, c, raw[idx[c]], allow_empty=(c == "applied")))
            if c == "condition" and cols[c][-1] not in (0.0, 1.0):
                raise InputError(f"{p}: row {r}, column 'condition': {cols[c][-1]:g} (0 or 1)")
    a = {c: np.array(v, dtype=float) for c, v in cols.items()}
    dt = np.diff(a["t"])
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        r = int(bad[0]) + 3
        raise InputError(f"{p}: row {r}, column 't': time {a['t'][bad[0] + 1]:g} does not increase "
                         f"(previous {a['t'][bad[0]]:g}); the rows must be in time order")
    step = float(np.median(dt))
    if step > _MAX_STEP_S:
        raise InputError(f"{p}: column 't': the median time step is {step:g}; times must be in seconds "
                         f"(milliseconds? divide by 1000)")
    received = np.isfinite(a["applied"])
    late = np.flatnonzero(received & (a["applied"] < a["sent"]))
    if late.size:
        r = int(late[0]) + 2
        raise InputError(f"{p}: row {r}, column 'applied': {a['applied'][late[0]]:g} is before 'sent' "
                         f"{a['sent'][late[0]]:g}")
    delays = (a["applied"] - a["sent"])[received]
    if delays.size and float(np.median(delays)) > max(_MAX_STEP_S, 100 * step):
        raise InputError(f"{p}: columns 'sent'/'applied': the median delay is {float(np.median(delays)):g} against a "
                         f"time step of {step:g}; all times must be in seconds")
    jumps = np.flatnonzero(np.diff(a["seq"]) != 1)
    if jumps.size:
        r = int(jumps[0]) + 3
        raise InputError(f"{p}: row {r}, column 'seq': {a['seq'][jumps[0] + 1]:g} after {a['seq'][jumps[0]]:g}; "
                         "one command per sampling instant, numbered consecutively (a lost one has an empty 'applied')")
    return RobotLog(str(p), a["t"], a["x"], a["y"], a["theta"], a["seq"], a["rho_r"], a["rho_l"], a["sent"],
                    a["applied"], np.stack([a[c] for c in ESTIMATE_COLUMNS], axis=1) if given else None)


def log_text(log: RobotLog) -> str:
    """The CSV text of a log (17 significant digits: reading it back gives the same numbers)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    cols = LOG_COLUMNS + (ESTIMATE_COLUMNS if log.estimate is not None else ())
    w.writerow(cols)
    for k in range(len(log)):
        vals = [log.t[k], log.x[k], log.y[k], log.theta[k], log.seq[k], log.rho_r[k], log.rho_l[k], log.sent[k],
                log.applied[k]] + ([] if log.estimate is None else list(log.estimate[k]))
        w.writerow(["" if (c == "applied" and not math.isfinite(v)) else (str(int(v)) if c in ("seq", "condition")
                                                                            else repr(float(v)))
                    for c, v in zip(cols, vals)])
    return out.getvalue()


def write_log(path: str | Path, log: RobotLog) -> None:
    """Write ``log`` atomically."""
    atomic_write(path, log_text(log).encode("utf-8"))
