"""What every command prints, pinned line for line: the library calls are replaced by stubs that return
fixed results (every branch of the summaries: robot and linear plant, passed and failed, notes, witnesses,
turns, injections, exports refused), so that the whole stdout and stderr of each command is compared to
the text it printed when the formatting moved out of cli.py (issue 52).  Seconds: nothing is solved."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace as NS

import pytest
from click.testing import CliRunner

from robustsynth.cli import main
from robustsynth.results import Verdict

ROOT = Path(__file__).resolve().parents[1]
LTI = str(ROOT / "tests" / "data" / "dc-servo.yaml")
ICR = str(ROOT / "configs" / "icr-physics.yaml")
DEFAULT = str(ROOT / "configs" / "default.yaml")
TRACKS = str(ROOT / "configs" / "tracks-box.yaml")


# the certified figures of _robot_gains() and the gain of _lti_gains(), as synthesize and run print them
ROBOT_CERTIFIED = ("certified (ultimate-bound): decay rate 0.9123, |e_x| <= 1.23 cm, |e_y| <= 4.56 cm, "
                   "|e_theta| <= 0.0789 rad, |rho| <= 10.500 rad/s")
ROBOT_CERTIFIED_ALL_T = ("certified (ultimate-bound): decay rate 0.9123, |e_x| <= 1.23 cm, |e_y| <= 4.56 cm, "
                         "|e_theta| <= 0.0789 rad at the samples (for all t: |e_x| <= 1.35 cm, |e_y| <= 4.71 cm), "
                         "|rho| <= 10.500 rad/s")
LTI_GAIN = ("certified (ultimate-bound, d = 2): V+ <= 0.9500 V + 0.0500 (invariant, attracting set), |angle| <= 0.123 "
            "rad, from rest within |x| <= 1.5, inputs within |voltage| <= 12\n"
            "robust stability of this gain, delay_max: configured 0.01 s, certified at least 0.0123 s, exhibited 0.02 s "
            "(the certificate may miss 38.5 % of the exhibited margin) (witness: period 3, delays [0.01, lost, 0.02], "
            "spectral radius 1.000123)\n")


def _invoke(args: list[str]) -> tuple[int, str, str]:
    r = CliRunner().invoke(main, args)
    if r.exception is not None and not isinstance(r.exception, SystemExit):
        raise r.exception
    return r.exit_code, r.stdout, r.stderr


def _patch(monkeypatch, module: str, **names) -> None:
    import importlib

    mod = importlib.import_module(module)
    for k, v in names.items():
        monkeypatch.setattr(mod, k, v)


def _robot_gains(nonlinear: bool = False) -> dict:
    g = {"objective": "ultimate-bound",
         "certified": {"decay_rate": 0.91234, "ultimate_bound": {"e_x": 0.0123, "e_y": 0.0456, "e_theta": 0.0789},
                       "motor_speed_bound": 10.5, "hinf_gain": None},
         "notes": ["first note", "second note"]}
    if nonlinear:  # with the bounds for all t (between the samples) that a robot proof writes
        g["certificate"] = {"kinematics": "nonlinear", "heading_bound": 0.5}
        g["certified"]["ultimate_bound_between_samples"] = {"e_x": 0.0135, "e_y": 0.0471, "e_theta": 0.0789}
    return g


def _diagnosis() -> list:
    return [NS(constraint="motor limit x2", e_y=0.0312, change=-0.31, status="certified"),
            NS(constraint="slip range halved", e_y=None, change=None, status="infeasible")]


def _mc(turns: list | None = None) -> dict:
    return {"runs": 20, "ratio_to_certified": {"e_x": 0.412, "e_y": 0.733}, "turns": turns or []}


def _robot_result(passed: bool, turns: list | None = None, cfg=None):
    from robustsynth.results import CertificateCheck
    from robustsynth.robot_verification import VerificationResult

    checks = [{"name": "certificate", "passed": True},
              {"name": "monte carlo e_y", "passed": passed, "value": 0.05, "threshold": 0.04, "detail": "too far"},
              {"name": "frozen", "passed": passed, "detail": "unstable at tau 0.03"},
              {"name": "lifted", "passed": passed}]
    return VerificationResult(passed, tuple(checks), CertificateCheck(True, ()), _mc(turns), {}, {}, config=cfg)


def _lti_gains() -> dict:
    return {"objective": "ultimate-bound", "lifting": {"d": 2},
            "certified": {"disturbance_step_bound": 0.1, "alpha": 0.95, "rest_radius": 1.5,
                          "outputs": [{"name": "angle", "bound": 0.123, "unit": "rad"}, {"name": "speed", "bound": None}],
                          "inputs": [{"name": "voltage", "limit": 12.0}]},
            "network": {"delay": [0.0, 0.01]},
            "delay_margin": {"configured": 0.01, "certified": 0.0123, "exhibited": 0.02, "at_least": True,
                             "unit": "s", "note": "searched to 0.05", "searched_up_to": 0.05, "searched": "sequences",
                             "searched_periods": 2.5, "certificate_searched_up_to": 0.02, "solves": 3, "search_s": 0.1,
                             "certificate_s": 0.2,
                             "witness": {"period": 3, "delays": [0.01, None, 0.02], "spectral_radius": 1.0001234}}}


def _lti_checks(passed: bool) -> dict:
    return {"checks": [{"name": "invariance (boundary)", "passed": True, "value": 0.98, "threshold": 1.0, "detail": ""},
                       {"name": "outputs", "passed": passed, "value": 1.2, "threshold": 1.0, "detail": "angle beyond"}],
            "starts": 8, "families": [1, 2], "passed": passed, "files": ["v.json", "v.md"]}


def test_build_model(monkeypatch, tmp_path) -> None:
    st = NS(cleared=("old/other/gains.json", "old/other/report.md"), files=(Path("a/model.json"), Path("a/model.md")),
            model=NS(d_lo=0, d_hi=1, n_s=5, instants=[1, 2, 3]),
            coverage={"passed": False, "max_abs_delta": 0.12345, "max_residual": 1.2e-9})
    _patch(monkeypatch, "robustsynth.pipeline", model_stage=lambda cfg, out, path: st)
    assert _invoke(["build-model", DEFAULT, "-o", str(tmp_path / "o")]) == (0, (
        f"set aside 2 file(s) another config had left in {tmp_path / 'o'}, under {tmp_path / 'o' / 'old/other'}/ "
        "(nothing deleted): gains.json, report.md\n"
        "model 'default': d_lo=0 d_hi=1 n_s=5 uncertain instants=3 coverage=FAILED (max|Delta|=0.1235, residual=1.2e-09)\n"
        "wrote a/model.json, a/model.md\n"), "")
    lin = NS(cleared=(), files=["m.json"], model=NS(n_x=2, n_u=1, d_hi=2, n_s=4, pieces=3, arrays={"controllable": False}),
             coverage={"remainder_ratio": 0.5, "samples": 100.0, "reconstruction": 3e-12})
    _patch(monkeypatch, "robustsynth.pipeline", model_stage=lambda cfg, out, path: lin)
    code, out, err = _invoke(["build-model", LTI, "-o", str(tmp_path / "l")])
    assert (code, out.split(": ", 1)[1]) == (0, (
        "n=2 m=1 d_hi=2 n_s=4 pieces=3 coverage=ok (worst remainder / bound 0.500 on 100 instants, residual 3.0e-12)\n"
        "wrote m.json\n"))
    assert out.startswith("model '") and "' (linear plant): " in out
    assert err == "warning: plant: (A, B) is not controllable; a stabilizing gain may not exist\n"


def test_synthesize(monkeypatch, tmp_path) -> None:
    st = NS(cleared=(), gains=_robot_gains(nonlinear=True), diagnosis=_diagnosis(), files=(Path("g.json"), Path("s.md")))
    _patch(monkeypatch, "robustsynth.pipeline", synthesis_stage=lambda *a, **k: st, plant_of=lambda cfg, path: None)
    assert _invoke(["synthesize", DEFAULT, "-o", str(tmp_path)]) == (0, (
        ROBOT_CERTIFIED_ALL_T + ", for the nonlinear robot (|e_theta(t)| <= 0.5 rad)\n"
        "note: first note\nnote: second note\n"
        "where the design is stuck (one re-synthesis per relaxed constraint; see synthesis.md):\n"
        "  motor limit x2: |e_y| <= 3.12 cm (-31 %)\n  slip range halved: infeasible\n"
        "wrote g.json, s.md\n"), "")
    res = NS(cleared=(), gains=_lti_gains(), files=["g.json"], diagnosis=None)
    _patch(monkeypatch, "robustsynth.pipeline", synthesis_stage=lambda *a, **k: res, plant_of=lambda cfg, path: None)
    assert _invoke(["synthesize", LTI, "-o", str(tmp_path)]) == (0, LTI_GAIN + "wrote g.json\n", "")


def test_verify(monkeypatch, tmp_path) -> None:
    from robustsynth.config import load_config

    cfg = load_config(DEFAULT)
    turns = [{"certified": True, "waypoint": 1}, {"certified": False, "waypoint": 2, "reason": "too sharp"}]
    st = NS(result=_robot_result(False, turns, cfg), model=NS(config=cfg), figures={"a": 1, "b": 2})
    _patch(monkeypatch, "robustsynth.pipeline", verification_stage=lambda *a, **k: st, plant_of=lambda cfg, path: None,
           write_run_logs=lambda model, result, logdir: [1, 2, 3])
    o = tmp_path / "v"
    assert _invoke(["verify", DEFAULT, "-o", str(o), "--log", str(tmp_path / "logs")]) == (1, (
        "verification FAILED: 4 checks, 20 Monte Carlo runs; worst/certified: e_x 0.412, e_y 0.733\n"
        "waypoint turns (not in the verdict): 1 of 2 certified; waypoint 2: too sharp (reference.turn_radius rounds the "
        "corners into arcs the certificate can cover: docs/theory.md §10)\n"
        f"wrote {o / 'verification.json'}, {o / 'verification.md'} and 2 figures\n"
        f"wrote 3 run logs to {tmp_path / 'logs'}/\n"), (
        "FAILED: monte carlo e_y (value 0.05, threshold 0.04): too far\nFAILED: frozen: unstable at tau 0.03\n"
        "FAILED: lifted\n"))
    arcs = [{"certified": True, "note": "along an arc of radius 1"}] * 2
    st = NS(result=_robot_result(True, arcs, cfg), model=NS(config=cfg), figures={})
    _patch(monkeypatch, "robustsynth.pipeline", verification_stage=lambda *a, **k: st)
    assert _invoke(["verify", DEFAULT, "-o", str(o)]) == (0, (
        "verification passed: 4 checks, 20 Monte Carlo runs; worst/certified: e_x 0.412, e_y 0.733\n"
        "waypoint turns: 2 of 2 certified (arcs the certificate covers; the Monte Carlo maxima include them)\n"
        f"wrote {o / 'verification.json'}, {o / 'verification.md'}\n"), "")
    lin = Verdict.from_dict(_lti_checks(False))
    _patch(monkeypatch, "robustsynth.pipeline", plant_of=lambda cfg, path: None,  # one summary for every plant
           verification_stage=lambda *a, **k: NS(result=lin, data=lin.to_dict(), figures={"verification": 1}))
    assert _invoke(["verify", LTI, "-o", str(o)]) == (1, (
        "verification FAILED: 2 checks, 8 starts on the set's boundary x 2 delay families; invariance 0.98, outputs 1.2\n"
        f"wrote {o / 'verification.json'}, {o / 'verification.md'} and 1 figure\n"),
        "FAILED: outputs (value 1.2, threshold 1): angle beyond\n")


def _run_result(passed: bool, cfg) -> NS:
    return NS(model=NS(cleared=()), passed=passed,
              synthesis=NS(gains=_robot_gains(), diagnosis=None),
              verification=NS(result=_robot_result(passed, cfg=cfg), model=NS(config=cfg)))


def test_run(monkeypatch, tmp_path) -> None:
    from robustsynth.config import load_config

    cfg = load_config(DEFAULT)
    vd = {"ratio_to_certified": {"e_x": 0.5, "e_y": None, "e_theta": 0.25}, "straight_rule": "straight (away from turns)",
          "passed": False}
    _patch(monkeypatch, "robustsynth.pipeline", run=lambda *a, **k: _run_result(True, cfg),
           validation_stage=lambda *a, **k: vd)
    proof = {"proof": {"proven": "for delays up to 0.03 s", "verified": "verification passed (20 runs)"}}
    _patch(monkeypatch, "robustsynth.runtime.export", export_controller=lambda *a: (proof, [Path("x.c"), Path("x.h")]))
    o = tmp_path / "r"
    assert _invoke(["run", DEFAULT, "-o", str(o), "--physics", "3", "--export", "c"]) == (1, (
        ROBOT_CERTIFIED + "\n"
        "verification passed: 4 checks, 20 Monte Carlo runs; worst/certified: e_x 0.412, e_y 0.733\n"
        "[validate on the physics robot]\n"
        "physics robot (MuJoCo, 3 episodes, straight): observed/certified e_x 0.50, e_theta 0.25; validation FAILED\n"
        "exported (c; proven: for delays up to 0.03 s; verification: verification passed (20 runs)): x.c, x.h\n"
        f"report: {o / 'report.md'}\n"), "")
    _patch(monkeypatch, "robustsynth.pipeline", run=lambda *a, **k: _run_result(False, cfg))
    code, out, err = _invoke(["run", DEFAULT, "-o", str(o), "--export", "python"])
    assert code == 1 and out.splitlines()[-2:] == [
        f"export skipped: verification failed, so the gain is not exported as a controller (robustsynth export "
        f"{o / 'gains.json'} --to python --allow-unverified exports it marked UNVERIFIED)", f"report: {o / 'report.md'}"]
    res = NS(model=NS(cleared=()), synthesis=NS(cleared=(), gains=_lti_gains(), diagnosis=None),
             verification=NS(result=Verdict.from_dict(_lti_checks(True))), passed=True)
    _patch(monkeypatch, "robustsynth.pipeline", run=lambda *a, **k: res)  # one run for every plant
    assert _invoke(["run", LTI, "-o", str(o)]) == (0, LTI_GAIN + (
        "verification passed: 2 checks, 8 starts on the set's boundary x 2 delay families; invariance 0.98, outputs 1.2\n"
        f"report: {o / 'report.md'}\n"), "")


def test_margin(monkeypatch, tmp_path) -> None:
    """One summary for every plant's margins (issue 52): a line per margin (at least, the gap, how far a search
    went that found nothing), the report's notes, the files; its warnings on stderr; with --json, only those."""
    from robustsynth.margins import Margin, MarginReport

    delay = Margin("delay_max", "s", "max", 0.05, 0.06, 0.08, None, (0.01, 0.3))
    losses = Margin("dropouts", "packets", "max", 0, 3, None, None, (0, 3), at_least=True, families="bursts")
    rep = MarginReport((delay, losses), {"config": "x"}, ("note: one",), ("warning: two",))
    st = NS(report=rep, data=rep.to_dict(), files=(Path("margin.json"),))
    _patch(monkeypatch, "robustsynth.pipeline", margin_stage=lambda *a, **k: st)
    lines = ("delay_max: configured 0.05 s, certified 0.06 s, exhibited 0.08 s (the certificate may miss 25.0 % of the "
             "exhibited margin)\ndropouts: configured 0 packets, certified at least 3 packets, exhibited none (no "
             "instability found in [0, 3] among bursts)\nnote: one\nwrote margin.json\n")
    for config in (DEFAULT, LTI):
        assert _invoke(["margin", config, "-o", str(tmp_path)]) == (0, lines, "warning: two\n")
        code, out, err = _invoke(["margin", config, "-o", str(tmp_path), "--json"])
        assert (code, err, json.loads(out)) == (0, "warning: two\n", rep.to_dict())
    gains = ROOT / "results" / "baselines"
    assert _invoke(["margin", "--gains", str(gains / "nonlinear-proof" / "gains.json"), "-o", str(tmp_path)])[1] == (
        f"config: the one stored in {gains / 'nonlinear-proof' / 'gains.json'} ('nonlinear-proof'); pass CONFIG to take "
        "the gain's margins on another\n" + lines)
    code, out, err = _invoke(["margin", "--gains", str(gains / "nonlinear-proof" / "gains.json"), "-o", str(tmp_path),
                              "--json"])  # stdout is the JSON alone: the config's line goes to stderr
    assert json.loads(out) == rep.to_dict() and err.startswith("config: the one stored in ") and code == 0


