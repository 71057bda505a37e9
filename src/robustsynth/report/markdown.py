"""Small Markdown helpers shared by the reports."""

from __future__ import annotations

import re
from typing import Any, Mapping, Sequence

import numpy as np

__all__ = ["fmt", "table", "matrix_table", "condition_counts", "conditions_text", "margin_table", "margin_markdown",
           "LINEAR_READING"]


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


_MEMBERS = (re.compile(r"\bat (\d+) vertex conditions?\b"), re.compile(r"\((?:multipliers, )?(\d+) vertices\)"))


def condition_counts(checks: Sequence[Mapping[str, Any]]) -> tuple[int, int, int]:
    """What a certificate's re-check (certificate.check_certificate's ``checks``) holds: (rows, LMIs,
    scalar bounds).  Each row is one family of conditions: a matrix inequality per member ("invariance
    LMI (6b) at 48 vertex conditions": 48 LMIs, "M_i > 0 (multipliers, 12 vertices)": 12, "Q > 0": 1),
    or one scalar bound (no eigenvalue: the motor speed, the heading bound).  synthesis.md and
    verification.md both count with this (issue 50: "5 conditions" in one, "108" in the other)."""
    lmis = scalars = 0
    for c in checks:
        if c.get("max_eig") is None and c.get("margin_found") is None:
            scalars += 1
            continue
        name = str(c.get("name", ""))
        for pat in _MEMBERS:
            m = pat.search(name)
            if m:
                lmis += int(m.group(1))
                break
        else:
            lmis += 1
    return len(checks), lmis, scalars


def conditions_text(checks: Sequence[Mapping[str, Any]], rows_of: str = "synthesis.md's certificate check") -> str:
    """'145 LMIs in 4 families and 2 scalar bounds (the 6 rows of ...)': the same count in synthesis.md and
    verification.md (:func:`condition_counts`)."""
    rows, lmis, scalars = condition_counts(checks)
    families = rows - scalars
    out = f"{lmis} LMI{'s' if lmis != 1 else ''} in {families} famil{'ies' if families != 1 else 'y'}"
    if scalars:
        out += f" and {scalars} scalar bound{'s' if scalars != 1 else ''}"
    return out + f" (the {rows} row{'s' if rows != 1 else ''} of {rows_of})"


def margin_table(margins: Mapping[str, Mapping[str, Any]], reading: str) -> list[str]:
    """The margins' table (configured, certified, exhibited, their ratio, the witness), their notes and ``reading``
    (what certified and exhibited mean for the plant), from margin.json's entries (``Margin.to_dict``) or a linear
    gain's ``delay_margin`` record: the keys configured, certified, exhibited, unit, at_least, witness, note."""
    md = ["| margin | configured | certified | exhibited | certified / exhibited | witness |\n|---|---|---|---|---|---|\n"]
    for name, mg in margins.items():
        ratio = (f"{mg['certified'] / mg['exhibited']:.3f}" if mg["certified"] is not None and mg["exhibited"]
                 and mg.get("unit") != "packets" else "-")  # a ratio of a few packets says nothing (Margin.gap)
        w = mg["witness"]
        delays = ", ".join("lost" if x is None else fmt(x) for x in w["delays"]) if w else ""
        wtxt = (f"period {w['period']}: delays [{delays}], spectral radius {w['spectral_radius']:.6f}" if w else "-")
        at_least = "≥ " if mg.get("at_least") else ""
        unit = f" ({mg['unit']})" if mg.get("unit") else ""
        md.append(f"| {name}{unit} | {fmt(mg['configured'])} | {at_least}{fmt(mg['certified'])} | "
                  f"{fmt(mg['exhibited'])} | {ratio} | {wtxt} |\n")
    notes = [f"- {name}: {mg['note']}\n" for name, mg in margins.items() if mg.get("note")]
    if notes:
        md.append("\n" + "".join(notes))
    md.append(f"\n{reading}\n")
    return md


def margin_markdown(data: Mapping[str, Any]) -> str:
    """margin.md: a gain's margins (margin.json, ``MarginReport.to_dict`` with the stage's meta), any plant."""
    meta = data["meta"]
    net = meta.get("network")
    md = [f"# Margins of a gain\n\nConfig {meta.get('config')}"
          + (f", gains {meta['gains']}" if meta.get("gains") else "")
          + (f": Ts = {net['sampling_time']:g} s, delays [{net['delay'][0]:g}, {net['delay'][1]:g}] s, "
             + (f"up to {net['max_consecutive']} commands lost in a row" if net["max_consecutive"] else "no command lost")
             if net else "") + ".\n\n"]
    return "".join(md + margin_table({k: v for k, v in data.items() if k != "meta"}, meta.get("reading", "")))


# what a linear plant's certified and exhibited margins are (margin.md, and the synthesis report's delay margin)
LINEAR_READING = ("Certified: a common quadratic Lyapunov function of the guaranteed over-approximation (docs/theory.md "
                  "§14), proven in numpy. Exhibited: a destabilizing periodic delay/loss sequence of the exactly lifted "
                  "closed loop.")
