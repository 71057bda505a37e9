"""The slip-compensated law's certificate model (robustsynth.model.compensation, docs/theory.md §18) and its
arithmetic (robustsynth.law.compensate, Compensator): the ratio box holds every mu / mu_hat the condition allows,
the compensated command's tracks move as the law asked, floats and arrays agree bit for bit, and bad settings are
refused with the key named."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.config import ConfigError, config_from_dict, config_to_dict, load_config
from robustsynth.law import Compensator, compensate
from robustsynth.model.compensation import certificate_config, compensation_of

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "configs" / "harsh-compensated.yaml"
REL = 1e-12  # round-off of a few operations on numbers of order 1


def _cfg(**slip):
    d = config_to_dict(load_config(CONFIG))
    d["slip"].update(slip)
    return config_from_dict(d)


def test_the_certificate_config_is_the_ratio_box_and_the_lower_motor_limit() -> None:
    cfg = load_config(CONFIG)
    comp = compensation_of(cfg)
    cc = certificate_config(cfg, comp)
    e = comp.error
    assert cc.slip.compensation is None and cc.slip.max_rate is None and cc.slip.model == "tracks"
    for rng, lo in ((cc.slip.right, cfg.slip.right.min), (cc.slip.left, cfg.slip.left.min)):
        assert math.isclose(rng.min, 1.0 - e / lo, rel_tol=REL) and math.isclose(rng.max, 1.0 + e / lo, rel_tol=REL)
    assert math.isclose(cc.robot.max_motor_speed, cfg.robot.max_motor_speed * min(cfg.slip.right.min, cfg.slip.left.min),
                        rel_tol=REL)
    # everything else is the user's
    a, b = config_to_dict(cfg), config_to_dict(cc)
    for key in ("network", "reference", "synthesis", "verification", "monitor"):
        assert a[key] == b[key]


def test_auto_error_is_the_a_priori_bound_at_action_with_its_stated_headroom() -> None:
    from robustsynth.model.compensation import AUTO_HEADROOM
    from robustsynth.monitor import slip_estimate_bound
    from robustsynth.model.compensation import estimate_description

    cfg = _cfg(compensation={"error": "auto"})
    comp = compensation_of(cfg)
    bound = slip_estimate_bound(estimate_description(cfg))
    assert comp.error_auto and math.isclose(comp.error, AUTO_HEADROOM * max(bound["at_action"].values()), rel_tol=REL)
    assert not compensation_of(_cfg(compensation={"error": 0.05})).error_auto


@settings(max_examples=200, deadline=None)
@given(st.floats(0.6, 1.0), st.floats(0.6, 1.0), st.floats(-1.0, 1.0), st.floats(0.005, 0.2))
def test_every_ratio_the_condition_allows_is_in_the_ratio_box(mu_hat, frac, sign, e) -> None:
    """mu_hat in the box (the estimate is clamped to it) and |mu - mu_hat| <= e with mu in the box: mu / mu_hat lies
    in [1 - e / lo, 1 + e / lo] (the box the certificate is built on)."""
    lo = 0.6
    mu = min(max(mu_hat + sign * e * frac, 0.6), 1.0)
    ratio = mu / mu_hat
    assert 1.0 - e / lo - 1e-15 <= ratio <= 1.0 + e / lo + 1e-15


@settings(max_examples=200, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(-2.0, 2.0), st.floats(0.3, 1.5), st.floats(0.3, 1.5), st.floats(0.1, 0.5))
def test_the_compensated_tracks_move_as_the_law_asked(v, w, mu_r, mu_l, half_D) -> None:
    """A track with traction mu_hat moves at mu_hat times its command: the compensated command's tracks, times
    mu_hat, are the law's own track speeds (closed form against the arithmetic), and numpy arrays give the floats'
    values bit for bit (the simulator's vectorized law is the deployed one)."""
    vc, wc = compensate(v, w, mu_r, mu_l, half_D)
    assert math.isclose((vc + wc * half_D) * mu_r, v + w * half_D, rel_tol=1e-12, abs_tol=1e-12)
    assert math.isclose((vc - wc * half_D) * mu_l, v - w * half_D, rel_tol=1e-12, abs_tol=1e-12)
    av, aw = compensate(np.array([v, 0.5]), np.array([w, 0.1]), np.array([mu_r, 0.8]), np.array([mu_l, 0.7]), half_D)
    assert av[0] == vc and aw[0] == wc


def _estimate(half, mu=(0.8, 0.7), consistent=True, windows=3):
    return {"consistent": consistent, "windows": windows, "estimate": {"mu_r": mu[0], "mu_l": mu[1]},
            "bound": {"mu_r": half[0], "mu_l": half[1]}}


def test_the_compensator_holds_exactly_when_half_width_plus_lag_is_within_the_error() -> None:
    # binary fractions, so that the boundary case is exact: 0.046875 + 0.015625 = 0.0625
    c = Compensator({"track_distance": 0.45, "d_hi": 1, "compensation": {"error": 0.0625, "lag": 0.015625,
                                                                          "box": [[0.6, 1.0], [0.6, 1.0]]}})
    assert c.mu == (0.8, 0.8) and not c.holds and not c.covered  # the box's centre before any estimate
    assert not c.update(_estimate((0.046875, 0.03)))  # on the boundary: holds, but the command before did not
    assert c.holds and c.mu == (0.8, 0.7) and c.margin == 0.0
    assert c.update(_estimate((0.046875, 0.03)))  # d_hi = 1: two in a row cover the next state
    assert not c.update(_estimate((0.03, 0.046876)))  # the worse track decides
    assert not c.holds and c.margin < 0.0
    assert not c.update(_estimate((0.01, 0.01))) and c.holds  # the failed command can still act
    assert c.update(_estimate((0.01, 0.01)))
    assert not c.update(_estimate((0.01, 0.01), mu=(0.9, 0.9), consistent=False))  # no traction explains the data:
    assert c.mu == (0.8, 0.7) and c.margin is None and not c.holds  # the last consistent estimate is kept
    assert not c.update(None) and not c.update(_estimate((0.01, 0.01), windows=0))
    c.reset()
    assert c.mu == (0.8, 0.8) and not c.holds and not c.covered


@pytest.mark.parametrize("slip, key", [
    ({"model": "icr", "yaw": {"min": 0.5, "max": 0.7}, "icr_offset": {"min": 0.0, "max": 0.1}}, "slip.compensation"),
    ({"max_rate": None}, "slip.compensation"),
    ({"compensation": {"error": 0.6}}, "slip.compensation.error"),
    ({"compensation": {"error": -0.1}}, "slip.compensation.error"),
])
def test_bad_compensation_settings_name_their_key(slip, key) -> None:
    with pytest.raises(ConfigError) as exc:
        _cfg(**slip)
    msg = str(exc.value)
    assert msg.startswith(key) and "\n" not in msg


def test_an_auto_error_that_leaves_no_positive_ratio_is_refused() -> None:
    """Pose noise that leaves the estimate the box, on a box down to 0.2: 1.5 x (0.4 + lag) is past the smallest
    traction, so no compensated certificate exists; one line naming the key."""
    d = config_to_dict(_cfg(right={"min": 0.2, "max": 1.0}, left={"min": 0.2, "max": 1.0}))
    d["verification"]["noise"] = {"position": 0.05, "heading": 0.05}
    with pytest.raises(ConfigError, match=r"^slip\.compensation\.error: auto gives"):
        compensation_of(config_from_dict(d))