def test_check_log_and_monitor(monkeypatch, tmp_path) -> None:
    rows = [{"assumption": "delay", "range": [0.0, 0.03], "unit": "s", "samples": 100, "outside": 3,
             "fraction_outside": 0.03, "worst": 0.041, "where": "a.csv:12"},
            {"assumption": "slip right", "range": [0.8, 1.0], "unit": "1", "samples": 50, "outside": 0,
             "fraction_outside": 0.0, "worst": None, "where": None},
            {"assumption": "icr", "range": [-0.1, 0.1], "unit": "m", "samples": 0, "pose_noise": [0.002, 0.01]}]
    _patch(monkeypatch, "robustsynth.artifacts.logs", read_log=lambda p: p)
    _patch(monkeypatch, "robustsynth.identification", check_log=lambda *a: rows)
    assert _invoke(["check-log", "a.csv", "--config", DEFAULT]) == (1, (
        "VIOLATED delay in [0, 0.03] (s): 3 of 100 outside (3.00 %), worst 0.041 at a.csv:12\n"
        "ok       slip right in [0.8, 1] (1): 0 of 50 outside (0.00 %)\n"
        "n/a      icr in [-0.1, 0.1] (m): not checked (no period of the logs says anything about it)\n"
        "check-log: 1 of 3 assumptions hold, 1 not checked (tolerance 0.5 %); pose noise assumed 0.002 m, 0.01 rad\n"), "")
    runs = [{"log": "a.csv", "alarms": [{"period": 7, "t": 0.35, "causes": "delay, slip", "by": {"delay": 0.0123}}],
             "fallback_engaged_at": 9, "fallback": "stop"},
            {"log": "b.csv", "alarms": [], "fallback_engaged_at": None, "fallback": "stop"}]
    alarm_periods = {"delay": 1, "losses": 0, "set": 0, "heading": 0, "motor": 0, "slip": 1, "rate": 0}
    res = {"runs": runs, "alarm_periods": alarm_periods, "runs_with_alarms": 1, "logs": 2}
    _patch(monkeypatch, "robustsynth.runtime.replay", monitor_files=lambda *a: res)
    assert _invoke(["monitor", "a.csv", "b.csv", "--gains", "g.json", "-o", str(tmp_path)]) == (1, (
        "a.csv: period 7 (t = 0.350 s): delay by 0.0123\n"
        "a.csv: the fallback (stop) would have engaged at period 9\n"
        f"monitor: 1 of 2 logs with alarms (periods: delay 1, slip 1); wrote {tmp_path / 'monitor.json'}\n"), "")


