"""verify on a linear plant (docs/theory.md §15): it passes a certified design and catches false
claims — an over-stated bound, a delay range beyond the certified one — and the CLI chain
(build-model, synthesize, verify, run, margin --gains) with its exit codes and files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robustsynth.model.lti import lti_plant_from
from robustsynth.synthesis.lti import synthesize_lti
from robustsynth.verification.lti import verify_lti

RADIUS_RTOL = 1e-12  # batched against one-at-a-time products: the same matrices, rounded in another order

ROOT = Path(__file__).resolve().parents[2]
ZBP_A = np.array([[0.0, 1.0], [0.0, -0.1]])
ZBP_B = np.array([[0.0], [0.1]])
ZBP_E = np.array([[0.0], [0.1]])

CONFIG = """\
name: zbp-disturbed
plant:
  kind: lti
  A: [[0, 1], [0, -0.1]]
  B: [[0], [0.1]]
  states: [position, velocity]
  units: [m, m/s]
  disturbance: {E: [[0], [0.1]], bound: 0.5}
  input_limits: [20]
network:
  sampling_time: 0.5
  delay: {min: 0.0, max: 0.5}
"""


@pytest.fixture(scope="module")
def design():
    pl = lti_plant_from(ZBP_A, ZBP_B, E=ZBP_E, w_max=0.5, u_max=[20.0])
    return pl, synthesize_lti(pl, 0.5, 0.0, 0.5, 0, "ultimate-bound")


def test_verify_passes_a_certified_design_with_room(design) -> None:
    pl, r = design
    v = verify_lti(pl, r.K, r.P, 0.5, 0.0, 0.5, 0, r.certified, runs=24, periods=60, multipliers=r.certificate["multipliers"])
    assert v["passed"], v["checks"]
    by = {c["name"].split(" (")[0]: c["value"] for c in v["checks"]}
    assert by["the set is invariant"] < 1.0 and by["frozen-delay spectral radius"] < 1.0
    assert by["outputs within their certified bounds"] > 0.5  # the probes reach the bounds' scale


def test_verify_catches_an_understated_bound_and_refuses_nan(design) -> None:
    """A bound 10 % below the set's extent fails (the maximizers of each output are among the starts);
    a certificate with a NaN is refused, not passed."""
    from robustsynth.errors import InputError

    pl, r = design
    figs = dict(r.certified, outputs=[dict(o, bound=0.9 * o["bound"]) for o in r.certified["outputs"]])
    v = verify_lti(pl, r.K, r.P, 0.5, 0.0, 0.5, 0, figs, runs=24, periods=30, multipliers=r.certificate["multipliers"])
    assert not v["passed"]
    assert [c["passed"] for c in v["checks"] if c["name"].startswith("outputs")] == [False]
    P = r.P.copy()
    P[0, 0] = np.nan
    with pytest.raises(InputError, match="must be finite"):
        verify_lti(pl, r.K, P, 0.5, 0.0, 0.5, 0, r.certified, runs=4, periods=5, multipliers=r.certificate["multipliers"])


def test_verify_catches_delays_beyond_the_certificate() -> None:
    """A design certified for delays up to 0.1 s, checked against delays up to 0.5 s (the same lifting):
    frozen delays destabilize it and the set is left."""
    pl = lti_plant_from(ZBP_A, ZBP_B, E=ZBP_E, w_max=0.5, u_max=[20.0])
    r = synthesize_lti(pl, 0.5, 0.0, 0.1, 0, "ultimate-bound")
    v = verify_lti(pl, r.K, r.P, 0.5, 0.0, 0.5, 0, r.certified, runs=24, periods=60, multipliers=r.certificate["multipliers"])
    bad = {c["name"].split(" (")[0] for c in v["checks"] if not c["passed"]}
    assert not v["passed"] and {"the set is invariant", "frozen-delay spectral radius"} <= bad


def test_verify_catches_a_plant_the_certificate_was_not_made_for(design) -> None:
    """The gain on a plant with negative friction (still stabilized): the set is no longer invariant."""
    _, r = design
    other = lti_plant_from(np.array([[0.0, 1.0], [0.0, 0.3]]), ZBP_B, E=ZBP_E, w_max=0.5, u_max=[20.0])
    v = verify_lti(other, r.K, r.P, 0.5, 0.0, 0.5, 0, r.certified, runs=24, periods=60, multipliers=r.certificate["multipliers"])
    bad = {c["name"].split(" (")[0] for c in v["checks"] if not c["passed"]}
    assert bad == {"the certificate re-proven in numpy for this config", "the set is invariant"}


def test_verify_without_the_multipliers_proves_nothing_and_fails(design) -> None:
    """The library call re-proves the certificate first, as `robustsynth verify` does; without the
    multipliers it cannot, and simulations that pass do not make the verdict pass."""
    pl, r = design
    v = verify_lti(pl, r.K, r.P, 0.5, 0.0, 0.5, 0, r.certified, runs=8, periods=20)
    first = v["checks"][0]
    assert not v["passed"] and not first["passed"] and "multipliers" in first["detail"]
    assert all(c["passed"] for c in v["checks"][1:])  # the simulations alone would have passed
    slower = verify_lti(pl, r.K, r.P, 0.8, 0.0, 0.5, 0, r.certified, runs=8, periods=20, multipliers=r.certificate["multipliers"])
    assert not slower["checks"][0]["passed"]  # a network the certificate does not cover (Ts 0.8 s): not re-proven


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "robustsynth", *args], capture_output=True, text=True)


@pytest.mark.slow
def test_cli_chain_on_a_linear_plant(tmp_path) -> None:
    cfg = tmp_path / "zbpd.yaml"
    cfg.write_text(CONFIG)
    out = tmp_path / "out"
    r = _run("build-model", str(cfg), "-o", str(out))
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "model.json").read_text())["coverage"]["remainder_ratio"] <= 1.0
    r = _run("run", str(cfg), "-o", str(out), "--runs", "8")
    assert r.returncode == 0, r.stderr
    assert "certified (ultimate-bound" in r.stdout and "verification passed" in r.stdout
    gd = json.loads((out / "gains.json").read_text())
    assert gd["kind"] == "lti" and len(gd["K"][0]) == 3 and gd["certified"]["outputs"][0]["name"] == "position"
    for f in ("gains.mat", "synthesis.md", "verification.json", "verification.md", "report.md", "summary.json"):
        assert (out / f).exists(), f
    from scipy.io import loadmat

    assert np.allclose(loadmat(out / "gains.mat")["K"], gd["K"])
    r = _run("margin", str(cfg), "--gains", str(out / "gains.json"), "--json")
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)["delay_max"]
    assert m["certified"] >= 0.5 and (m["exhibited"] is None or m["certified"] <= m["exhibited"])
    # a robot's gains file is refused with one line
    r = _run("verify", str(cfg), "--gains", str(ROOT / "results" / "baselines" / "tracks-box" / "gains.json"), "-o",
             str(tmp_path / "v"))
    assert r.returncode == 2 and "not a linear plant's gains file" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    # ultimate-bound without a disturbance: one line, exit 2, before anything is written
    bare = tmp_path / "bare.yaml"
    no_dist = CONFIG.replace("  disturbance: {E: [[0], [0.1]], bound: 0.5}\n", "")
    bare.write_text(no_dist + "synthesis: {objective: ultimate-bound}\n")
    r = _run("synthesize", str(bare), "-o", str(tmp_path / "b"))
    assert r.returncode == 2 and "synthesis.objective" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    # no gain exists: exit 3, and the old gain files are gone
    unst = tmp_path / "unst.yaml"
    unst.write_text(CONFIG.replace("A: [[0, 1], [0, -0.1]]", "A: [[0.5, 0], [0, -0.1]]"))
    (tmp_path / "u").mkdir()
    (tmp_path / "u" / "gains.json").write_text("{}")
    r = _run("synthesize", str(unst), "-o", str(tmp_path / "u"))
    assert r.returncode == 3, r.stderr
    assert not (tmp_path / "u" / "gains.json").exists()


def test_verify_hinf_passes_and_catches_an_understated_gain() -> None:
    pl = lti_plant_from(ZBP_A, ZBP_B, E=ZBP_E, w_max=0.5, C=[[1.0, 0.0]])
    r = synthesize_lti(pl, 0.5, 0.0, 0.5, 0, "hinf")
    v = verify_lti(pl, r.K, r.P, 0.5, 0.0, 0.5, 0, r.certified, multipliers=r.certificate["multipliers"])
    assert v["passed"] and 0.3 < v["checks"][-1]["value"] < 1.0
    v = verify_lti(pl, r.K, r.P, 0.5, 0.0, 0.5, 0, dict(r.certified, hinf_gain=0.25 * r.certified["hinf_gain"]), multipliers=r.certificate["multipliers"])
    assert not v["passed"] and not v["checks"][-1]["passed"]


def test_the_gains_file_is_re_proven(design) -> None:
    """recheck_lti proves a design from its own numbers, and refuses a changed gain or a lowered bound."""
    from robustsynth.certificate.lti import recheck_lti

    pl, r = design
    gd = {"K": r.K.tolist(), "certified": r.certified,
          "certificate": {"P": r.P.tolist(), "multipliers": r.certificate["multipliers"].tolist(), "alpha": r.certificate["alpha"], "pieces": 2}}
    assert recheck_lti(pl, gd, 0.5, 0.0, 0.5, 0).passed
    changed = recheck_lti(pl, dict(gd, K=(1.2 * r.K).tolist()), 0.5, 0.0, 0.5, 0)
    assert not changed.passed and changed.reason.startswith("vertex block") and not changed.checks[0]["passed"]
    low = dict(r.certified, outputs=[dict(o, bound=0.99 * o["bound"]) for o in r.certified["outputs"]])
    assert "output bound" in recheck_lti(pl, dict(gd, certified=low), 0.5, 0.0, 0.5, 0).reason
    assert not recheck_lti(pl, gd, 0.5, 0.0, 0.5, 1).passed  # a loss it was not certified for


def test_a_linear_plants_gains_without_its_config_is_named_as_such(tmp_path) -> None:
    """Without CONFIG the robot's default config is used; with a linear plant's gains file that used to
    fail on the robot's shapes ("K: has shape (1, 3), the config's model needs (2, 5)")."""
    from click.testing import CliRunner

    from robustsynth.cli import main

    g = tmp_path / "gains.json"
    g.write_text(json.dumps({"kind": "lti", "K": [[0.0, 0.0, 0.0]]}))
    for cmd in ("verify", "margin"):
        r = CliRunner().invoke(main, [cmd, "--gains", str(g), "-o", str(tmp_path / cmd)])
        assert r.exit_code == 2, r.output
        assert r.output.strip() == f"error: --gains: {g} is a linear plant's gain (kind: lti): pass its config too " \
                                   f"(robustsynth {cmd} CONFIG --gains {g})"
        assert not (tmp_path / cmd).exists()


