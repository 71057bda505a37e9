"""CLI: arguments forwarded, exit codes, one-line errors, and a real subprocess run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from robustsynth.cli import main

from .conftest import BASE_CONFIG


def test_help_lists_commands() -> None:
    r = CliRunner().invoke(main, ["--help"])
    assert r.exit_code == 0
    for cmd in ("build-model", "schema"):
        assert cmd in r.output


def test_schema_is_json() -> None:
    r = CliRunner().invoke(main, ["schema"])
    assert r.exit_code == 0
    schema = json.loads(r.output)
    assert set(schema["properties"]) >= {"name", "robot", "reference", "network", "slip", "synthesis", "verification"}


def test_build_model_writes_files(tmp_path) -> None:
    r = CliRunner().invoke(main, ["build-model", "-o", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    data = json.loads((tmp_path / "out" / "model.json").read_text())
    assert set(data) >= {"schema_version", "config", "dimensions", "state_names", "input_names", "continuous", "lifted", "uncertainty"}
    assert data["dimensions"] == {"n_e": 3, "n_u": 2, "n_s": 5, "d_lo": 0, "d_hi": 1}
    assert data["state_names"] == ["e_x", "e_y", "e_theta", "dV[k-1]", "omega[k-1]"]
    assert len(data["lifted"]["B_p"]) == 5 and len(data["lifted"]["B_p"][0]) == 3
    assert (tmp_path / "out" / "model.md").read_text().startswith("# Model of `default`")


def test_build_model_forwards_config(tmp_path) -> None:
    cfg = tmp_path / "c.yaml"
    from .conftest import default_dict
    import yaml

    d = default_dict()
    d["name"] = "long"
    d["network"]["delay"] = {"min": 0.12, "max": 0.25}
    cfg.write_text(yaml.safe_dump(d))
    r = CliRunner().invoke(main, ["build-model", str(cfg), "-o", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    dims = json.loads((tmp_path / "o" / "model.json").read_text())["dimensions"]
    assert (dims["d_lo"], dims["d_hi"], dims["n_s"]) == (1, 3, 9)


def test_bad_config_exits_2_with_one_line_and_no_files(tmp_path) -> None:
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("name: x\nrobot: {gear_radius: -1, track_distance: 0.4}\n")
    r = CliRunner().invoke(main, ["build-model", str(cfg), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: robot.gear_radius: Input should be greater than 0")
    assert not (tmp_path / "o").exists()


def test_unknown_option_is_usage_error() -> None:
    r = CliRunner().invoke(main, ["build-model", "--bogus"])
    assert r.exit_code == 2


LAZY_PROBE = (
    "import sys, runpy\nsys.argv = ['robustsynth'] + sys.argv[1:]\n"
    "try:\n    runpy.run_module('robustsynth', run_name='__main__')\nexcept SystemExit as e:\n"
    "    assert e.code in (0, None), e.code\n"
    "print('HEAVY', sorted(m for m in ('cvxpy', 'matplotlib', 'scipy') if m in sys.modules))"
)


@pytest.mark.parametrize("args", [["--help"], ["schema"], ["build-model", "-o", "{tmp}"]], ids=["help", "schema", "build-model"])
def test_startup_commands_do_not_import_heavy_modules(tmp_path, args) -> None:
    argv = [a.replace("{tmp}", str(tmp_path / "o")) for a in args]
    out = subprocess.run([sys.executable, "-c", LAZY_PROBE, *argv], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    heavy = out.stdout.strip().splitlines()[-1]
    assert "cvxpy" not in heavy and "matplotlib" not in heavy, heavy


def test_real_subprocess_run(tmp_path) -> None:
    r = subprocess.run([sys.executable, "-m", "robustsynth", "build-model", "-o", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "o" / "model.json").exists()
    r = subprocess.run([sys.executable, "-m", "robustsynth", "build-model", str(tmp_path / "nope.yaml")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.startswith("error: ") and "Traceback" not in r.stderr


def test_public_verify_is_the_function_even_after_the_subpackage_is_imported() -> None:
    code = ("import robustsynth.verification.checks; from robustsynth import verify; "
            "print(callable(verify), verify.__module__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["True", "robustsynth.verification.checks"]


def test_default_config_name_names_the_output_directory(tmp_path) -> None:
    r = CliRunner().invoke(main, ["default-config", "--name", "my-robot"])
    assert r.exit_code == 0 and "name: \"my-robot\"" in r.output
    r = CliRunner().invoke(main, ["default-config", "--name", "baselines"])
    assert r.exit_code == 2 and "reserved" in r.output and len(r.output.strip().splitlines()) == 1


def test_a_stage_sets_aside_what_another_config_left(tmp_path) -> None:
    """build-model of another config on a full run's directory moves that run's gains and reports under
    stale/<time>/ instead of leaving a foreign model beside them, and deletes none of them (issue 50: a
    rebuild had removed 14 files)."""
    r = CliRunner().invoke(main, ["run", str(BASE_CONFIG), "-o", str(tmp_path), "--runs", "3", "--no-plots", "--objective",
                                  "stability"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "gains.json").exists() and (tmp_path / "report.md").exists()
    before = {p.relative_to(tmp_path): p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    r = CliRunner().invoke(main, ["build-model", str(BASE_CONFIG), "-o", str(tmp_path)])  # same config: nothing moved
    assert r.exit_code == 0 and "set aside" not in r.output and (tmp_path / "gains.json").exists()
    assert not (tmp_path / "stale").exists()
    other = tmp_path / "other.yaml"
    other.write_text(CliRunner().invoke(main, ["default-config", "--name", "other"]).output)
    r = CliRunner().invoke(main, ["build-model", str(other), "-o", str(tmp_path)])
    assert r.exit_code == 0 and "another config had left" in r.output and "nothing deleted" in r.output
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_file() and p.suffix != ".yaml") == ["model.json", "model.md"]
    assert json.loads((tmp_path / "model.json").read_text())["config"]["name"] == "other"
    (stale,) = (tmp_path / "stale").iterdir()
    assert "another config" in (stale / "STALE.txt").read_text()
    # every file of the earlier run is kept, byte for byte, under stale/<time>/ (model.json/.md of the same
    # config were rewritten by the same-config build-model above with the same bytes)
    for rel, data in before.items():
        assert (stale / rel).read_bytes() == data, rel


def test_a_file_written_before_a_key_existed_is_not_foreign(tmp_path) -> None:
    """The committed baselines were written before ``reference.turn_radius`` existed: their config is the
    same config with that key at its default, so a stage writing beside them keeps them (it had removed
    them).  A changed value still counts as another config."""
    import shutil
    from pathlib import Path

    from robustsynth.config import parse_config
    from robustsynth.pipeline import clear_foreign

    root = Path(__file__).resolve().parents[1]
    g = json.loads((root / "results" / "baselines" / "tracks-box" / "gains.json").read_text())
    for key in ("turn_radius", "turn_ramp"):  # as a file written before these keys existed
        del g["config"]["reference"][key]
    (tmp_path / "gains.json").write_text(json.dumps(g))
    text = (root / "configs" / "tracks-box.yaml").read_text()
    assert clear_foreign(tmp_path, parse_config(text)) == []
    assert (tmp_path / "gains.json").exists()
    (moved,) = clear_foreign(tmp_path, parse_config(text.replace("speed: 0.5", "speed: 0.4")))
    assert moved.startswith("stale/") and moved.endswith("/gains.json") and (tmp_path / moved).is_file()
    assert not (tmp_path / "gains.json").exists()


def test_a_file_written_with_the_path_at_its_old_place_is_not_foreign(tmp_path) -> None:
    """The committed baselines store the path as verification.path (its old place); configs/fast.yaml, whose path
    is not the default, now writes it as reference.path: the same config, so a stage keeps the files beside it.
    Another path is another config."""
    import shutil

    from robustsynth.config import parse_config
    from robustsynth.pipeline import clear_foreign

    root = Path(__file__).resolve().parents[1]
    shutil.copy(root / "results" / "baselines" / "fast" / "gains.json", tmp_path / "gains.json")
    assert "path" in json.loads((tmp_path / "gains.json").read_text())["config"]["verification"]
    text = (root / "configs" / "fast.yaml").read_text()
    assert clear_foreign(tmp_path, parse_config(text)) == [] and (tmp_path / "gains.json").exists()
    (moved,) = clear_foreign(tmp_path, parse_config(text.replace("[48.0, 6.0]", "[50.0, 6.0]")))
    assert moved.startswith("stale/") and moved.endswith("/gains.json")


def test_schema_and_default_config_hold_the_path_under_reference() -> None:
    import yaml

    r = CliRunner().invoke(main, ["schema"])
    assert r.exit_code == 0
    defs = json.loads(r.output)["$defs"]
    assert "path" in defs["ReferenceConfig"]["properties"] and "path" not in defs["VerificationConfig"]["properties"]
    r = CliRunner().invoke(main, ["default-config"])
    assert r.exit_code == 0
    d = yaml.safe_load(r.output)
    assert d["reference"]["path"] == [[0.0, 0.0], [6.0, 0.0], [10.0, 2.0], [16.0, 2.0]] and "path" not in d["verification"]


def test_a_gear_radius_in_centimetres_exits_2_with_the_unit_it_looks_like(tmp_path) -> None:
    """gear_radius: 7 (cm written as m) was accepted; now one line naming the key and the likely unit."""
    cfg = tmp_path / "cm.yaml"
    cfg.write_text(CliRunner().invoke(main, ["default-config"]).output.replace("gear_radius: 0.09", "gear_radius: 7"))
    r = CliRunner().invoke(main, ["build-model", str(cfg), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2
    assert r.output.strip().splitlines() == ["error: robot.gear_radius: 7 m is not a plausible sprocket radius (below 1 m "
                                             "for a tracked robot; lengths are in metres: 7 looks like centimetres, did "
                                             "you mean 0.07 m?)"]
    assert not (tmp_path / "out").exists()


def test_a_linear_plants_stage_clears_what_another_config_left(tmp_path) -> None:
    """The same for a linear plant (a review found dc-motor's gains and report left beside zbp's model), and its
    own files stay through its stages (its model.json and summary.json name their config, not hold it)."""
    from pathlib import Path

    configs = Path(__file__).resolve().parents[1] / "configs"
    r = CliRunner().invoke(main, ["run", str(configs / "dc-motor.yaml"), "-o", str(tmp_path), "--runs", "2", "--no-plots"])
    assert r.exit_code == 0, r.output
    for cmd in ("build-model", "synthesize"):
        r = CliRunner().invoke(main, [cmd, str(configs / "zbp.yaml"), "-o", str(tmp_path)])
        assert r.exit_code == 0, r.output
        assert ("another config had left" in r.output) == (cmd == "build-model"), r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gains.json", "gains.mat", "model.json", "stale", "synthesis.md"]
    assert json.loads((tmp_path / "gains.json").read_text())["config"]["name"] == "zbp"


def test_demo_output_is_not_a_committed_baseline() -> None:
    """`make demo` writes results/default/, which git ignores; the baselines live in results/baselines/."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    demo = re.search(r"^demo:.*\n\t(.*)$", (root / "Makefile").read_text(), flags=re.M).group(1)
    out = re.search(r"-o (\S+)", demo).group(1)
    assert out == "results/default"
    r = subprocess.run(["git", "check-ignore", "-q", f"{out}/gains.json"], cwd=root)
    if r.returncode == 128:
        pytest.skip("not a git checkout")
    assert r.returncode == 0, f"{out}/gains.json would be tracked by git"
    assert subprocess.run(["git", "check-ignore", "-q", "results/baselines/default/gains.json"], cwd=root).returncode == 1


