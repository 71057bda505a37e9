"""The paper-vs-slip-aware comparison: the other kind's design is made with the settings of the gain it
is compared with."""

from __future__ import annotations

from robustsynth.comparison import other_config

from .conftest import committed_gain


def test_the_other_kind_is_designed_with_the_gains_overrides() -> None:
    """Review, stop 47: `synthesize CFG --objective ultimate-bound` on a config saying stability compared its
    gain with a *stability* design of the paper's model (every bound '—'): the other design took the file's
    settings, not the ones the gain was made with (gains.json's synthesis_overrides)."""
    model = committed_gain("tracks-box")[0]
    cfg = model.config.model_copy(update={"synthesis": model.config.synthesis.model_copy(update={"objective": "stability"})})
    gains = {"synthesis_overrides": {"synthesis.objective": "ultimate-bound", "synthesis.solver": "scs"}}
    other = other_config(cfg, "paper", gains).synthesis
    assert (other.model, other.objective, other.solver, other.lyapunov) == ("paper", "ultimate-bound", "scs", "common")
    plain = other_config(cfg, "paper", {}).synthesis
    assert (plain.objective, plain.solver) == ("stability", cfg.synthesis.solver)


def test_a_nonlinear_gains_paper_design_is_linearized() -> None:
    """Fourth review, stop 47: for a nonlinear-kinematics config the paper model's copy kept kinematics:
    nonlinear, which the validation refuses (only the slip-aware model has the channels): `run` and
    `synthesize` of configs/nonlinear-proof.yaml and turns.yaml ended in a traceback."""
    for name in ("nonlinear-proof", "turns"):
        cfg = committed_gain(name)[0].config
        other = other_config(cfg, "paper", {"synthesis_overrides": {"synthesis.heading_bound": 0.2}}).synthesis
        assert (other.model, other.kinematics, other.heading_bound) == ("paper", "linearized", "auto")


def test_a_nonlinear_certificate_is_compared_with_the_papers_design() -> None:
    """The path that raised (fourth review, stop 47), end to end from the committed gain: the paper model's
    design of nonlinear-proof's config is made and certified, beside the nonlinear certificate's row."""
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.comparison import compare_models

    from .conftest import ROOT

    model = committed_gain("nonlinear-proof")[0]
    cmp = compare_models(model, load_gains(ROOT / "results" / "baselines" / "nonlinear-proof" / "gains.json"))
    rows = {r["model"]: r for r in cmp["rows"]}
    assert set(rows) == {"slip-aware", "paper"} and rows["paper"]["status"] == "certified"
