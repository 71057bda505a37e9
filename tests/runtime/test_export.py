"""robustsynth export: C99 (compiled with the system compiler), the pure-Python module, ROS 2
parameters and JSON, each against runtime.Controller on random poses across segment switches."""

from __future__ import annotations

import ast
import importlib.util
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from robustsynth.runtime import Controller
from robustsynth.runtime.export import export_controller
from robustsynth.plants.path import make_path

ROOT = Path(__file__).resolve().parents[2]
GAINS = sorted(p for p in (ROOT / "results" / "baselines").glob("*/gains.json")
               if json.loads(p.read_text()).get("kind") != "lti")  # the robot's (a linear plant's: test_linear_law)
# the slip-compensated law's (docs/theory.md §18): its C99 and ROS 2 forms carry the compensator
COMPENSATED = [p for p in GAINS if json.loads(p.read_text()).get("compensation") is not None]
EXPORT_TOL = 1e-12  # generated controller vs Controller.step (issue 11)
STEPS = 10_000  # random steps per gain (issue 11: >= 10 000, including segment switches)
CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")


def _episodes(ctl: Controller, seed: int):
    """STEPS (t, x, y, theta) in episodes along the whole path (reset between them): measured poses
    a few cm / degrees around the desired pose, with now and then a large error."""
    rng = np.random.default_rng(seed)
    path = make_path(ctl.description["path"], ctl.V, ctl.description.get("turn_radius"), ctl.Ts)
    n = int(path.duration / ctl.Ts) + 30
    rows: list[tuple[float, ...] | None] = []
    while len([r for r in rows if r is not None]) < STEPS:
        rows.append(None)  # reset
        scale = rng.choice([0.01, 0.05, 0.5])
        for k in range(n):
            t = k * ctl.Ts
            q = path.desired_pose(t) + rng.normal(0.0, scale, 3) * [1.0, 1.0, 2.0]
            rows.append((float(t), *map(float, q)))
    return rows


def _reference(ctl: Controller, rows) -> np.ndarray:
    out = []
    for r in rows:
        if r is None:
            ctl.reset()
        else:
            out.append(ctl.step(*r))
    return np.array(out)


def _crosses_waypoints(ctl: Controller, rows) -> bool:
    """The steps pass a waypoint: a segment switch, or on a path rounded by arcs, both arcs' yaw rates."""
    if ctl.path.turning:
        w = {ctl.law.feedforward(r[0]) for r in rows if r}
        return max(w) > 0.0 > min(w) and 0.0 in w
    return len({ctl.path.t_start.index(max(s for s in ctl.path.t_start if s <= r[0] + 1e-12)) for r in rows if r}) > 1


def test_the_compensated_law_exports_to_c_and_ros2_with_its_compensator(tmp_path: Path) -> None:
    """The committed compensated gain exports to C99 and ROS 2 (once refused): rs_monitor.h declares the compensated
    step (tests/runtime/test_export_monitor.py compares it with Compensator.step) and rs_controller.h says to send
    through it, the ROS 2 parameters carry the compensation, flat and without null; an uncompensated gain's files have
    none of it."""
    assert [p.parent.name for p in COMPENSATED] == ["harsh-compensated"]
    plain = ROOT / "results" / "baselines" / "default" / "gains.json"
    for gains, compensated in ((COMPENSATED[0], True), (plain, False)):
        out = tmp_path / gains.parent.name
        export_controller(gains, "c", out / "c", allow_unverified=True)
        export_controller(gains, "ros2", out / "ros2", allow_unverified=True)
        h = (out / "c" / "rs_monitor.h").read_text()
        assert ("int rs_compensator_step(" in h and "void rs_monitor_suspend(" in h) == compensated
        assert ("rs_compensator_step" in (out / "c" / "rs_controller.h").read_text()) == compensated
        assert ("SATURATION_LIMIT" in (out / "c" / "rs_monitor.c").read_text()) == compensated
        p = yaml.safe_load((out / "ros2" / "rs_controller.ros2.yaml").read_text())["robustsynth_controller"]["ros__parameters"]
        assert all(v is not None for v in p.values()) and not any(isinstance(v, list) and not v for v in p.values())
        if not compensated:
            assert not any(k.startswith("compensation") or "saturation" in k for k in p)
            continue
        d = json.loads(gains.read_text())
        assert p["has_compensation"] and p["compensation_error"] == d["compensation"]["error"]
        box = d["config"]["slip"]
        assert p["compensation_box"] == [box["right"]["min"], box["right"]["max"], box["left"]["min"], box["left"]["max"]]
        assert p["compensation_lag"] > 0.0
        assert p["monitor_has_saturation_limit"] and p["monitor_saturation_limit"] == 12.0
        assert p["monitor_rho_limit"] == pytest.approx(12.0 * 0.6, rel=1e-15)


@pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on this machine")
@pytest.mark.parametrize("gains", GAINS, ids=lambda p: p.parent.name)
def test_c_export_compiles_strictly_and_reproduces_the_commands(gains: Path, tmp_path: Path) -> None:
    _, files = export_controller(gains, "c", tmp_path, allow_unverified=True)  # the code, whatever the verdict
    # the law and, for a gain with a certified set, its runtime monitor (tests/runtime/test_export_monitor.py)
    assert {p.name for p in files} == {"rs_controller.h", "rs_controller.c", "rs_harness.c", "rs_monitor.h", "rs_monitor.c",
                                       "rs_monitor_harness.c"}
    for name, own in (("rs_controller.c", "rs_controller.h"), ("rs_monitor.c", "rs_monitor.h")):
        src = (tmp_path / name).read_text()
        assert "malloc" not in src and [ln for ln in src.splitlines() if ln.startswith("#include")] == [
            "#include <math.h>", f'#include "{own}"']
    exe = tmp_path / "rs_harness"
    subprocess.run([CC, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O2", "-o", str(exe),
                    str(tmp_path / "rs_harness.c"), str(tmp_path / "rs_controller.c"), "-lm"], check=True,
                   capture_output=True, text=True)
    ctl = Controller.from_files(gains)
    rows = _episodes(ctl, seed=len(gains.parent.name))
    assert _crosses_waypoints(ctl, rows)
    text = "".join("reset\n" if r is None else "%r %r %r %r\n" % r for r in rows)
    out = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True).stdout
    got = np.array([[float(v) for v in ln.split()] for ln in out.splitlines()])
    want = _reference(ctl, rows)
    assert got.shape == want.shape and got.shape[0] >= STEPS
    assert np.max(np.abs(got - want)) <= EXPORT_TOL


@pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on this machine")
def test_c_export_of_a_turning_path_has_no_undefined_behaviour_for_a_bad_time(tmp_path: Path) -> None:
    """A NaN or infinite t: the table index is clamped before its conversion to an integer (which would
    be undefined behaviour), and the command is NaN.  Compiled with the float-cast sanitizer, which
    traps on the conversion (the export before this fix stopped with 'nan is outside the range')."""
    gains = ROOT / "results" / "baselines" / "turns" / "gains.json"
    export_controller(gains, "c", tmp_path)
    exe = tmp_path / "rs_harness"
    built = subprocess.run([CC, "-std=c99", "-O2", "-fsanitize=float-cast-overflow", "-fno-sanitize-recover=all", "-o",
                            str(exe), str(tmp_path / "rs_harness.c"), str(tmp_path / "rs_controller.c"), "-lm"],
                           capture_output=True, text=True)
    if built.returncode != 0:
        pytest.skip(f"the compiler has no float-cast sanitizer: {built.stderr.strip()[:200]}")
    for t in ("nan", "inf", "-inf"):
        r = subprocess.run([str(exe)], input=f"{t} 0 0 0\n", capture_output=True, text=True)
        assert r.returncode == 0 and "runtime error" not in r.stderr, (t, r.stderr)
        assert all(np.isnan(float(v)) for v in r.stdout.split()), (t, r.stdout)


