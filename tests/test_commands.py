"""The commands' jobs per plant kind (robustsynth.commands): the registry, the refusals, and a CLI without plant
branches (issue 52)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from click.testing import CliRunner

from robustsynth.cli import main
from robustsynth.commands import JOBS, Jobs, jobs_for, require
from robustsynth.config import load_config
from robustsynth.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
DC_MOTOR = ROOT / "configs" / "dc-motor.yaml"


def test_every_plant_kind_offers_the_core_commands_through_one_implementation() -> None:
    """A plant kind is data and refusals: the core jobs are the base's for every kind (one implementation; a kind
    may only wrap one to refuse its options), each kind says how its model is described."""
    core = {"build-model", "synthesize", "verify", "run", "margin", "export", "sweep"}
    assert set(JOBS) == {"tracked-robot", "lti"}
    for kind, jobs in JOBS.items():
        assert jobs.kind == kind and core <= jobs.commands
        for name in ("model", "synthesize", "verify", "run"):
            assert getattr(type(jobs), name) is getattr(Jobs, name), (kind, name)
        assert type(jobs).model_summary is not Jobs.model_summary
    assert jobs_for(load_config(None)).kind == "tracked-robot"
    assert jobs_for(load_config(DC_MOTOR)).kind == "lti"


def test_a_command_the_plant_kind_does_not_offer_is_refused_by_name() -> None:
    cfg = load_config(DC_MOTOR)
    for cmd in ("identify", "check-log", "monitor", "validate"):
        with pytest.raises(InputError, match=rf"^plant\.kind: lti: `robustsynth {cmd}` is not available for a linear "
                                             r"plant yet \(available: build-model, synthesize, verify, run, margin, "
                                             r"sweep, export\)$"):
            require(cfg, cmd)
    require(load_config(None), "validate")  # the robot offers it


def test_the_cli_has_no_plant_branches() -> None:
    """The CLI parses options, calls one job and prints: it names no plant kind's module or predicate."""
    tree = ast.Module(body=[node for p in sorted((ROOT / "src" / "robustsynth" / "cli").glob("*.py"))
                            for node in ast.parse(p.read_text(encoding="utf-8")).body], type_ignores=[])
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)} | {
        n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    modules = {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
    assert not {"is_lti", "kind_of"} & (names | imported)
    assert not [m for m in modules if m.endswith("_lti") or m.endswith(".lti")]


@pytest.mark.parametrize("args, message", [
    (["--physics", "2"], "error: --physics: the MuJoCo robot validates the tracked robot's gain, not a linear plant's"),
    (["--export", "ros2"], "error: --export: ros2 is for the robot; a linear plant's gain exports to c, python, json"),
    (["--multiplier", "full"], "error: --multiplier: a robot synthesis option, not available for a linear plant"),
])
def test_run_on_a_linear_plant_refuses_the_robots_options_before_any_work(tmp_path, args, message) -> None:
    """--physics and --export ros2 were ignored silently on a linear plant before the jobs: now one line, exit 2,
    nothing written."""
    out = tmp_path / "o"
    r = CliRunner().invoke(main, ["run", str(DC_MOTOR), "-o", str(out), "--no-plots", *args])
    assert r.exit_code == 2 and r.output.strip() == message, r.output
    assert not out.exists()


def test_run_on_a_linear_plant_exports_its_verified_controller(tmp_path) -> None:
    out = tmp_path / "o"
    r = CliRunner().invoke(main, ["run", str(DC_MOTOR), "-o", str(out), "--no-plots", "--export", "c"])
    assert r.exit_code == 0, r.output
    lines = r.output.strip().splitlines()
    assert lines[-1] == f"report: {out / 'report.md'}"  # last, as for the robot
    assert lines[-2].startswith("exported (c; proven: certified for the linear plant") and "verification: passed" in lines[-2]
    assert sorted(p.name for p in (out / "export").iterdir()) == ["rs_lti.c", "rs_lti.h"]
    assert "double" in (out / "export" / "rs_lti.c").read_text()