def test_verify_refuses_a_config_that_is_not_the_gains_plant(tmp_path) -> None:
    """A config without the disturbance the certificate is for (a traceback before), or with other
    outputs than those certified (they were checked against the wrong bounds): one line, exit 2, no
    directory; a gains.mat without CONFIG is named as a linear plant's gain."""
    from pathlib import Path

    import yaml
    from click.testing import CliRunner

    from robustsynth.cli import main
    from robustsynth.config import load_config
    from robustsynth.pipeline import plant_of, synthesis_stage

    src = Path(__file__).resolve().parents[2] / "configs" / "dc-motor.yaml"
    g = tmp_path / "g"
    synthesis_stage(plant_of(load_config(src), src), g)
    d = yaml.safe_load(src.read_text())
    nodist = dict(d, plant={k: v for k, v in d["plant"].items() if k != "disturbance"})
    one = dict(d, plant=dict(d["plant"], outputs={k: v[:1] for k, v in d["plant"]["outputs"].items()}))
    cases = [(nodist, "error: plant.disturbance: the gain's certificate is for a disturbance input"),
             (one, "error: plant.outputs: ['angle'] differ from the outputs the gain was certified for")]
    for i, (cfg, msg) in enumerate(cases):
        p = tmp_path / f"c{i}.yaml"
        p.write_text(yaml.safe_dump(cfg))
        r = CliRunner().invoke(main, ["verify", str(p), "--gains", str(g / "gains.json"), "-o", str(tmp_path / f"o{i}")])
        assert r.exit_code == 2 and r.output.startswith(msg) and len(r.output.strip().splitlines()) == 1, r.output
        assert not (tmp_path / f"o{i}").exists()
    r = CliRunner().invoke(main, ["verify", "--gains", str(g / "gains.mat"), "-o", str(tmp_path / "m")])
    assert r.exit_code == 2 and "is a linear plant's gain (kind: lti): pass its config too" in r.output