def test_verbose_synthesis_prints_the_search(tmp_path) -> None:
    r = CliRunner().invoke(main, ["synthesize", str(BASE_CONFIG), "-o", str(tmp_path), "-v"])
    assert r.exit_code == 0, r.output
    lines = r.stderr.splitlines()
    assert any(ln.startswith("ultimate-bound: scan of alpha") for ln in lines)
    scan = [ln for ln in lines if ln.startswith("  alpha = ")]
    assert len(scan) >= 5 and all("clarabel" in ln or "scs" in ln for ln in scan)


def test_progress_bar_starts_with_the_first_report() -> None:
    from robustsynth.report.progress import LazyBar

    bar = LazyBar()
    assert bar.bar is None  # nothing before the Monte Carlo starts: its ETA counts the simulation only
    bar(1, 100)
    assert bar.bar is not None and bar.last == 1
    bar.render_finish()


def test_a_linear_plants_gains_and_malformed_kinds_get_one_plain_line(tmp_path) -> None:
    """Messages a review found misleading: a linear plant's gains given to the robot's verify ("made for another
    delay range?") and check-log (missing robot keys), 'plant: lti' as a string, and nan for --pose-noise."""
    from pathlib import Path

    (tmp_path / "lti.json").write_text(json.dumps({"kind": "lti", "K": [[0.1, 0.2]], "lifting": {"n": 2, "m": 1, "d": 0}}))
    default = Path(__file__).resolve().parents[1] / "configs" / "tracks-box.yaml"
    r = CliRunner().invoke(main, ["verify", str(default), "--gains", str(tmp_path / "lti.json"), "-o", str(tmp_path / "v")])
    assert r.exit_code == 2 and "a linear plant's gains (kind: lti)" in r.output, r.output
    r = CliRunner().invoke(main, ["check-log", str(default), "--gains", str(tmp_path / "lti.json")])
    assert r.exit_code == 2 and "a linear plant's gains (kind: lti)" in r.output, r.output
    (tmp_path / "p.yaml").write_text("name: x\nplant: lti\n")
    r = CliRunner().invoke(main, ["build-model", str(tmp_path / "p.yaml"), "-o", str(tmp_path / "m")])
    assert r.exit_code == 2 and "plant: must be a mapping (got 'lti')" in r.output, r.output
    r = CliRunner().invoke(main, ["check-log", str(default), "--config", str(default), "--pose-noise", "nan", "nan"])
    assert r.exit_code == 2 and "'nan' is not a finite number >= 0" in r.output, r.output


