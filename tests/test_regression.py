"""Every config in configs/ re-run and compared with its committed results/baselines/<name>/summary.json
(tolerances named in robustsynth.regression).  Regenerate with `make baselines`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robustsynth.regression import compare, run_config

pytestmark = pytest.mark.slow  # make test-all / CI (`make test` runs the rest in minutes)

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = sorted((ROOT / "configs").glob("*.yaml"))
REQUIRED = {"default", "tracks-box", "paper-model", "delay-full-period", "delay-multi-period", "delay-dlo1", "heavy-slip", "fast", "tight-motors",
            "infeasible"}


def test_required_configs_exist() -> None:
    assert REQUIRED <= {p.stem for p in CONFIGS}
    for p in CONFIGS:
        assert p.read_text().startswith("#"), f"{p.name} must say its purpose in a comment"


# configs whose run takes minutes (the default: the robot proof with the icr model along eased arcs, a synthesis
# of about 48 vertices x 40 channels and a verification whose adversary branches over 16 slip corners; the
# slip-compensated harsh ground: a robot proof whose heading search takes about two minutes): CI
# re-checks their committed gain's certificate in numpy and compares its figures with the baseline; the whole
# run (synthesis, verification) is `python -m robustsynth.regression` (make baselines writes it)
SLOW = {"default", "harsh-compensated"}


@pytest.mark.parametrize("cfg", [p for p in CONFIGS if p.stem not in SLOW], ids=[p.stem for p in CONFIGS if p.stem not in SLOW])
def test_config_matches_baseline(cfg, tmp_path) -> None:
    got = run_config(cfg, tmp_path)
    base = ROOT / "results" / "baselines" / got["name"] / "summary.json"
    assert base.exists(), f"no baseline for {cfg.name}: run make baselines"
    diffs = compare(json.loads(base.read_text()), got)
    assert not diffs, "\n".join(diffs)


@pytest.mark.parametrize("name", sorted(SLOW))
def test_slow_configs_committed_gain_rechecks_to_its_baseline(name) -> None:
    """The committed gain of a slow config: its certificate proven again in verified arithmetic for the config as
    it is now, with the figures of the baseline summary (rel CERTIFIED_REL), and the baseline's verdict passed."""
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.certificate import recheck_gains
    from robustsynth.config import load_config
    from robustsynth.model import build_model
    from robustsynth.regression import CERTIFIED_REL

    model = build_model(load_config(ROOT / "configs" / f"{name}.yaml"))
    base = json.loads((ROOT / "results" / "baselines" / name / "summary.json").read_text())
    chk = recheck_gains(model, load_gains(ROOT / "results" / "baselines" / name / "gains.json"))
    assert chk.passed, chk.reason
    for k, v in base["certified"]["ultimate_bound"].items():
        assert abs(chk.figures["ultimate_bound"][k] - v) <= CERTIFIED_REL * v, (k, chk.figures["ultimate_bound"][k], v)
    assert base["verification_passed"] and not base["failed_checks"]


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
    # a stronger claim (a smaller bound or decay rate) is no regression; a weaker one by more than the tolerance is
    d = json.loads(json.dumps(a))
    d["certified"]["ultimate_bound"]["e_y"], d["certified"]["decay_rate"] = 0.03 * (1 - 1e-2), 0.9 * (1 - 1e-2)
    assert compare(a, d) == []
    d["certified"]["decay_rate"] = 0.9 * (1 + 2e-3)
    assert any("certified.decay_rate" in x for x in compare(a, d))