def test_verify_writes_its_figure_format_and_leaves_no_stale_one(tmp_path) -> None:
    from pathlib import Path

    from click.testing import CliRunner

    from robustsynth.cli import main
    from robustsynth.config import load_config
    from robustsynth.pipeline import plant_of, synthesis_stage

    src = Path(__file__).resolve().parents[2] / "configs" / "dc-motor.yaml"
    out = tmp_path / "g"
    synthesis_stage(plant_of(load_config(src), src), out)
    r = CliRunner().invoke(main, ["verify", str(src), "-o", str(out), "--format", "pdf"])
    assert r.exit_code == 0 and (out / "verification.pdf").is_file() and not (out / "verification.png").exists()
    gid = json.loads((out / "gains.json").read_text())["gains_id"]  # the verification names the gain it checked
    assert len(gid) == 64 and json.loads((out / "verification.json").read_text())["gains_id"] == gid
    r = CliRunner().invoke(main, ["verify", str(src), "-o", str(out), "--no-plots"])
    assert r.exit_code == 0 and not list(out.glob("verification.p*"))


def test_a_gain_of_ones_own_gets_a_certificate_searched(tmp_path) -> None:
    """K only (the benchmark's published gain): verify searches a certificate (the margin's analysis LMIs),
    proves it and checks it; beyond the delay where the gain is exhibited unstable (0.923 s) there is none:
    exit 3, no directory."""
    from pathlib import Path

    from click.testing import CliRunner

    from robustsynth.cli import main

    src = Path(__file__).resolve().parents[2] / "configs" / "zbp.yaml"
    g = tmp_path / "k.json"
    g.write_text(json.dumps({"K": [[-3.75, -11.5]]}))
    r = CliRunner().invoke(main, ["verify", str(src), "--gains", str(g), "-o", str(tmp_path / "ok"), "--no-plots"])
    assert r.exit_code == 0, r.output
    v = json.loads((tmp_path / "ok" / "verification.json").read_text())
    assert v["passed"] and v["certificate_searched"]["pieces"] == 6 and v["checks"][0]["passed"]
    assert "came without a certificate" in (tmp_path / "ok" / "verification.md").read_text()
    far = tmp_path / "far.yaml"
    far.write_text(src.read_text().replace("max: 0.5}", "max: 0.95}"))
    assert "max: 0.95}" in far.read_text()
    r = CliRunner().invoke(main, ["verify", str(far), "--gains", str(g), "-o", str(tmp_path / "no"), "--no-plots"])
    assert r.exit_code == 3 and "no certificate found for this gain" in r.output
    assert not (tmp_path / "no").exists()


