"""verification.md and report.md (report/verification.py): the waypoint-turn bounds that say nothing say so, the
certificate's conditions are counted as synthesis.md counts them, and report.md shows each figure once (issue 50,
items 7 and 8)."""

from __future__ import annotations

import copy
import math
import re
from dataclasses import replace

import pytest

from robustsynth.artifacts.gains import load_gains
from robustsynth.config import config_with
from robustsynth.verification.checks import verify

from ..conftest import ROOT, committed_gain

GAINS = ROOT / "results" / "baselines" / "tracks-box" / "gains.json"
THETA = "certified peak |e_theta| at the samples [rad]"
EY = "certified peak |e_y| at the samples [cm]"
RHO = "certified peak |rho| [rad/s]"


@pytest.fixture(scope="module")
def polyline():
    """tracks-box's committed gain verified on 4 runs (the adversary left out): a polyline path with two waypoint
    turns, neither certified (their motor peak exceeds robot.max_motor_speed)."""
    m, _, _ = committed_gain("tracks-box")
    m = replace(m, config=config_with(m.config, {"verification.adversarial_runs": 0}))
    return m, verify(m, load_gains(GAINS), runs=4)


def _cells(line: str) -> list[str]:
    """A Markdown table row's cells ('|' inside a cell is escaped), unescaped."""
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]


def _table(text: str, column: str) -> list[dict[str, str]]:
    """The rows of the table whose header has ``column``, as dicts."""
    lines = text.splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.startswith("|") and column in _cells(ln))
    header = _cells(lines[i])
    rows = []
    for ln in lines[i + 2:]:
        if not ln.startswith("|"):
            break
        rows.append(dict(zip(header, _cells(ln))))
    return rows


def _number(cell: str) -> float | None:
    """The cell as a plain number, None if it is not one (e.g. "no bound (...)", "37.4 (exceeds ...)")."""
    try:
        return float(cell)
    except ValueError:
        return None


def test_turn_bounds_that_say_nothing_print_no_bound_not_a_number(polyline) -> None:
    """Issue 50, item 7: the turn table printed |e_theta| 5.56 and 6.51 rad, |e_y| 61.3 cm, |rho| 150 rad/s as
    certified peaks.  A heading bound >= pi says nothing (every heading error is within pi after wrapping), a
    cross-track bound above half the shortest segment says nothing about which segment the robot follows: both
    print "no bound" and why; a motor peak above robot.max_motor_speed keeps its number, marked as beyond the
    limit, never as a plain certified figure.  Bounds that do say something stay numbers."""
    from robustsynth.report.verification import nonlinear_markdown

    m, res = polyline
    cfg = m.config
    lim = cfg.robot.max_motor_speed
    wp = cfg.reference.path
    half = 0.5 * min(math.dist(a, b) for a, b in zip(wp, wp[1:]))  # [m]
    assert lim is not None and half is not None and half < 10.0

    mc = copy.deepcopy(res.monte_carlo)
    assert len(mc["turns"]) == 2
    big, small = mc["turns"]
    big["peak"] = {"e_x": 1.0, "e_y": 2.0 * half, "e_theta": 6.51}  # all beyond what a bound can say
    big["motor_speed_peak"] = 150.0
    small["peak"] = {"e_x": 0.01, "e_y": 0.02, "e_theta": 0.3}  # say something
    small["motor_speed_peak"] = 0.5 * lim
    text = nonlinear_markdown(cfg, mc)
    rows = _table(text, THETA)
    assert len(rows) == 2
    r_big, r_small = rows
    for col in (THETA, EY):  # no number in a column whose bound says nothing
        assert _number(r_big[col]) is None and r_big[col].startswith("no bound"), r_big[col]
    assert "pi" in r_big[THETA]
    assert "half the shortest segment" in r_big[EY] and f"{half:.3g} m" in r_big[EY]
    assert _number(r_big[RHO]) is None and r_big[RHO].startswith("150") and f"{lim:g} rad/s limit" in r_big[RHO]
    assert _number(r_small[THETA]) == pytest.approx(0.3, rel=1e-3)  # rel: 3 significant digits printed
    assert _number(r_small[EY]) == pytest.approx(2.0, rel=1e-3)
    assert _number(r_small[RHO]) == pytest.approx(0.5 * lim, rel=1e-3)
    # every heading figure left as a number is below pi, every motor figure left plain within the limit
    for r in rows:
        assert _number(r[THETA]) is None or _number(r[THETA]) < math.pi
        assert _number(r[RHO]) is None or _number(r[RHO]) <= lim
    assert "In the table above, a heading bound of pi rad or more says nothing" in text

    # the real turns of this gain: their motor peak (37.4 rad/s) exceeds the 12 rad/s limit, their other
    # bounds say something
    for t, r in zip(res.monte_carlo["turns"], _table(nonlinear_markdown(cfg, res.monte_carlo), THETA)):
        assert t["motor_speed_peak"] > lim
        assert _number(r[RHO]) is None and "limit" in r[RHO]
        assert _number(r[THETA]) is not None and _number(r[EY]) is not None