@pytest.mark.parametrize("args", [["verify", "--runs", "0"], ["run", "--format", "gif"], ["nosuch"]])
def test_a_usage_error_is_one_line_and_exit_2(args) -> None:
    """The console script reports click's usage errors in one line (click's own format takes four)."""
    r = subprocess.run([sys.executable, "-m", "robustsynth", *args], capture_output=True, text=True)
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "robustsynth" in lines[0] and "Traceback" not in r.stderr, r.stderr


def test_robustsynth_alone_shows_its_help() -> None:
    """No command: click's help, not an 'error:' line around it (review of the one-line usage errors)."""
    r = subprocess.run([sys.executable, "-m", "robustsynth"], capture_output=True, text=True)
    assert "Usage:" in r.stdout + r.stderr and "error:" not in r.stdout + r.stderr and "Commands:" in r.stdout + r.stderr


def test_a_failed_command_leaves_no_empty_directory_it_made(tmp_path) -> None:
    """Review, stop 47: `synthesize` that failed (exit 2 here, exit 3 alike) left its new, empty output
    directory behind; one that already existed stays, and so does every file a stage kept."""
    cfg = Path(__file__).resolve().parents[1] / "configs" / "nonlinear-proof.yaml"
    new = tmp_path / "a" / "b"
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "--objective", "stability", "-o", str(new)])
    assert r.exit_code == 2 and "synthesis.objective: stability (overridden: --objective)" in r.output
    assert not (tmp_path / "a").exists()
    old = tmp_path / "kept"
    old.mkdir()
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "--objective", "stability", "-o", str(old)])
    assert r.exit_code == 2 and old.is_dir()