def _periodic_radius_reference(A, B, K, Ts, dseq, m_lost):
    """rho(prod)^(1/p) per periodic sequence, built without the periodic window of the function under
    test: the period tiled over many periods, the switching instants of the whole tiled sequence, and the
    product of exact_closed_loop over one period in the middle (whose newest packet is the period's first)."""
    from robustsynth.core.network import s_tilde_sequence
    from robustsynth.core.delays import exact_closed_loop

    n, m = B.shape
    d = (K.shape[1] - n) // m
    out = []
    for seq in np.atleast_2d(dseq):
        p = seq.size
        k0 = (-d) % p + p  # step k's newest packet is tiled[k + d] = seq[(k + d) % p]
        R = (k0 + p + d + m_lost + 2) // p + 2
        s = s_tilde_sequence(np.tile(seq, R)[None], Ts, d)[0]
        prod = np.eye(K.shape[1])
        for k in range(k0, k0 + p):
            prod = exact_closed_loop(A, B, K, Ts, s[k]) @ prod
        out.append(float(np.max(np.abs(np.linalg.eigvals(prod)))) ** (1.0 / p))
    return np.array(out)


@pytest.mark.parametrize("m_lost,extra", [(0, 0), (2, 0), (0, 2)])
def test_the_frozen_check_is_the_plant_generic_radius(m_lost, extra) -> None:
    """The linear plant's frozen check goes through the robot's plant-generic frozen radius
    (verification.lifted.frozen_spectral_radius on a LinearPlant), against a per-sequence reference."""
    from robustsynth.core.delays import pad_lti_gain
    from robustsynth.verification.lti import CONSTANT_DELAYS, _frozen_check

    pl = lti_plant_from([[0.0, 1.0], [1.5, -0.2]], [[0.0], [1.0]])
    K = pad_lti_gain(np.array([[-4.0, -2.5]]), 2, 1, 1 + m_lost + extra)  # extra: a gain that keeps more commands
    check, trace = _frozen_check(pl, K, 0.1, 0.01, 0.09, m_lost)
    taus = np.linspace(0.01, 0.09, CONSTANT_DELAYS)[:, None]
    assert trace["delay"] == taus[:, 0].tolist()
    ref = _periodic_radius_reference(pl["A"], pl["B"], K, 0.1, taus, m_lost)
    assert np.allclose(trace["spectral_radius"], ref, rtol=RADIUS_RTOL, atol=0)
    assert check["passed"] == (max(trace["spectral_radius"]) < 1.0) and check["threshold"] == 1.0