@pytest.mark.parametrize("gains", GAINS, ids=lambda p: p.parent.name)
def test_python_export_is_dependency_free_and_reproduces_the_commands(gains: Path, tmp_path: Path) -> None:
    export_controller(gains, "python", tmp_path, allow_unverified=True)  # the code, whatever the verdict
    f = tmp_path / "rs_controller.py"
    tree = ast.parse(f.read_text())
    imported = {a.name.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.Import) for a in node.names}
    imported |= {(node.module or ".").split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert imported <= {"math", "bisect"}
    spec = importlib.util.spec_from_file_location(f"rs_controller_{gains.parent.name.replace('-', '_')}", f)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    ctl = Controller.from_files(gains)
    rows = _episodes(ctl, seed=7)
    exported = mod.Controller()
    got = np.array([exported.step(*r) if r is not None else (exported.reset() or (np.nan, np.nan)) for r in rows])
    got = got[~np.isnan(got[:, 0])]
    assert np.max(np.abs(got - _reference(ctl, rows))) <= EXPORT_TOL
    assert exported.motor_speeds(0.5, 0.1) == ctl.motor_speeds(0.5, 0.1)


def test_ros2_and_json_carry_the_controller(tmp_path: Path) -> None:
    gains = ROOT / "results" / "baselines" / "delay-multi-period" / "gains.json"
    ctl = Controller.from_files(gains)
    export_controller(gains, "ros2", tmp_path, allow_unverified=True)  # the parameters, whatever the verdict
    export_controller(gains, "json", tmp_path, allow_unverified=True)
    p = yaml.safe_load((tmp_path / "rs_controller.ros2.yaml").read_text())["robustsynth_controller"]["ros__parameters"]
    d = json.loads((tmp_path / "rs_controller.json").read_text())
    assert d.pop("proof")["verification"]["status"] == "failed"  # what it is proven for, and its verdict (issue 50)
    assert p["verified"] is False and "UNVERIFIED" in p["proof"]
    assert d == json.loads(json.dumps(ctl.description))
    K = np.array(p["K"]).reshape(p["K_rows"], p["K_cols"])
    assert np.array_equal(K, np.array(ctl.description["K"]))  # floats round-trip exactly
    assert p["d_hi"] == ctl.d_hi == 3 and p["sampling_time"] == ctl.Ts and p["has_motor_limit"]
    assert [list(xy) for xy in zip(p["path_x"], p["path_y"])] == ctl.description["path"]
    assert all(v is not None for v in p.values())  # ROS 2 parameters have no null
    # nor an empty list, which a params file cannot type (ros2/rclcpp#1955): no turn radius, no reference table
    assert not p["has_turn_radius"] and not any(isinstance(v, list) and not v for v in p.values())
    assert "ref_x" not in p


def test_export_cli_writes_atomically_and_refuses_bad_input(tmp_path: Path) -> None:
    gains = ROOT / "results" / "baselines" / "tracks-box" / "gains.json"
    run = lambda *a: subprocess.run([sys.executable, "-m", "robustsynth", "export", *a], capture_output=True, text=True)
    r = run(str(gains), "--to", "c", "-o", str(tmp_path / "c"), "--allow-unverified")  # its verification failed
    assert r.returncode == 0 and "rs_controller.h" in r.stdout
    r = run(str(gains), "--to", "fortran", "-o", str(tmp_path / "f"))
    assert r.returncode == 2 and not (tmp_path / "f").exists()
    bad = tmp_path / "bad.json"
    bad.write_text('{"K": [[1, 2]]}')
    r = run(str(bad), "--to", "c", "-o", str(tmp_path / "bad"))
    assert r.returncode == 2 and r.stderr.startswith("error: K: has 2") is False and "K: has 1 x 2 entries" in r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "bad").exists()
    # a gain without a certificate is exported with a warning
    g = json.loads(gains.read_text())
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps({"K": g["K"], "config": g["config"]}))
    r = run(str(plain), "--to", "json", "-o", str(tmp_path / "plain"), "--allow-unverified")  # never verified
    assert r.returncode == 0 and "no certificate" in r.stdout


def test_a_gain_changed_after_synthesis_is_exported_as_uncertified(tmp_path: Path) -> None:
    """A gains file whose K was edited no longer matches its gains_id: its "certified" figures are not this
    gain's, so the export says UNCERTIFIED and carries no figures (a review found an edited K exported as "the
    certified controller"); the file as written stays certified.  (A verified baseline: the edited one is no
    longer the gain its record verified, so it needs allow_unverified.)"""
    src = ROOT / "results" / "baselines" / "icr-physics" / "gains.json"
    d, _ = export_controller(src, "c", tmp_path / "ok")
    assert d["certified"] and "the certified networked-robot controller" in (tmp_path / "ok" / "rs_controller.h").read_text()
    g = json.loads(src.read_text())
    g["K"][0][0] += 5.0
    (tmp_path / "edited.json").write_text(json.dumps(g))
    for target, name in (("c", "rs_controller.h"), ("python", "rs_controller.py")):
        d, _ = export_controller(tmp_path / "edited.json", target, tmp_path / target, allow_unverified=True)
        text = (tmp_path / target / name).read_text()
        assert not d.get("certified") and "UNCERTIFIED" in text and "gains_id (none)" in text
        assert "UNVERIFIED" in text and "Proven: nothing: no certificate that holds for this gain" in text


