"""The deployable controller: a verified gain with its memory, path and motor mapping.

No cvxpy, no matplotlib: reading a gains file needs the config module (pydantic, PyYAML) and, for
a ``.mat``, scipy; stepping needs nothing beyond the Python standard library."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .law import SEGMENT_EPS
from .law import Controller as _PureController

__all__ = ["Controller", "controller_description", "DESCRIPTION_FORMAT"]

DESCRIPTION_FORMAT = "robustsynth-controller/1"


def controller_description(gains: dict[str, Any], config: Any | None = None) -> dict[str, Any]:
    """Everything a controller needs, as plain data (what ``export --to json`` writes): the gain,
    sampling time, lifting, integrators, path, reference speed and the motor mapping and limit.

    ``config`` (a :class:`~robustsynth.config.Config`) supplies the path; by default the config
    stored in the gains file (the one it was verified with), else the embedded default.  A config
    whose sampling time, reference speed or integral action differs from the gain's is refused:
    the gain would run a law nobody verified."""
    from pydantic import ValidationError

    from ..config import Config, _format_validation_error, load_config
    from ..errors import InputError
    from ..model import gain_lifting, state_names

    stored = gains.get("config")
    try:
        base = Config.model_validate(stored) if isinstance(stored, dict) else None
    except ValidationError as exc:
        raise InputError(f"config (in the gains file): {_format_validation_error(exc)}") from None
    cfg = config if config is not None else (base if base is not None else load_config(None))
    if base is not None and config is not None:
        for key, a, b in (("network.sampling_time", base.network.sampling_time, cfg.network.sampling_time),
                          ("reference.speed", base.reference.speed, cfg.reference.speed),
                          ("synthesis.integral_action", base.synthesis.integral_action, cfg.synthesis.integral_action)):
            if a != b:
                raise InputError(f"{key}: {b!r} in the config, but the gain was designed with {a!r}")
    integral = cfg.synthesis.integral_action
    K = [[float(v) for v in row] for row in gains["K"]]
    try:
        d_hi = gain_lifting(K, integral)
    except (InputError, ValueError):  # ragged rows too
        raise InputError(f"K: has {len(K)} x {len(K[0]) if K else 0} entries; a controller needs 2 rows of "
                         f"3 + 2 d_hi{' + 2' if integral else ''} (integral_action is {str(integral).lower()})") from None
    names = gains.get("state_names")
    rob = cfg.robot
    return {
        "format": DESCRIPTION_FORMAT,
        "name": cfg.name,
        "gains_id": gains.get("gains_id"),
        "law": "u_hat_k = [V^D, 0] + K xi_k, xi_k = [e_x, e_y, e_theta, du_{k-1}, ..., du_{k-d_hi}(, int_e_x, int_e_y)]",
        "K": K,
        "state_names": list(names) if isinstance(names, list) and len(names) == len(K[0]) else list(state_names(d_hi, integral)),
        "input_names": ["dV", "omega"],
        "sampling_time": cfg.network.sampling_time,
        "d_hi": d_hi,
        "integral_action": integral,
        "reference_speed": cfg.reference.speed,
        "path": [[float(x), float(y)] for x, y in cfg.verification.path],
        "segment_eps": SEGMENT_EPS,
        "gear_radius": rob.gear_radius,
        "track_distance": rob.track_distance,
        "max_motor_speed": rob.max_motor_speed,
        "certified": gains.get("certified"),
    }


class Controller(_PureController):
    __doc__ = _PureController.__doc__

    @classmethod
    def from_files(cls, gains_path: str | Path, config_path: str | Path | None = None) -> "Controller":
        """The controller of a ``gains.json`` (or ``gains.mat``); the path and reference speed come
        from ``config_path``, else from the config stored in the gains file, else the embedded
        default."""
        from ..config import load_config
        from ..verification.checks import load_gains

        gains = load_gains(gains_path)
        return cls(controller_description(gains, load_config(config_path) if config_path is not None else None))
