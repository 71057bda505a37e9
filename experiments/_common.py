"""Shared helpers of the experiments (not part of the robustsynth package)."""

from __future__ import annotations

import copy
from typing import Any

import yaml

from robustsynth.config import Config, default_config_text


def config(**overrides: Any) -> Config:
    """The default config with dotted-path overrides, e.g. config(**{"slip.right.min": 0.4})."""
    d = copy.deepcopy(yaml.safe_load(default_config_text()))
    for path, value in overrides.items():
        node = d
        keys = path.split(".")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        node[keys[-1]] = value
    return Config.model_validate(d)


def motor_lmis(cp, np, model, Q, Y):
    """[[u^2, c_i' Y], [Y' c_i, Q]] >= 0 with u = rho_max - V^D/R (math.md §5c)."""
    cfg = model.config
    ub = cfg.robot.max_motor_speed - cfg.reference.speed / cfg.robot.gear_radius
    out = []
    for c in np.asarray(model.J_inv):
        row = c @ Y
        blk = cp.bmat([[np.array([[ub**2]]), cp.reshape(row, (1, model.n_s), order="C")],
                       [cp.reshape(row, (model.n_s, 1), order="C"), Q]])
        out.append((blk + blk.T) / 2 >> 0)
    return out
