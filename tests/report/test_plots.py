"""The verification figures (report/plots.py): what their legends name is what they draw."""

from __future__ import annotations

from dataclasses import replace

import pytest

from robustsynth.artifacts.gains import load_gains
from robustsynth.config import config_with
from robustsynth.verification.checks import verify

from ..conftest import ROOT, committed_gain


@pytest.mark.parametrize("name,excludes", [("default", True), ("turns", False)])
def test_the_excluded_steps_are_named_only_where_there_are_some(name, excludes) -> None:
    """A polyline (the default path) excludes the steps after each waypoint until the robot is back in the
    set, and errors.png and lyapunov.png shade and name them; a path rounded by arcs (configs/turns.yaml)
    excludes nothing, and its figures name no excluded steps (they once had an empty legend entry)."""
    from robustsynth.report.plots import _covered, fig_errors, fig_lyapunov

    m, _, _ = committed_gain(name)
    # the figures read the Monte Carlo runs only: the adversary's searches are left out (25 s of 32 on turns)
    m = replace(m, config=config_with(m.config, {"verification.adversarial_runs": 0}))
    res = verify(m, load_gains(ROOT / "results" / "baselines" / name / "gains.json"), runs=4)
    assert bool((~_covered(res)).any()) == excludes
    for fig in (fig_errors(res, m), fig_lyapunov(res, m)):
        labels = [lab for ax in fig.axes for lab in ax.get_legend_handles_labels()[1]]
        assert any(lab.startswith("excluded") for lab in labels) == excludes, labels
