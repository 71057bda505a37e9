"""The robot log format: a written log reads back to the same numbers, and every malformed log is
refused with one line naming the file, the row and the column (exit 2 from the CLI)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robustsynth.artifacts.logs import LOG_COLUMNS, RobotLog, read_log, write_log
from robustsynth.errors import InputError

ROOT = Path(__file__).resolve().parents[2]


def _log(n: int = 6) -> RobotLog:
    t = np.arange(n) * 0.1
    applied = t + 0.03
    applied[2] = np.nan  # lost
    return RobotLog("x.csv", t, np.linspace(0, 0.25, n), np.zeros(n), np.zeros(n), np.arange(n, dtype=float),
                    np.full(n, 5.5), np.full(n, 5.6), t.copy(), applied)


def _text(rows: list[list[str]], header=LOG_COLUMNS) -> str:
    return ",".join(header) + "\n" + "\n".join(",".join(r) for r in rows) + "\n"


def _good_rows(n: int = 4) -> list[list[str]]:
    return [[f"{0.1 * k:.1f}", "0", "0", "0", str(k), "5", "5", f"{0.1 * k:.1f}", f"{0.1 * k + 0.02:.2f}"] for k in range(n)]


def test_round_trip(tmp_path) -> None:
    log = _log()
    write_log(tmp_path / "a.csv", log)
    back = read_log(tmp_path / "a.csv")
    for name in ("t", "x", "y", "theta", "seq", "rho_r", "rho_l", "sent"):
        assert np.array_equal(getattr(back, name), getattr(log, name)), name
    assert np.isnan(back.applied[2]) and np.array_equal(back.applied[~np.isnan(back.applied)], log.applied[~np.isnan(log.applied)])


def test_the_sample_log_in_the_repo_reads() -> None:
    log = read_log(ROOT / "docs" / "sample-log.csv")
    assert len(log) >= 100 and np.any(np.isnan(log.applied))


def _bad(tmp_path, text: str) -> str:
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(InputError) as e:
        read_log(p)
    msg = str(e.value)
    assert msg.startswith(str(p)) and "\n" not in msg
    return msg


def test_malformed_logs_name_file_row_and_column(tmp_path) -> None:
    rows = _good_rows()
    assert "column 'theta' is missing" in _bad(tmp_path, _text([r[:3] + r[4:] for r in rows], LOG_COLUMNS[:3] + LOG_COLUMNS[4:]))
    back = [r.copy() for r in rows]
    back[2][0] = "0.05"
    assert "row 4, column 't'" in _bad(tmp_path, _text(back)) and "does not increase" in _bad(tmp_path, _text(back))
    nan = [r.copy() for r in rows]
    nan[1][1] = "nan"
    assert "row 3, column 'x': NaN" in _bad(tmp_path, _text(nan))
    ms = [[f"{100 * k}", "0", "0", "0", str(k), "5", "5", f"{100 * k}", f"{100 * k + 20}"] for k in range(4)]
    assert "milliseconds" in _bad(tmp_path, _text(ms))
    assert "empty" in _bad(tmp_path, "")
    early = [r.copy() for r in rows]
    early[1][8] = "0.05"
    assert "row 3, column 'applied'" in _bad(tmp_path, _text(early))
    gap = [r.copy() for r in rows]
    gap[3][4] = "7"
    assert "row 5, column 'seq'" in _bad(tmp_path, _text(gap))
    word = [r.copy() for r in rows]
    word[0][5] = "fast"
    assert "row 2, column 'rho_r': 'fast' is not a number" in _bad(tmp_path, _text(word))


def test_cli_exit_2_one_line_no_traceback(tmp_path) -> None:
    p = tmp_path / "bad.csv"
    p.write_text(_text([r[:3] + r[4:] for r in _good_rows()], LOG_COLUMNS[:3] + LOG_COLUMNS[4:]))
    for cmd in (["identify", str(p)], ["check-log", str(p), "--config", str(ROOT / "configs" / "tracks-box.yaml")]):
        r = subprocess.run([sys.executable, "-m", "robustsynth", *cmd], capture_output=True, text=True)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {p}: row 1: column 'theta' is missing"), r.stderr


def test_a_log_cut_short_is_refused_naming_its_row(tmp_path) -> None:
    """A file that ends within a row (its last field may still read as a number): one line, the row named."""
    text = (ROOT / "docs" / "sample-log.csv").read_text()
    cut = tmp_path / "cut.csv"
    cut.write_text(text[: text.index("\n", 400) - 3])
    rows = cut.read_text().count("\n") + 1
    with pytest.raises(InputError, match=rf"cut.csv: row {rows}: not ended by a line break \(a truncated file\?\)"):
        read_log(cut)
    whole = tmp_path / "whole.csv"
    whole.write_text(text)
    assert len(read_log(whole)) == len(read_log(ROOT / "docs" / "sample-log.csv"))


def test_a_compensated_laws_estimate_columns_round_trip_and_come_together(tmp_path) -> None:
    """mu_hat_r, mu_hat_l, condition (a slip-compensated law's log, docs/theory.md §18): written and read back to the
    same numbers; a log without them reads as before (None); one of them alone, or a condition other than 0 or 1, is
    refused with one line naming the row and column."""
    import dataclasses

    from robustsynth.artifacts.logs import ESTIMATE_COLUMNS

    log = _log()
    est = np.stack([np.linspace(0.8, 0.9, 6), np.full(6, 0.7 + 1e-13), (np.arange(6) > 1).astype(float)], axis=1)
    write_log(tmp_path / "c.csv", dataclasses.replace(log, estimate=est))
    back = read_log(tmp_path / "c.csv")
    assert back.estimate is not None and np.array_equal(back.estimate, est)
    write_log(tmp_path / "plain.csv", log)
    assert read_log(tmp_path / "plain.csv").estimate is None
    rows = [r + ["0.8", "0.8", "1"] for r in _good_rows()]
    (tmp_path / "part.csv").write_text(_text([r[:-1] for r in rows], LOG_COLUMNS + ESTIMATE_COLUMNS[:2]))
    with pytest.raises(InputError, match=r"part\.csv: row 1: column 'condition' is missing") as exc:
        read_log(tmp_path / "part.csv")
    assert "\n" not in str(exc.value)
    rows[2][-1] = "0.5"
    (tmp_path / "cond.csv").write_text(_text(rows, LOG_COLUMNS + ESTIMATE_COLUMNS))
    with pytest.raises(InputError, match=r"cond\.csv: row 4, column 'condition': 0\.5 \(0 or 1\)"):
        read_log(tmp_path / "cond.csv")