def test_a_rate_bounded_certificates_gains_mat_exports_as_certified(tmp_path: Path) -> None:
    """A slip-rate-bounded certificate holds for its slip step only: the .mat keeps the step, so the export's
    re-check of the .mat certifies it as the .json does (a review found it UNCERTIFIED from the .mat)."""
    from robustsynth import build_model, load_config
    from robustsynth.pipeline import synthesis_stage

    cfg = load_config(ROOT / "configs" / "tracks-box.yaml")
    cfg = cfg.model_copy(update={"slip": cfg.slip.model_copy(update={"max_rate": 0.5}),
                                 "synthesis": cfg.synthesis.model_copy(update={"lyapunov": "slip-dependent",
                                                                               "alpha_points": 5})})
    synthesis_stage(build_model(cfg), tmp_path / "g", compare=False)
    d_json, _ = export_controller(tmp_path / "g" / "gains.json", "python", tmp_path / "j", allow_unverified=True)
    d_mat, _ = export_controller(tmp_path / "g" / "gains.mat", "python", tmp_path / "m", allow_unverified=True)
    assert d_json["certified"] and d_mat["certified"]
    assert d_mat["certified"]["ultimate_bound"] == pytest.approx(d_json["certified"]["ultimate_bound"], rel=1e-9)


# ------------------------------------------------------------------ what the export says the gain is proven for (issue 50)

def _cli(*args: str):
    from click.testing import CliRunner

    from robustsynth.cli import main

    return CliRunner().invoke(main, list(args))


def _copy(name: str, dest: Path) -> Path:
    """A baseline's gains.json alone in ``dest`` (no verification record beside it)."""
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "results" / "baselines" / name / "gains.json", dest / "gains.json")
    return dest / "gains.json"


def _record(passed: bool, gid: str) -> str:
    """A verification.json as `robustsynth verify` writes it, with the fields export reads."""
    return json.dumps({"schema_version": 1, "passed": passed, "gains_file": "gains.json", "gains_id": gid,
                       "config": {"name": "x"}, "checks": []})


def test_a_gain_whose_verification_failed_is_refused(tmp_path: Path) -> None:
    """The tracks-box baseline failed verification (its run's summary.json says so, and a verification.json
    beside it too): export refuses it with exit 1 and one line naming the file and the remedy, and writes
    nothing (it had been exported as "the certified controller")."""
    from robustsynth.artifacts.gains import gains_id, load_gains
    from robustsynth.errors import VerificationFailed

    gains = ROOT / "results" / "baselines" / "tracks-box" / "gains.json"
    r = _cli("export", str(gains), "--to", "c", "-o", str(tmp_path / "c"))
    assert r.exit_code == 1, r.output
    assert r.stderr.count("\n") == 1 and "its verification failed" in r.stderr and str(gains) in r.stderr
    assert "--allow-unverified" in r.stderr and "Traceback" not in r.stderr and not (tmp_path / "c").exists()
    g = _copy("tracks-box", tmp_path / "g")
    (g.parent / "verification.json").write_text(_record(False, gains_id(load_gains(g))))
    with pytest.raises(VerificationFailed, match="its verification failed .verification.json beside the gains file"):
        export_controller(g, "python", tmp_path / "py")
    assert not (tmp_path / "py").exists()