def test_arc_turn_bounds_follow_the_same_rules(polyline) -> None:
    """The turn table of a path rounded by arcs renders its bounds with the same rules."""
    from robustsynth.report.verification import nonlinear_markdown

    m, res = polyline
    cfg = config_with(m.config, {"reference.turn_radius": 5.0})
    mc = copy.deepcopy(res.monte_carlo)
    for t in mc["turns"]:
        t["peak"] = {"e_x": 0.1, "e_y": 0.05, "e_theta": 4.0}
        t["motor_speed_peak"] = 150.0
    rows = _table(nonlinear_markdown(cfg, mc), "certified |e_theta| for all t [rad]")
    assert rows and all(r["certified |e_theta| for all t [rad]"].startswith("no bound") for r in rows)
    assert all(_number(r[RHO]) is None and "limit" in r[RHO] for r in rows)


def test_verification_and_synthesis_count_the_certificate_conditions_alike(polyline) -> None:
    """Issue 50, item 7: verification.md said "5 conditions" (the families the re-check has) where synthesis.md
    said "108" (the LMIs of one family) for the same gain.  Both now give the same count, naming what it counts:
    LMIs, their families, and scalar bounds."""
    from robustsynth.report.verification import verification_dict, verification_markdown

    m, res = polyline
    cert = load_gains(GAINS)["certificate"]
    # this gain: Q > 0, the invariance LMI at 12 and at 768 vertex conditions, the motor-speed bound
    rows = len(cert["checks"])
    scalars = sum(1 for c in cert["checks"] if c.get("margin_found") is None)
    lmis = 1 + sum(int(n) for c in cert["checks"] for n in re.findall(r"at (\d+) vertex condition", c["name"]))
    assert (rows, scalars) == (4, 1) and lmis == 781
    count = re.compile(r"(\d+) LMIs in (\d+) famil(?:y|ies)(?: and (\d+) scalar bounds?)?")
    said = {}
    text = verification_markdown(m, res, verification_dict(m, res, "gains.json", "0" * 64))
    (row,) = [r for r in _table(text, "detail") if r["check"] == "certificate: LMIs re-checked in numpy"]
    said["verification.md"] = count.search(row["detail"])
    assert said["verification.md"], row["detail"]
    from robustsynth.report.synthesis import certificate_check_markdown

    said["synthesis.md"] = count.search(certificate_check_markdown(cert))
    assert all(said.values()), said
    got = {k: (int(v[1]), int(v[2]), int(v[3] or 0)) for k, v in said.items()}
    assert got["verification.md"] == got["synthesis.md"] == (lmis, rows - scalars, scalars), got
    assert not re.search(rf"\b{rows} conditions\b", row["detail"])  # no bare count of families left


def test_report_shows_each_figure_once(polyline) -> None:
    """Issue 50, item 8: report.md listed the figures, then showed the same figures again.  Each figure appears
    once in report.md and in verification.md, lyapunov.png with the caption its one-line title leaves out."""
    from robustsynth.report import plots
    from robustsynth.report.verification import report_markdown, verification_dict, verification_markdown

    m, res = polyline
    gains = load_gains(GAINS)
    vd = verification_dict(m, res, "gains.json", "0" * 64)
    figures = {name: f"figures/{name}.png" for name in plots.FIGURES}
    for text in (report_markdown(m, gains, vd, figures), verification_markdown(m, res, vd, figures)):
        for rel in figures.values():
            assert text.count(f"({rel})") == 1, (rel, text.count(f"({rel})"))
        assert plots.FIGURE_CAPTIONS["lyapunov"] in text