def test_the_cleanup_keeps_what_existed_and_never_turns_an_error_into_a_traceback(tmp_path) -> None:
    """Second review, stop 47: 'new/../kept' made an existing directory look new, and was removed; a path
    the system cannot look at (too long) raised from the check itself: a traceback and exit 1 instead of
    the stage's one line and exit 2; verify's -o was not covered."""
    root = Path(__file__).resolve().parents[1]
    kept = tmp_path / "kept"
    kept.mkdir()
    r = CliRunner().invoke(main, ["synthesize", str(root / "configs" / "infeasible.yaml"), "-o",
                                  str(tmp_path / "ghost" / ".." / "kept")])
    assert r.exit_code == 3 and kept.is_dir()
    r = CliRunner().invoke(main, ["build-model", str(root / "configs" / "fast.yaml"), "-o", str(tmp_path / ("a" * 300))])
    assert r.exit_code == 2 and r.output.startswith("error: ") and "Traceback" not in r.output
    r = CliRunner().invoke(main, ["verify", str(root / "configs" / "tracks-box.yaml"), "--gains",
                                  str(root / "results" / "baselines" / "delay-multi-period" / "gains.json"),
                                  "-o", str(tmp_path / "v" / "x")])
    assert r.exit_code == 2 and not (tmp_path / "v").exists()