def _vd(passed: bool, through: bool, arcs: bool) -> dict:
    return {"straight_max": {"e_x": 0.012, "e_y": 0.034, "e_theta": 0.05},
            "certified": {"e_x": 0.02, "e_y": 0.04, "e_theta": None},
            "certificate": {"passed": True, "error_bounds": True, "model": "paper"},
            "physics": {"summary": "a 20 kg chassis"}, "through_turns": through,
            "turn_max": {"e_y": 0.1, "e_theta": 0.2}, "torque_saturated_s": 1.25,
            "straight_rule": "between the arcs" if arcs else "straight",
            "slip": {"estimated": {"right": [0.91, 0.99], "left": [0.9, 0.98]}, "inside_box": False},
            "slip_whole_episodes": {"estimated": {"right": [0.8, 0.99], "left": [0.85, 0.97]}},
            "monitor": {"alarm_periods": {"delay": 2, "slip": 0}, "runs_with_alarms": 1, "logs": 2,
                        "first_per_log": [{"period": 151, "causes": "delay"}, None]},
            "passed": passed}


def test_validate(monkeypatch, tmp_path) -> None:
    _patch(monkeypatch, "robustsynth.model", build_model=lambda cfg: None)
    _patch(monkeypatch, "robustsynth.pipeline", excitation_stage=lambda *a, **k: [1, 2, 3, 4],
           validation_stage=lambda *a, **k: _vd(False, False, False))
    _patch(monkeypatch, "robustsynth.robot_verification.physics",
           physics_config=lambda cfg: (None, {"summary": "the icr chassis"}))
    o = tmp_path / "x"
    assert _invoke(["validate", ICR, "--excite", "-o", str(o)]) == (0, (
        "physics robot (MuJoCo): the icr chassis\n"
        f"excitation (physics): 4 episodes written to {o / 'logs'}; next: robustsynth identify {o / 'logs'}/*.csv "
        f"--config {ICR} --model icr --pose-noise 0 0 --settle 1 --max-motor-speed 12.0 -o FRAGMENT.yaml\n"), "")
    assert _invoke(["validate", TRACKS, "--excite", "--engine", "kinematic", "-o", str(o)])[1] == (
        f"excitation (kinematic): 4 episodes written to {o / 'logs'}; next: robustsynth identify {o / 'logs'}/*.csv "
        f"--config {TRACKS} --max-motor-speed 12.0 -o FRAGMENT.yaml\n")
    assert _invoke(["validate", DEFAULT, "--gains", "g.json", "-o", str(o), "--inject", "delay"]) == (1, (
        "physics robot (MuJoCo): a 20 kg chassis\n"
        "the certificate is for the paper's model (synthesis.model: paper), whose slip is not this robot's: its bounds "
        "are the paper model's claims (verify judges them on the robot)\n"
        "straight segments: |e_x| 1.2 cm (certified 2, ratio 0.60), |e_y| 3.4 cm (certified 4, ratio 0.85), "
        "|e_theta| 0.05 rad\n"
        "turns (not certified): |e_y| 10 cm, |e_theta| 0.2 rad; torque-saturated up to 1.2 s per episode\n"
        "slip the engine showed on the straight segments (identify): right [0.910, 0.990], left [0.900, 0.980] — "
        "OUTSIDE the config's box\n"
        "  with the turns: right [0.800, 0.990], left [0.850, 0.970] (the turns are not certified)\n"
        "runtime monitor over the episodes: 1 of 2 with alarms (periods: delay 2)\n"
        "injected delay from period 150: the command sent at the period arrives 0.07 s after tau_max; the runtime "
        "monitor's first alarm: episode 0: "
        "period 151 (delay); episode 1: not flagged\n"
        f"validation FAILED: 4 episodes; wrote {o / 'validation.json'}\n"), "")
    vd = _vd(True, True, True)
    vd["certificate"] = {"passed": True, "error_bounds": None}
    vd["slip"]["inside_box"] = True
    vd["physics"] = vd["monitor"] = None
    _patch(monkeypatch, "robustsynth.pipeline", validation_stage=lambda *a, **k: vd)
    assert _invoke(["validate", DEFAULT, "--gains", "g.json", "-o", str(o), "--episodes", "2"]) == (0, (
        "the certificate states no error bounds (its objective proves no invariant set): the errors below are not "
        "judged, only the slip\n"
        "the whole path, turns included (against the bounds for all t): |e_x| 1.2 cm (certified 2, ratio 0.60), "
        "|e_y| 3.4 cm (certified 4, ratio 0.85), |e_theta| 0.05 rad\n"
        "torque-saturated up to 1.2 s per episode\n"
        "slip the engine showed on the straight segments (identify): right [0.910, 0.990], left [0.900, 0.980] — "
        "inside the config's box: the certificate covers it\n"
        "  with the turns: right [0.800, 0.990], left [0.850, 0.970] (with the arcs)\n"
        f"validation passed: 2 episodes; wrote {o / 'validation.json'}\n"), "")
    vd["certificate"] = {"passed": False, "detail": "no gain file"}
    vd["through_turns"] = False
    code, out, _ = _invoke(["validate", DEFAULT, "--gains", "g.json", "-o", str(o)])
    assert out.splitlines()[0] == "no certified bounds: no gain file"
    assert out.splitlines()[2] == ("arcs (certified; reported apart from the straight segments): |e_y| 10 cm, "
                                   "|e_theta| 0.2 rad; torque-saturated up to 1.2 s per episode")
    assert out.splitlines()[3].endswith("— inside the config's box")


