"""Small Markdown helpers shared by the reports."""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["fmt", "table", "matrix_table"]


def fmt(x: float | None, digits: int = 4) -> str:
    if x is None:
        return "—"
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
    x = float(x)
    if x == 0.0:
        return "0"
    return f"{x:.{digits}g}"


def _cell(c: object) -> str:
    return str(c).replace("|", "\\|")


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table; '|' inside cells is escaped."""
    out = ["| " + " | ".join(_cell(h) for h in header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for r in rows:
        out.append("| " + " | ".join(_cell(c) for c in r) + " |")
    return "\n".join(out) + "\n"


def matrix_table(M: np.ndarray, row_names: Sequence[str], col_names: Sequence[str], digits: int = 5) -> str:
    M = np.atleast_2d(np.asarray(M, dtype=float))
    if M.size == 0:
        return "(empty)\n"
    rows = [[f"**{row_names[i]}**"] + [fmt(M[i, j], digits) for j in range(M.shape[1])] for i in range(M.shape[0])]
    return table([""] + [f"`{c}`" for c in col_names], rows)