def test_a_linear_plants_gains_record_the_overrides(tmp_path) -> None:
    """Third review, stop 47: `synthesize --solver scs` on a linear plant left nothing in gains.json that
    said scs was used (the robot's files record synthesis_overrides)."""
    cfg = Path(__file__).resolve().parents[1] / "configs" / "dc-motor.yaml"  # the cheapest linear plant (4 s with scs)
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "--solver", "scs", "--objective", "stability",
                                  "-o", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    g = json.loads((tmp_path / "o" / "gains.json").read_text())
    assert g["synthesis_overrides"] == {"synthesis.solver": "scs", "synthesis.objective": "stability"}
    assert g["config"]["synthesis"]["solver"] == "clarabel" and g["config"]["synthesis"]["objective"] != "stability"


def test_the_cleanup_follows_symlinks_and_covers_a_gains_files_directory(tmp_path) -> None:
    """Third review, stop 47: 'lnk/../made' with lnk a symlink left the made directory (a lexical '..' is not
    the system's), and verify without -o writes beside --gains, whose new directory stayed on failure."""
    root = Path(__file__).resolve().parents[1]
    (tmp_path / "real" / "sub").mkdir(parents=True)
    (tmp_path / "lnk").symlink_to(tmp_path / "real" / "sub")
    r = CliRunner().invoke(main, ["synthesize", str(root / "configs" / "infeasible.yaml"), "-o", str(tmp_path / "lnk" / ".." / "made")])
    assert r.exit_code == 3 and sorted(p.name for p in (tmp_path / "real").iterdir()) == ["sub"]
    r = CliRunner().invoke(main, ["verify", str(root / "configs" / "fast.yaml"), "--gains", str(tmp_path / "g" / "x" / "gains.json")])
    assert r.exit_code == 2 and not (tmp_path / "g").exists()


def test_a_long_stage_gets_a_line_at_least_every_heartbeat(monkeypatch, capsys) -> None:
    """On a terminal a long command prints its steps and, between them, a line of its own at least every
    HEARTBEAT_S (issue 50: a nonlinear synthesis was silent for 12.6 minutes).  Here with the period shortened
    to 0.3 s (the thread looking every 0.1 s) and 0.9 s without a step; once stopped, it says nothing more."""
    import time

    from robustsynth.report import progress

    monkeypatch.setattr(progress, "HEARTBEAT_S", 0.3)
    monkeypatch.setattr(progress, "HEARTBEAT_POLL_S", 0.1)
    say = progress.Heartbeat()
    say("step one")
    say.open_line = True  # as a rewritten count line (sweep) leaves it: the first beat goes below it
    time.sleep(0.9)
    say("step two")
    progress.stop_heartbeats()  # as every command does when it ends: no line after its last one
    time.sleep(0.4)
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "step one" and err[-1] == "step two"
    assert err[1] == "", err
    beats = [line for line in err[2:-1] if "still working" in line]
    assert len(beats) >= 2 and len(beats) == len(err) - 3, err
