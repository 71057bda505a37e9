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
from generated import parsed
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
        return parsed(self, lines, "results/baselines", rst=True)


def _kind(v: Any) -> str:
    if isinstance(v, dict):
        return "object"
    if isinstance(v, list):
        depth, x = 0, v
        while isinstance(x, list) and x:
            depth, x = depth + 1, x[0]
        return "matrix" if depth >= 2 else "list"
    return {bool: "bool", int: "number", float: "number", str: "string", type(None): "null"}[type(v)]


def json_key_lines(data: dict[str, Any], depth: int = 2, indent: str = "") -> list[str]:
    """A nested list of a JSON document's keys with the kind of each value, to ``depth`` levels."""
    out = []
    for k, v in data.items():
        out.append(f"{indent}- ``{k}``: {_kind(v)}")
        if isinstance(v, dict) and depth > 1 and v:
            out += [""] + json_key_lines(v, depth - 1, indent + "  ") + [""]
    return out


class JsonKeys(SphinxDirective):
    """``{json-keys} results/...json``: the keys of a committed JSON file (path from the repository's root)."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        path = BASELINES.parents[1] / self.arguments[0]
        self.env.note_dependency(str(path))
        return parsed(self, json_key_lines(json.loads(path.read_text())), str(path), rst=True)


CONFIGS = BASELINES.parents[1] / "configs"


def _header(text: str) -> str:
    """The comment lines a config file starts with, as one paragraph (what the scenario is)."""
    out = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        out.append(line.lstrip("#").strip())
    return " ".join(x for x in out if x)


def _outcome(name: str) -> str:
    """What the committed baseline of config ``name`` says: its certified figures and verdict, or why it has none."""
    d = BASELINES / name
    if not (d / "summary.json").exists():
        return "no committed baseline"
    s = json.loads((d / "summary.json").read_text())
    if s.get("message"):
        return f"{s.get('status', 'no certificate')}: {s['message']}"
    if s.get("status") == "lti-margins":
        m = s["margins"]["delay_max"]
        return (f"its gain's delay margin: certified {m['certified']:.4g} s, exhibited {m['exhibited']:.4g} s "
                f"(configured {m['configured']:g} s)")
    ub = (s.get("certified") or {}).get("ultimate_bound") or {}
    g = json.loads((d / "gains.json").read_text()) if (d / "gains.json").exists() else {}
    if g.get("kind") == "lti":
        figs = ", ".join(f"\\|{k}\\| ≤ {v:.4g}" for k, v in ub.items())
        proven = "for the linear plant"
    else:
        figs = ", ".join(f"\\|{k}\\| ≤ {100 * v:.2f} cm" if k != "e_theta" else f"\\|{k}\\| ≤ {v:.3g} rad"
                         for k, v in ub.items() if isinstance(v, (int, float)))
        kin = ((g.get("config") or {}).get("synthesis") or {}).get("kinematics")
        proven = {"nonlinear": "for the nonlinear robot", "linearized": "for the linearization only"}.get(kin, "")
    verdict = ("verification passed" if s.get("verification_passed") else
               "verification FAILED" + (f" ({', '.join(s['failed_checks'])})" if s.get("failed_checks") else ""))
    return f"certified {proven}: {figs or 'stability'}; {verdict}"


class ConfigGallery(SphinxDirective):
    """``{config-gallery}``: every committed config of configs/ as an example — what it is (its own header
    comment), what its committed baseline certifies and whether its verification passed, the command that
    reproduces it and the file itself (folded).  Read from the files at build time, never copied by hand."""

    def run(self) -> list[nodes.Node]:
        lines: list[str] = []
        for path in sorted(CONFIGS.glob("*.yaml")):
            self.env.note_dependency(str(path))
            text = path.read_text()
            name = path.stem
            lines += ["```{rubric} " + name, "```", "", _header(text) or "(no description)", "",
                      f"**Committed result** (`results/baselines/{name}/`): {_outcome(name)}.", "",
                      "```sh", f"robustsynth run configs/{name}.yaml", "```", "",
                      f":::{{admonition}} configs/{name}.yaml", "", "```yaml", text.rstrip("\n"), "```", ":::", ""]
        return parsed(self, lines, str(CONFIGS))


def setup(app: Any) -> dict[str, Any]:
    app.add_directive("config-gallery", ConfigGallery)
    app.add_directive("baseline-costs", BaselineCosts)
    app.add_directive("json-keys", JsonKeys)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
