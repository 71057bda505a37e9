"""model.md (report/model.py): it names every slip parameter the model has, and where each one enters."""

from __future__ import annotations

import pytest

from robustsynth.config import load_config
from robustsynth.pipeline import model_stage

from ..conftest import ROOT


@pytest.mark.parametrize("name,icr", [("icr-physics", True), ("tracks-box", False)])
def test_the_icr_parameters_are_said_to_enter_at_the_vertices_not_in_b_d(name, icr, tmp_path) -> None:
    """B_D and B_d carry mu_r and mu_l only; with slip.model icr model.md says where the yaw factor and
    x_icr enter (a review found the page listing only mu_r and mu_l there, as if the ICR model had no more)."""
    model_stage(load_config(ROOT / "configs" / f"{name}.yaml"), tmp_path)
    text = (tmp_path / "model.md").read_text()
    assert ("The yaw factor and the ICR offset x_icr do not appear in them" in text) == icr
    assert ("| yaw factor | yaw |" in text) == icr and ("| ICR offset | x_icr |" in text) == icr
