"""Margins of a given gain: certified <= truth <= exhibited, a witness that really destabilizes
(period product eigenvalues vs a simulation of the lifted loop), and the margin command's files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustsynth.cli import main
from robustsynth.config import config_with
from robustsynth.margins import EXHIBIT_TOL, find_instability, margin, pad_gain, witness_delays
from robustsynth.model import build_model
from robustsynth.synthesis import synthesize
from robustsynth.synthesis.analysis import analyze_stability
from robustsynth.verification.lifted import closed_loop_run

from ..conftest import BASE_CONFIG, make_config

GROWTH_RTOL = 0.01  # simulated per-step growth rate vs spectral radius^(1/p) of the period product
PERIODS = 200  # periods simulated for the growth rate


@pytest.fixture(scope="module")
def cfg():
    return make_config()


@pytest.fixture(scope="module")
def K(cfg):
    return synthesize(build_model(cfg)).K


@pytest.fixture(scope="module")
def report(cfg, K):
    return margin(cfg, K)


def _periodic(model, witness, periods):
    p = witness["period"]
    d = witness_delays(witness)  # inf: a lost packet
    steps = p * periods
    taus = d[(np.arange(steps + model.d_hi) - model.d_hi) % p][None, :]
    mu = np.asarray(witness["slip"])[np.arange(steps) % p][None, :, :]
    return taus, mu


def test_witness_growth_matches_its_spectral_radius(cfg, K) -> None:
    """A witness found well past the margin: the lifted loop driven by it grows at the rate the
    eigenvalues of its period product give (independent code paths: eigvals vs step-by-step)."""
    m = build_model(config_with(cfg, {"network.delay.max": 0.3}), min_lifting=1)
    Kp = pad_gain(K, m)
    w = find_instability(m, Kp)
    assert w is not None and w["spectral_radius"] > 1.05
    taus, mu = _periodic(m, w, PERIODS)
    xi0 = np.random.default_rng(0).normal(size=(1, m.n_s))
    xi = closed_loop_run(m, Kp, taus, mu, xi0, affine=False)
    n = np.linalg.norm(xi[0], axis=1)
    steps = xi.shape[1] - 1
    half = steps // 2  # measure the rate over the second half (transients gone)
    rate = (n[-1] / n[half]) ** (1.0 / (steps - half))
    assert rate == pytest.approx(w["spectral_radius"], rel=GROWTH_RTOL)


@pytest.mark.slow
def test_delay_margin_brackets_the_truth(cfg, K, report) -> None:
    d = report.delay_max
    assert d.configured == cfg.network.delay.max
    assert d.certified is not None and d.exhibited is not None
    assert d.configured <= d.certified <= d.exhibited
    w = d.witness
    assert max(w["delays"]) == pytest.approx(d.exhibited)  # the default link loses nothing: no nulls
    assert min(w["delays"]) >= cfg.network.delay.min - 1e-12
    assert w["spectral_radius"] > 1.0 + EXHIBIT_TOL
    # the witness is unstable on the model at tau_max = exhibited ...
    m = build_model(config_with(cfg, {"network.delay.max": d.exhibited}), min_lifting=1)
    Kp = pad_gain(K, m)
    again = find_instability(m, Kp)
    assert again is not None
    # ... and the certified end has a certificate that an independent re-run finds again
    m = build_model(config_with(cfg, {"network.delay.max": d.certified}), min_lifting=1)
    assert analyze_stability(m, pad_gain(K, m), lyapunov="common").certified
    assert d.gap is not None and 0.0 <= d.gap < 1.0


def test_slip_margin(cfg, report) -> None:
    s = report.slip_min
    assert s.configured == min(cfg.slip.right.min, cfg.slip.left.min)
    assert s.certified is not None and s.certified <= s.configured
    if s.exhibited is not None:
        assert s.exhibited <= s.certified
    else:
        assert "no instability found" in s.line()


def test_dropout_margin_and_its_witness(cfg, K, report) -> None:
    """The default gain was designed for a link that loses nothing: it is certified at 0 losses, and
    the search shows a burst it does not survive; replaying the witness on the lossy model grows."""
    d = report.dropouts
    assert d.configured == 0 and d.certified == 0
    assert d.exhibited is not None and d.exhibited >= 1
    w = d.witness
    assert any(w["lost"]) and all((x is None) == lost for x, lost in zip(w["delays"], w["lost"]))
    m = build_model(config_with(cfg, {"network.dropouts.max_consecutive": int(d.exhibited)}))
    Kp = pad_gain(K, m)
    taus, mu = _periodic(m, w, PERIODS + 2)
    xi0 = np.random.default_rng(0).normal(size=(1, m.n_s))
    xi = closed_loop_run(m, Kp, taus, mu, xi0, affine=False)[:, : w["period"] * PERIODS + 1]
    n = np.linalg.norm(xi[0], axis=1)
    steps = xi.shape[1] - 1
    half = steps // 2
    assert (n[-1] / n[half]) ** (1.0 / (steps - half)) == pytest.approx(w["spectral_radius"], rel=GROWTH_RTOL)


def test_pad_gain_is_the_same_law(cfg, K) -> None:
    """Zero columns for older inputs: identical error trajectories on the longer lifting."""
    m1 = build_model(cfg)
    m2 = build_model(cfg, min_lifting=m1.d_hi + 2)
    rng = np.random.default_rng(1)
    taus = rng.uniform(cfg.network.delay.min, cfg.network.delay.max, size=(4, 30 + m2.d_hi))
    mu = rng.uniform(0.6, 1.0, size=(4, 30, 2))
    x0 = rng.normal(scale=0.01, size=(4, m1.n_s))
    x0_long = np.concatenate([x0, np.zeros((4, m2.n_s - m1.n_s))], axis=1)
    a = closed_loop_run(m1, K, taus[:, m2.d_hi - m1.d_hi:], mu, x0)
    b = closed_loop_run(m2, pad_gain(K, m2), taus, mu, x0_long)
    np.testing.assert_allclose(a[:, :, :3], b[:, :, :3], rtol=0, atol=1e-12)


@pytest.mark.slow
def test_margin_cli_json_matches_the_file(tmp_path, cfg, K) -> None:
    gains = tmp_path / "gains.json"
    gains.write_text(json.dumps({"K": K.tolist()}))
    r = CliRunner().invoke(main, ["margin", str(BASE_CONFIG), "--gains", str(gains), "--json"])  # no -o: beside the gain
    assert r.exit_code == 0, r.output
    printed = json.loads(r.output)
    on_disk = json.loads((tmp_path / "margin.json").read_text())
    assert printed == on_disk
    for key in ("delay_max", "slip_min", "dropouts"):
        assert {"configured", "certified", "exhibited", "witness"} <= set(printed[key])
    assert printed["delay_max"]["witness"]["delays"] and printed["delay_max"]["witness"]["slip"]
    assert printed["meta"]["kinematics"] == "linearized"  # what "certified" is about, whatever the gain's certificate
    assert printed["meta"]["gains_kinematics"] is None  # a bare K: no certificate of its own


def test_margin_cli_rejects_a_gain_of_the_wrong_shape(tmp_path) -> None:
    gains = tmp_path / "gains.json"
    gains.write_text(json.dumps({"K": [[1.0, 2.0, 3.0]]}))
    r = CliRunner().invoke(main, ["margin", "--gains", str(gains), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: K has shape (1, 3)")
    assert not (tmp_path / "o" / "margin.json").exists()


@pytest.mark.slow
def test_icr_margins_per_slip_parameter() -> None:
    """slip.model icr: a margin per slip parameter (issue 24).  The ICR offset's: the certified end has a
    certificate an independent re-run finds again, and the witness (its slip holds x_icr = exhibited)
    grows on the lifted loop at the exhibited value, as its spectral radius says."""
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.config import load_config
    from robustsynth.margins.robot import _icr_margin

    root = Path(__file__).resolve().parents[2]
    cfg = load_config(root / "configs" / "icr-physics.yaml")
    K = np.asarray(load_gains(root / "results" / "baselines" / "icr-physics" / "gains.json")["K"], dtype=float)
    x = _icr_margin(cfg, K, "common", lambda _m: None, "icr_offset_max")
    assert x.name == "icr_offset_max" and x.configured == cfg.slip.icr_offset.max
    assert x.certified is not None and x.exhibited is not None
    assert x.configured <= x.certified <= x.exhibited
    assert max(c[3] for c in x.witness["slip"]) == pytest.approx(x.exhibited)
    m = build_model(config_with(cfg, {"slip.icr_offset.max": x.certified}))
    assert analyze_stability(m, K, lyapunov="common").certified
    m = build_model(config_with(cfg, {"slip.icr_offset.max": x.exhibited}))
    taus, mu = _periodic(m, x.witness, PERIODS)
    xi = closed_loop_run(m, K, taus, mu, np.random.default_rng(0).normal(size=(1, m.n_s)), affine=False)
    n = np.linalg.norm(xi[0], axis=1)
    half = (xi.shape[1] - 1) // 2
    rate = (n[-1] / n[half]) ** (1.0 / (xi.shape[1] - 1 - half))
    assert rate == pytest.approx(x.witness["spectral_radius"], rel=GROWTH_RTOL)


def test_margin_without_config_takes_the_gains_own_config() -> None:
    """`margin --gains FILE` without CONFIG had analysed any gain against the embedded default config (its
    slip range, delays, model) without a word (review): now the config stored in the file, said in one
    line; a gain made for the default config keeps it, silently."""
    from pathlib import Path

    from robustsynth.artifacts.inputs import gains_own_config
    from robustsynth.config import load_config

    root = Path(__file__).resolve().parents[2] / "results" / "baselines"
    default = load_config(None)
    cfg = gains_own_config(default, root / "nonlinear-proof" / "gains.json")
    assert cfg.name == "nonlinear-proof" and cfg.slip.right.min == 0.8
    assert gains_own_config(default, root / "default" / "gains.json") is default  # the line: test_cli_summaries


def test_margin_without_config_refuses_an_invalid_stored_config(tmp_path) -> None:
    """An unknown key in the stored config had fallen back to the default config without a word (review): now
    one line naming it, exit 2, and no margin.json."""
    from pathlib import Path

    g = json.loads((Path(__file__).resolve().parents[2] / "results" / "baselines" / "nonlinear-proof" / "gains.json").read_text())
    g["config"]["robot"]["wheel_inertia"] = 0.01
    (tmp_path / "gains.json").write_text(json.dumps(g))
    r = CliRunner().invoke(main, ["margin", "--gains", str(tmp_path / "gains.json"), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2, r.output
    assert len(r.output.strip().splitlines()) == 1 and "wheel_inertia" in r.output
    assert not (tmp_path / "o" / "margin.json").exists()


def test_a_margin_line_puts_no_unit_after_none() -> None:
    from robustsynth.margins import Margin

    m = Margin("delay_max", "s", "max", 0.05, None, 0.0848, None, None)
    assert m.line().startswith("delay_max: configured 0.05 s, certified none, exhibited 0.0848 s")


@pytest.mark.parametrize("certified,exhibited,gap,words", [
    (0.0, 1.0, 0, "the certificate misses no packet of the exhibited margin"),
    (0.0, 4.0, 3, "the certificate may miss up to 3 packets of the exhibited margin"),
    (1.0, 3.0, 1, "the certificate may miss up to 1 packet of the exhibited margin"),
])
def test_a_count_margin_says_its_gap_in_packets_never_a_share(certified, exhibited, gap, words) -> None:
    """Issue 50, item 7: the dropout margin read "exhibited 1 packets (the certificate may miss 0.0 % of the exhibited
    margin)", and "may miss 75.0 %" of 4 packets: a count says its gap in packets (the truth is a whole number in
    [certified, exhibited - 1]), singular or plural, and no share, in the line nor in margin.json."""
    from robustsynth.margins import Margin

    m = Margin("dropouts", "packets", "max", 0.0, certified, exhibited, None, (0.0, 6.0))
    line = m.line()
    assert "%" not in line and words in line, line
    assert "1 packets" not in line and "0 packet " not in line, line
    for n in (certified, exhibited):
        assert (f"{int(n)} packet" + ("" if n == 1 else "s")) in line, line
    assert m.gap is None and m.gap_packets == gap
    d = m.to_dict()
    assert d["gap"] is None and d["gap_packets"] == gap
    # a continuous margin keeps its share
    s = Margin("delay_max", "s", "max", 0.08, 0.12, 0.15, None, None)
    assert s.gap == pytest.approx(0.2) and s.gap_packets is None and "20.0 %" in s.line()


def test_margin_stage_says_what_a_nonlinear_certificate_s_margins_are(monkeypatch, tmp_path) -> None:
    """The margin stage, any plant: margin.json is the report's to_dict with the gain's source; a gain whose own
    certificate is for the nonlinear robot gets the note that the margins are of its linearization (the report's
    notes, which the CLI prints); margin.md has the table.  The search itself is replaced: this is the stage's part."""
    import json

    from robustsynth import margins, pipeline
    from robustsynth.config import load_config
    from robustsynth.margins import Margin, MarginReport

    rep = MarginReport((Margin("delay_max", "s", "max", 0.05, 0.06, 0.08, None, (0.01, 0.3)),), {"reading": "R."})
    monkeypatch.setattr(margins, "margin", lambda *a, **k: rep)
    root = Path(__file__).resolve().parents[2]
    gains = root / "results" / "baselines" / "nonlinear-proof" / "gains.json"
    st = pipeline.margin_stage(load_config(root / "configs" / "nonlinear-proof.yaml"), tmp_path, gains)
    assert st.report.notes[-1].startswith("note: the margins are robust stability of the linearization")
    data = json.loads((tmp_path / "margin.json").read_text())
    assert data == st.data and data["meta"]["gains_kinematics"] == "nonlinear" and data["meta"]["gains"] == str(gains)
    md = (tmp_path / "margin.md").read_text()
    assert md.startswith("# Margins of a gain") and "| delay_max (s) | 0.05 | 0.06 | 0.08 | 0.750 | - |" in md