@pytest.mark.parametrize("m_lost", [0, 1, 2])
def test_the_periodic_radius_of_any_plant_against_a_per_sequence_reference(m_lost) -> None:
    """verification.lifted.periodic_spectral_radius on a LinearPlant (what the linear margins search) =
    the product built one sequence and one period at a time, on periodic sequences with losses."""
    from robustsynth.core.network import Network
    from robustsynth.margins.linear import spectral_radius
    from robustsynth.core.delays import pad_lti_gain

    net = Network(0.1, 0.01, 0.09, m_lost)
    K = pad_lti_gain(np.array([[-4.0, -2.5]]), 2, 1, 1 + m_lost)
    pl = lti_plant_from([[0.0, 1.0], [1.5, -0.2]], [[0.0], [1.0]], K=K)
    for p in (1, 2, 3):
        rows = net.periodic(net.grid(3), p)  # every one, bursts of the cap at the period's end too
        got = spectral_radius(pl, 0.1, rows, m_lost)
        ref = _periodic_radius_reference(pl["A"], pl["B"], K, 0.1, rows, m_lost)
        assert got.shape == (len(rows),) and np.allclose(got, ref, rtol=RADIUS_RTOL, atol=0)


def test_run_takes_a_linear_plants_config(tmp_path) -> None:
    """Issue 52: ``robustsynth.run`` on a linear plant's config runs the robot's stages (build-model, synthesize,
    verify) into the RunResult the robot's run returns: its stages announced, the model with its coverage, the
    figure's format, the verdict (a Verdict: passed, failed_checks), the gain it wrote and the summary that says the
    same; the robot's options refused in one line before any work."""
    import robustsynth
    from robustsynth.errors import InputError

    cfg = robustsynth.load_config(ROOT / "configs" / "dc-motor.yaml")
    stages: list[str] = []
    res = robustsynth.run(cfg, tmp_path / "a", runs=8, fmt="svg", on_stage=stages.append)
    # the figure in the format asked for (the CLI's run on a linear plant wrote png whatever --format said)
    assert (tmp_path / "a" / "verification.svg").exists() and not (tmp_path / "a" / "verification.png").exists()
    assert stages == ["build-model", "synthesize", "verify"] and res.passed is True
    assert res.verification.result.failed_checks == [] and res.model.coverage["remainder_ratio"] <= 1.0
    assert res.model.model is res.synthesis.model and json.loads((tmp_path / "a" / "model.json").read_text())["kind"] == "lti"
    gd = json.loads((tmp_path / "a" / "gains.json").read_text())
    assert gd == res.synthesis.gains and gd["kind"] == "lti" and np.array_equal(res.synthesis.result.K, gd["K"])
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["verification"]["passed"] is True
    from robustsynth import __version__
    from robustsynth.artifacts.files import SCHEMA_VERSION

    for name in ("model.json", "gains.json", "verification.json"):  # every record says which schema and version wrote it
        data = json.loads((tmp_path / "a" / name).read_text())
        assert (data["schema_version"], data["robustsynth_version"]) == (SCHEMA_VERSION, __version__), name
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["schema_version"] == SCHEMA_VERSION
    assert {"gains.json", "verification.json", "report.md", "summary.json"} <= {p.name for p in res.files}
    for bad, match in (({"multiplier": "full"}, "^multiplier: a tracked robot's option"), ({"diagnose": True}, "^diagnose")):
        with pytest.raises(InputError, match=match):
            robustsynth.run(cfg, tmp_path / "b", **bad)
    assert not (tmp_path / "b").exists()
