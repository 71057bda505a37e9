"""Every config in configs/ re-run and compared with its committed results/baselines/<name>/summary.json
(tolerances named in robustsynth.regression).  Regenerate with `make baselines`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robustsynth.regression import compare, run_config

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = sorted((ROOT / "configs").glob("*.yaml"))
REQUIRED = {"default", "delay-full-period", "delay-multi-period", "delay-dlo1", "heavy-slip", "fast", "tight-motors",
            "infeasible"}


def test_required_configs_exist() -> None:
    assert REQUIRED <= {p.stem for p in CONFIGS}
    for p in CONFIGS:
        assert p.read_text().startswith("#"), f"{p.name} must say its purpose in a comment"


@pytest.mark.parametrize("cfg", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_config_matches_baseline(cfg, tmp_path) -> None:
    got = run_config(cfg, tmp_path)
    base = ROOT / "results" / "baselines" / got["name"] / "summary.json"
    assert base.exists(), f"no baseline for {cfg.name}: run make baselines"
    diffs = compare(json.loads(base.read_text()), got)
    assert not diffs, "\n".join(diffs)


def test_infeasible_config_exits_3(tmp_path) -> None:
    from click.testing import CliRunner

    from robustsynth.cli import main

    r = CliRunner().invoke(main, ["run", str(ROOT / "configs" / "infeasible.yaml"), "-o", str(tmp_path), "--no-plots"])
    assert r.exit_code == 3
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "infeasible"
    assert not (tmp_path / "gains.json").exists()


def test_compare_detects_differences() -> None:
    a = {"status": "certified", "certified": {"decay_rate": 0.9, "ultimate_bound": {"e_y": 0.03}},
         "monte_carlo": {"max": {"e_y": 0.031}}, "verification_passed": True}
    assert compare(a, a) == []
    b = json.loads(json.dumps(a))
    b["certified"]["ultimate_bound"]["e_y"] = 0.03 * (1 + 2e-3)
    assert any("ultimate_bound.e_y" in d for d in compare(a, b))
    c = json.loads(json.dumps(a))
    c["verification_passed"] = False
    assert any("verification_passed" in d for d in compare(a, c))
