"""Sphinx extension: what the committed regression baselines cost, read from results/baselines/.

``{baseline-costs}`` writes one row per tracked-robot baseline (``results/baselines/<name>/gains.json`` and
``summary.json``, written by ``make baselines``): the scenario's delay range and lifting, loss cap, slip box,
kinematics, turn radius, the certificate's vertices, the certified |e_y|, the time of the final solve as
recorded in the gains file, and the verdict.  The figures are those files' own, never copied by hand.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective

BASELINES = Path(__file__).resolve().parents[2] / "results" / "baselines"


def baseline_rows() -> list[dict[str, str]]:
    rows = []
    for d in sorted(BASELINES.iterdir()):
        gains, summary = d / "gains.json", d / "summary.json"
        if not gains.exists() or not summary.exists():
            continue  # infeasible: no gain (its summary says why)
        g, s = json.loads(gains.read_text()), json.loads(summary.read_text())
        if g.get("kind") == "lti":
            continue
        cfg, cert = g["config"], g["certificate"]
        slip = cfg["slip"]
        box = f"{slip['model']} [{slip['right']['min']:g}, {slip['right']['max']:g}]"
        if slip["left"] != slip["right"]:
            box += f"; [{slip['left']['min']:g}, {slip['left']['max']:g}]"
        dims = s.get("dimensions", {})
        delay = cfg["network"]["delay"]
        rows.append({
            "config": f"``{d.name}``",
            "delay": f"[{1000 * delay['min']:g}, {1000 * delay['max']:g}] ms, d_hi {dims.get('d_hi', '?')}",
            "losses": str(cfg["network"]["dropouts"]["max_consecutive"]),
            "slip": box,
            "kinematics": cfg["synthesis"]["kinematics"],
            "turns": f"{cfg['reference']['turn_radius']:g} m" if cfg["reference"].get("turn_radius") else "—",
            "vertices": str(cert.get("vertices", "?")),
            "e_y": f"{100 * s['certified']['ultimate_bound']['e_y']:.2f} cm" if s.get("certified", {}).get("ultimate_bound") else "—",
            "solve": f"{g['solver']['solve_time_s']:.1f} s",
            "verdict": "passed" if s.get("verification_passed") else "failed",
        })
    return rows


class BaselineCosts(SphinxDirective):
    def run(self) -> list[nodes.Node]:
        cols = ["config", "delay", "losses", "slip", "kinematics", "turns", "vertices", "e_y", "solve", "verdict"]
        heads = ["config", "delay (lifting)", "losses in a row", "slip box", "kinematics", "arcs", "vertices",
                 "certified \\|e_y\\|", "final solve", "verdict"]
        lines = [".. list-table::", "   :header-rows: 1", ""]
        lines += ["   * - " + heads[0]] + [f"     - {h}" for h in heads[1:]]
        for r in baseline_rows():
            lines += ["   * - " + r[cols[0]]] + [f"     - {r[c]}" for c in cols[1:]]
        node = nodes.section()
        node.document = self.state.document
        # MyST parses a directive's content as Markdown: hand it the reST in an eval-rst block
        lines = ["```{eval-rst}", *lines, "```"]
        self.state.nested_parse(StringList(lines, source="results/baselines"), self.content_offset, node)
        return node.children


def setup(app: Any) -> dict[str, Any]:
    app.add_directive("baseline-costs", BaselineCosts)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