def test_a_gain_without_a_verification_of_its_own_is_refused(tmp_path: Path) -> None:
    """No verification.json beside the gains file, or one (or --verification) of another gain: exit 2, one line
    saying to run `robustsynth verify` first; nothing written."""
    from robustsynth.errors import InputError

    g = _copy("icr-physics", tmp_path / "g")  # a gain whose verification passed, but not recorded beside it here
    r = _cli("export", str(g), "--to", "c", "-o", str(tmp_path / "c"))
    assert r.exit_code == 2, r.output
    assert r.stderr.count("\n") == 1 and "no verification of this gain" in r.stderr
    assert f"run `robustsynth verify --gains {g}` first" in r.stderr and not (tmp_path / "c").exists()
    with pytest.raises(InputError, match="no verification of this gain"):
        export_controller(g, "json", tmp_path / "j")
    # a record of another gain: beside it, or given with --verification (the default baseline's, passed)
    other = ROOT / "results" / "baselines" / "default" / "summary.json"
    (g.parent / "verification.json").write_text(_record(True, json.loads(other.read_text())["gains_id"]))
    r = _cli("export", str(g), "--to", "c", "-o", str(tmp_path / "c"))
    assert r.exit_code == 2 and "is the verification of another gain" in r.stderr and "robustsynth verify" in r.stderr
    (g.parent / "verification.json").unlink()
    r = _cli("export", str(g), "--to", "json", "-o", str(tmp_path / "c"), "--verification", str(other))
    assert r.exit_code == 2 and f"{other} is the verification of another gain" in r.stderr, r.stderr
    assert not (tmp_path / "c").exists()
    r = _cli("export", str(g), "--to", "json", "-o", str(tmp_path / "c"), "--verification", str(g))
    assert r.exit_code == 2 and "--verification: " in r.stderr and "not a verification record" in r.stderr
    # the right record given explicitly: exported
    r = _cli("export", str(g), "--to", "json", "-o", str(tmp_path / "c"), "--verification",
             str(ROOT / "results" / "baselines" / "icr-physics" / "summary.json"))
    assert r.exit_code == 0, r.stderr
    assert json.loads((tmp_path / "c" / "rs_controller.json").read_text())["proof"]["verification"]["status"] == "passed"


def test_allow_unverified_exports_marked_unverified_and_warns(tmp_path: Path) -> None:
    """--allow-unverified (allow_unverified=True): exported, the headers and the description marked UNVERIFIED,
    a warning on stderr; never "the certified controller"."""
    gains = ROOT / "results" / "baselines" / "tracks-box" / "gains.json"
    r = _cli("export", str(gains), "--to", "c", "-o", str(tmp_path / "c"), "--allow-unverified")
    assert r.exit_code == 0, r.output
    assert "warning:" in r.stderr and "UNVERIFIED" in r.stderr and "FAILED" in r.stderr
    for name in ("rs_controller.h", "rs_controller.c"):
        text = (tmp_path / "c" / name).read_text()
        assert "Verification: UNVERIFIED: its verification FAILED (summary.json beside the gains file)." in text
        assert "the certified networked-robot controller" not in text
    assert "UNVERIFIED (its verification FAILED)" in (tmp_path / "c" / "rs_controller.h").read_text()
    g = _copy("tracks-box", tmp_path / "g")  # never verified
    for target, name in (("python", "rs_controller.py"), ("ros2", "rs_controller.ros2.yaml")):
        d, _ = export_controller(g, target, tmp_path / target, allow_unverified=True)
        text = (tmp_path / target / name).read_text()
        assert d["proof"]["verification"]["status"] == "missing"
        assert "Verification: UNVERIFIED: no verification of this gain" in text
    ast.parse((tmp_path / "python" / "rs_controller.py").read_text())  # the header stays a docstring
    yaml.safe_load((tmp_path / "ros2" / "rs_controller.ros2.yaml").read_text())


@pytest.mark.parametrize("name,proven", [
    ("nonlinear-proof", "certified for the nonlinear robot while |e_theta| <= 0.2 rad (its heading bound); "
                        "slip model tracks (mu_r in [0.8, 1], mu_l in [0.8, 1]"),
    ("icr-physics", "certified for the linearization only (certificate kinematics: linearized; not proven for the "
                    "nonlinear robot); slip model icr (mu_r in [0.95, 1.02]"),
])
def test_a_verified_gain_states_what_it_is_proven_for(name: str, proven: str, tmp_path: Path) -> None:
    """A baseline that passed verification: the CLI prints, the headers and the description state the certificate's
    kind (the nonlinear robot within its heading bound, or the linearization only), the slip model and that exactly
    this gain passed verification."""
    gains = ROOT / "results" / "baselines" / name / "gains.json"
    r = _cli("export", str(gains), "--to", "c", "-o", str(tmp_path / "c"))
    assert r.exit_code == 0, r.output
    assert f"proven: {proven}" in r.stdout and "verification: passed for exactly this gain" in r.stdout
    assert r.stderr == ""
    h = (tmp_path / "c" / "rs_controller.h").read_text()
    assert "the certified networked-robot controller" in h and f"Proven: {proven}" in h
    assert f"Verification: passed for exactly this gain (summary.json beside the gains file, config '{name}')." in h
    d, _ = export_controller(gains, "json", tmp_path / "j")
    assert d["proof"]["certificate"] == ("nonlinear" if name == "nonlinear-proof" else "linearized")
    assert json.loads((tmp_path / "j" / "rs_controller.json").read_text())["proof"]["proven"].startswith(proven)