@pytest.mark.parametrize("verified,certified", [(True, True), (False, False)])
def test_export(monkeypatch, tmp_path, verified, certified) -> None:
    d = {"certified": certified, "proof": {"proven": "P", "verified": "V",
                                           "verification": {"status": "passed" if verified else "failed"}}}
    _patch(monkeypatch, "robustsynth.runtime.export", export_controller=lambda *a, **k: (d, [Path("a.c")]))
    code, out, err = _invoke(["export", "g.json", "--to", "c", "-o", str(tmp_path)])
    assert code == 0 and out.splitlines()[-3:] == ["proven: P", "verification: V", "wrote a.c"]
    if verified:
        assert (out.count("\n"), err) == (3, "")
    else:
        assert err == ("warning: g.json: V; exported anyway (--allow-unverified), marked UNVERIFIED in the files: not a "
                       "verified controller, do not deploy it as one\n")
        assert out.splitlines()[0] == (
            "warning: g.json: no certificate that holds for this gain (none in the file, or its K, certificate or config "
            "changed after synthesis): exported as UNCERTIFIED (run `robustsynth verify --gains` on it)")


def test_sweep_and_identify(monkeypatch, tmp_path) -> None:
    sp = NS(points=lambda: [1, 2], keys=["a", "b"], mode="grid")
    res = NS(counts={"certified": 2, "infeasible": 0, "failed": 1}, rows=[1, 2, 3], engine={"kind": "local"},
             time_s=12.34, reused=2, files=[Path("sweep.csv"), Path("sweep.json")])
    _patch(monkeypatch, "robustsynth.sweeps", load_sweep=lambda spec: sp, sweep=lambda *a, **k: res)
    o = tmp_path / "s"
    assert _invoke(["sweep", "spec.yaml", "-o", str(o)]) == (0, (
        f"sweep: 3 points: 2 certified, 1 failed (local, 12.3 s, 2 read from {o / 'points'})\n"
        f"wrote sweep.csv, sweep.json and {o / 'points'}/\n"), "")
    ident = NS(logs=2, slip=NS(mu=NS(shape=(321, 2))))
    _patch(monkeypatch, "robustsynth.pipeline", identification_stage=lambda *a: (ident, "fragment: 1\n", [Path("f.yaml")]))
    assert _invoke(["identify", "a.csv"]) == (0, "fragment: 1\n", "")
    assert _invoke(["identify", "a.csv", "-o", "f.yaml"]) == (0, "identified from 2 log(s), 321 periods: wrote f.yaml\n", "")