@pytest.mark.slow
def test_run_exports_a_gain_whose_verification_passed_and_skips_one_that_failed(tmp_path: Path) -> None:
    """`robustsynth run --export` (make demo's path): the export reads the verification.json the run wrote beside
    gains.json; a passed verdict exports and states it, a failed one skips the export with a line, exit 1."""
    from ..conftest import BASE_CONFIG, PASSING_CONFIG

    r = _cli("run", str(PASSING_CONFIG), "-o", str(tmp_path / "pass"), "--runs", "10", "--no-plots", "--export", "c")
    assert r.exit_code == 0, r.output
    assert "exported (c; proven: certified for the linearization only" in r.stdout
    h = (tmp_path / "pass" / "export" / "rs_controller.h").read_text()
    assert "the certified networked-robot controller" in h
    assert "Verification: passed for exactly this gain (verification.json beside the gains file" in h
    r = _cli("run", str(BASE_CONFIG), "-o", str(tmp_path / "fail"), "--runs", "5", "--no-plots", "--export", "c")
    assert r.exit_code == 1, r.output
    assert "export skipped: verification failed" in r.stdout and "--allow-unverified" in r.stdout
    assert not (tmp_path / "fail" / "export").exists()
    # a gains.mat beside the gains.json run verified is the same gain
    d, _ = export_controller(tmp_path / "pass" / "gains.mat", "json", tmp_path / "m")
    assert d["proof"]["verification"]["status"] == "passed"


def test_the_python_export_leaves_out_the_monitors_docstring_import_and_all_wherever_their_lines_end() -> None:
    """rs_controller.py takes the monitor's source without its docstring, ``import math`` and ``__all__``, each
    statement whole (a wrapped ``__all__`` once left its second line behind: an IndentationError in the export)."""
    from robustsynth.runtime.export import _monitor_body

    src = '"""doc\nstring"""\n\nimport math\n\n__all__ = ["a",\n           "b"]\n\nA = 1\n'
    assert _monitor_body(src).split() == ["A", "=", "1"]


def test_every_plant_kind_exports_through_one_flow() -> None:
    """export_controller asks a plant kind's exporter and names no kind itself (issue 52): its body holds no plant
    kind's name, no ``kind`` and no linear or robot helper; each exporter offers the same calls, the robot's every
    target, a linear plant's refuses the robot's own by name."""
    import inspect
    import textwrap

    from robustsynth.errors import InputError
    from robustsynth.runtime import export
    from robustsynth.runtime.export import TARGETS, _exporter
    from robustsynth.runtime.linear_law import LTI_TARGETS

    body = ast.parse(textwrap.dedent(inspect.getsource(export.export_controller)))
    strings = {n.value for n in ast.walk(body) if isinstance(n, ast.Constant) and isinstance(n.value, str)}
    names = {n.id for n in ast.walk(body) if isinstance(n, ast.Name)} | {
        n.attr for n in ast.walk(body) if isinstance(n, ast.Attribute)}
    assert not {"lti", "tracked-robot", "kind"} & strings and "kind" not in names
    assert not [n for n in names if "lti" in n.lower() or "robot" in n.lower()], names

    robot, linear = _exporter({"K": [[0.0]]}), _exporter({"kind": "lti"})
    assert (robot.kind, linear.kind) == ("tracked-robot", "lti")
    for plant in (robot, linear):
        for call in ("refuse_target", "prepare", "check_config", "description", "proven", "files"):
            assert callable(getattr(plant, call)), (plant.kind, call)
        assert set(plant.targets) <= set(TARGETS)
    for target in TARGETS:
        robot.refuse_target(target)
        if target in LTI_TARGETS:
            linear.refuse_target(target)
        else:
            with pytest.raises(InputError, match=rf"^--to: {target} is for the robot; a linear plant's gain exports to "):
                linear.refuse_target(target)
