"""The gains file: one home for its format.

``gains.json`` (and ``gains.mat``, the same names MATLAB-friendly) is what ``synthesize`` writes
and what ``verify``, ``margin``, ``export`` and the deployed :class:`~robustsynth.runtime.Controller`
read.  This module owns all of it: the schema (:data:`SCHEMA_VERSION` of the output files), the
mapping written (:func:`gains_dict`) and its id (:func:`gains_id`), the ``.mat`` variables
(:func:`gains_mat_vars`), reading either file with one-line errors (:func:`load_gains`), what a
user may hand to the API instead (:func:`as_gains`), and the controller description derived from
it (:func:`controller_description`, what ``export --to json`` writes and the exports bake in).

It sits below everything that uses the file (runtime, verification, report, export, CLI) and
imports only the config, the model's naming helpers, the control law's constants and (for the multipliers' compact
form) the certificate's LMI module.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..errors import InputError
from ..objectives import certified_keys
from .files import SCHEMA_VERSION

__all__ = ["written_by_robustsynth", "gains_dict", "gains_id", "certified_figures", "gains_mat_vars", "load_gains", "as_gains", "stored_config", "controller_description",
           "same_plant", "lti_gain", "LAW", "DESCRIPTION_FORMAT", "MAX_GAINS_BYTES", "SCHEMA_VERSION"]

LAW = "du_k = K xi_k"
DESCRIPTION_FORMAT = "robustsynth-controller/1"
MAX_GAINS_BYTES = 8 << 20


def certified_figures(figs: dict[str, Any]) -> dict[str, Any]:
    """A gains file's "certified" mapping from a certificate check's figures: ``objectives.certified_keys()``, and |e_theta(t)|
    between samples, the nonlinear proof's bound and whether slip may change within a period where given."""
    certified = {k: figs.get(k) for k in certified_keys()}
    for k in ("heading_within_period", "heading_bound", "ultimate_bound_between_samples", "slip_within_period"):
        if figs.get(k) is not None:
            certified[k] = figs[k]
    return certified


def _overrides(config: Any, result: Any) -> dict[str, Any]:
    """The synthesis settings a result was made with that differ from ``config``'s (the command line's
    ``--objective``, ``--solver``, ``--multiplier``, or synthesize()'s keywords): with the config they reproduce
    the gain (review, stop 47: a file recorded only the config, whose settings its certificate contradicted).
    The config stays the file's, so that a stage writing beside it does not take it for another config's."""
    settings = getattr(result, "settings", None)
    if settings is None:
        return {}
    made, given = settings.model_dump(mode="json"), config.synthesis.model_dump(mode="json")
    return {k: v for k, v in made.items() if given.get(k) != v}


def gains_dict(model: Any, result: Any) -> dict[str, Any]:
    """The gains.json mapping of a synthesis result: the gain, the certified figures, the
    certificate (everything the numpy re-check needs), the solver's record and the config.  Many diagonal
    multipliers are written compactly (``{"diag": [...]}``, :func:`robustsynth.certificate.lmis.compact_multipliers`)."""
    from ..certificate.lmis import compact_multipliers
    from ..config import config_to_dict

    figs = result.certified
    cert = result.certificate
    certified = certified_figures(figs)
    certificate: dict[str, Any] = {
        "objective": cert["objective"],
        "model": cert["model"],
        "vertices": cert["vertices"],
        "lyapunov": cert["lyapunov"],
        "P": cert["P"],
    }
    if cert["lyapunov"] == "common":
        certificate["Q"] = cert["Q"]
    else:
        certificate["G"] = cert["G"]
        certificate["S"] = cert["S"]
        certificate["slip_step"] = cert.get("slip_step")
    certificate.update({
        "multipliers": dict(cert["multipliers"], M=compact_multipliers(cert["multipliers"]["M"])),
        "alpha": cert.get("alpha"),
        "beta": cert.get("beta"),
        "r2": cert.get("r2"),
        "gamma2": cert.get("gamma2"),
        "ellipsoid_level": figs.get("ellipsoid_level"),
        "motor_limits_enforced": cert.get("motor_limits_enforced", False),
        "margin": cert["margin"],
        "min_eig_margin_found": cert["min_eig_margin_found"],
        "checks": list(result.check.checks),
    })
    if cert.get("kinematics", "linearized") != "linearized":  # the certificate covers the exact arcs (theory §9)
        certificate["kinematics"] = cert["kinematics"]
        certificate["heading_bound"] = cert["heading_bound"]
    if cert.get("within_period_channels"):  # channels for slip changing within a period (theory §9, §10)
        certificate["within_period_channels"] = True
    if cert.get("turns") is not None:  # the reference yaw rates the certificate covers (model/arcs.py)
        certificate["turns"] = dict(cert["turns"])
    out = {
        "schema_version": SCHEMA_VERSION,
        "robustsynth_version": __version__,
        "config": config_to_dict(model.user_config),
        "K": result.K,
        "state_names": list(model.state_names),
        "input_names": list(model.input_names),
        "law": LAW,
        "objective": result.objective,
        "certified": certified,
        "certificate": certificate,
        "solver": {k: result.solver[k] for k in ("name", "version", "status", "iterations", "solve_time_s", "fallback_used")},
        "notes": list(result.notes),
    }
    if model.compensation is not None:  # the slip-compensated law: its certificate is on the ratio box (theory §18)
        out["compensation"] = model.compensation.to_dict()
    over = _overrides(model.config, result)
    if over:  # made with settings other than the config's: "synthesis.<key>" -> the value used
        out["synthesis_overrides"] = {f"synthesis.{k}": v for k, v in over.items()}
    out["gains_id"] = gains_id(out)
    return out


def gains_id(gd: dict[str, Any]) -> str:
    """sha256 of what defines a gain (config, K, certificate): identical for identical gains,
    unlike a hash of the file, which also holds the solver's timing.  ``synthesis.threads`` is left
    out: the lti line search visits the same points whatever it is, so it never changes the gain."""
    from .files import json_bytes, sha256

    cfg = gd.get("config")
    if isinstance(cfg, dict) and isinstance(cfg.get("synthesis"), dict) and "threads" in cfg["synthesis"]:
        cfg = dict(cfg, synthesis={k: v for k, v in cfg["synthesis"].items() if k != "threads"})
    return sha256(json_bytes({"config": cfg, "K": gd.get("K"), "certificate": gd.get("certificate")}))


def _mat_value(v: Any) -> Any:
    if v is None:
        return np.nan
    if isinstance(v, dict):
        return {k: _mat_value(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)) and v and isinstance(v[0], str):
        return np.array(v, dtype=object)
    return v


def _stack(mats: list[Any]) -> np.ndarray:
    """A list of equally shaped matrices as one 3-D array (vertex, row, col); empty ones as (n, 0, 0)."""
    arrs = [np.asarray(m, dtype=float) for m in mats]
    if not arrs:
        return np.zeros((0, 0, 0))
    return np.stack([a.reshape(a.shape if a.size else (0, 0)) for a in arrs])


def gains_mat_vars(gd: dict[str, Any]) -> dict[str, Any]:
    """The same names as gains.json, MATLAB-friendly (null -> NaN, lists of names -> cell arrays,
    per-vertex multipliers M and per-corner S as 3-D arrays indexed first by vertex / corner)."""
    from ..certificate.lmis import dense_multiplier

    c = gd["certificate"]
    lyap = {"P": np.asarray(c["P"], dtype=float), "Q": np.asarray(c["Q"], dtype=float)} if c["lyapunov"] == "common" else {
        "P": _stack(c["P"]), "G": np.asarray(c["G"], dtype=float), "S": _stack(c["S"])}
    return {
        "K": np.asarray(gd["K"], dtype=float),
        "state_names": _mat_value(gd["state_names"]),
        "input_names": _mat_value(gd["input_names"]),
        "law": gd["law"],
        "objective": gd["objective"],
        "model": c["model"],
        "lyapunov": c["lyapunov"],
        "certified": _mat_value(gd["certified"]),
        **lyap,
        "M": _stack([dense_multiplier(M) for M in c["multipliers"]["M"]]),
        "alpha": _mat_value(c["alpha"]),
        "beta": np.asarray(c["beta"] if c["beta"] is not None else np.nan, dtype=float),
        "r2": _mat_value(c["r2"]),
        "gamma2": _mat_value(c["gamma2"]),
        "multiplier": c["multipliers"]["kind"],
        "motor_limits_enforced": bool(c["motor_limits_enforced"]),
        "margin": c["margin"],
        "kinematics": c.get("kinematics", "linearized"),
        "heading_bound": _mat_value(c.get("heading_bound")),
        "within_period_channels": bool(c.get("within_period_channels", False)),
        "slip_step": _mat_value(c.get("slip_step")),  # a rate-bounded certificate's (NaN: any change)
        "turn_max_yaw_rate": _mat_value((c.get("turns") or {}).get("max_yaw_rate")),
        "turn_max_step": _mat_value((c.get("turns") or {}).get("max_step")),
        **_controller_mat_vars(gd),
    }


def _controller_mat_vars(gd: dict[str, Any]) -> dict[str, Any]:
    """What the C and ROS 2 exports carry: sampling time, lifting, integrators, path, limits."""
    d = controller_description(gd)
    rho = d["max_motor_speed"]
    return {
        "Ts": float(d["sampling_time"]),
        "d_hi": float(d["d_hi"]),
        "integral_action": bool(d["integral_action"]),
        "reference_speed": float(d["reference_speed"]),
        "path": np.asarray(d["path"], dtype=float),
        "turn_radius": float(d["turn_radius"]) if d.get("turn_radius") is not None else np.nan,  # NaN: a polyline
        "segment_eps": float(d["segment_eps"]),
        "gear_radius": float(d["gear_radius"]),
        "track_distance": float(d["track_distance"]),
        "max_motor_speed": float(rho) if rho is not None else np.nan,
        "config_json": json.dumps(gd["config"]),  # the whole config (MATLAB: jsondecode(config_json))
    }


def _mat_scalar(v: Any) -> Any:
    a = np.asarray(v)
    if a.dtype.kind in "US":
        return str(a.reshape(-1)[0]) if a.size else ""
    a = a.astype(float).reshape(-1)
    return None if a.size == 0 or not np.isfinite(a[0]) else float(a[0])


def _load_mat(p: Path) -> dict[str, Any]:
    """A gains.mat (ours, or any .mat with a matrix K) as the gains.json mapping.  The certificate
    is rebuilt when its parts (objective, Q, M, margin, ...) are present."""
    from scipy.io import loadmat

    try:
        m = loadmat(p, squeeze_me=False)
    except Exception as exc:  # scipy raises several types for a damaged file
        raise InputError(f"{p}: not a readable MATLAB .mat file ({exc})") from None
    if "K" not in m:
        raise InputError(f"{p}: K: required variable is missing")
    if "lti_gains_json" in m:  # a linear plant's: the gains file it was written with
        try:
            lti = json.loads(_mat_scalar(m["lti_gains_json"]))
            same = np.array_equal(np.asarray(lti["K"], dtype=float), np.asarray(m["K"], dtype=float))
        except (TypeError, ValueError, KeyError):
            raise InputError(f"{p}: lti_gains_json: not a gains file in JSON") from None
        if not same:
            raise InputError(f"{p}: K differs from the gain it was certified as (lti_gains_json): a changed gain "
                             "has no certificate")
        return lti
    data: dict[str, Any] = {"K": m["K"]}  # validated by load_gains like a JSON K
    if "config_json" in m:  # ours: the config the gain was designed and verified with
        try:
            data["config"] = json.loads(_mat_scalar(m["config_json"]))
        except (TypeError, ValueError):
            raise InputError(f"{p}: config_json: not valid JSON") from None
    if all(k in m for k in ("objective", "M", "margin")) and ("Q" in m or "S" in m):
        lyap = _mat_scalar(m.get("lyapunov", "common")) or "common"
        Ms = np.asarray(m["M"], dtype=float)
        Ms = [Ms[i] for i in range(Ms.shape[0])] if Ms.ndim == 3 else [Ms.reshape(Ms.shape if Ms.size else (0, 0))]
        beta = np.asarray(m.get("beta", np.nan), dtype=float).reshape(-1)
        cert: dict[str, Any] = {
            "objective": _mat_scalar(m["objective"]),
            "model": _mat_scalar(m.get("model", "paper")),
            "lyapunov": lyap,
            "multipliers": {"kind": _mat_scalar(m.get("multiplier", "structured")), "M": Ms},
            "alpha": _mat_scalar(m.get("alpha", np.nan)),
            "beta": None if beta.size == 0 or not np.all(np.isfinite(beta)) else beta,
            "r2": _mat_scalar(m.get("r2", np.nan)),
            "gamma2": _mat_scalar(m.get("gamma2", np.nan)),
            "motor_limits_enforced": bool(_mat_scalar(m.get("motor_limits_enforced", 0.0))),
            "margin": _mat_scalar(m["margin"]),
        }
        kin = _mat_scalar(m.get("kinematics", "linearized")) or "linearized"
        if kin != "linearized":
            cert["kinematics"] = kin
            cert["heading_bound"] = _mat_scalar(m.get("heading_bound", np.nan))
        if bool(_mat_scalar(m.get("within_period_channels", 0.0))):
            cert["within_period_channels"] = True
        turn = _mat_scalar(m.get("turn_max_yaw_rate", np.nan))
        if turn is not None:
            cert["turns"] = {"max_yaw_rate": turn, "max_step": _mat_scalar(m.get("turn_max_step", np.nan))}
        if lyap == "common":
            cert["Q"] = np.asarray(m["Q"], dtype=float)
            cert["P"] = np.asarray(m["P"], dtype=float) if "P" in m else np.linalg.inv(cert["Q"])
        else:
            S = np.asarray(m["S"], dtype=float)
            cert["S"] = [S[i] for i in range(S.shape[0])]
            cert["G"] = np.asarray(m["G"], dtype=float)
            # a rate-bounded certificate holds for its slip step only (a .mat without it re-checked as switching)
            cert["slip_step"] = _mat_scalar(m.get("slip_step", np.nan))
        data["certificate"] = cert
    return data


def load_gains(path: str | Path) -> dict[str, Any]:
    """Read a gains.json (or a .mat with a matrix K); InputError with the key path on anything
    malformed.

    Parameters
    ----------
    path : str or Path
        A ``gains.json``, or a ``.mat`` with a matrix ``K``.

    Returns
    -------
    dict
        The gains mapping (``K``, ``certificate``, ``config``, ...).

    Raises
    ------
    InputError
        A missing or malformed file, with the key path.
    """
    p = Path(path)
    try:
        if p.stat().st_size > MAX_GAINS_BYTES:
            raise InputError(f"{p}: file is larger than 8 MiB")
        data = _load_mat(p) if p.suffix.lower() == ".mat" else json.loads(p.read_text(encoding="utf-8"))
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError(f"{p}: gains file not found (run `robustsynth synthesize` first or pass --gains)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: cannot read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{p}: invalid JSON at line {exc.lineno}: {exc.msg}") from None
    if not isinstance(data, dict):
        raise InputError(f"{p}: must be a JSON object")
    if "K" not in data:
        raise InputError(f"{p}: K: required key is missing")
    try:
        K = np.asarray(data["K"], dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{p}: K: must be a matrix of numbers (list of rows)") from None
    if K.ndim != 2 or not np.all(np.isfinite(K)):
        raise InputError(f"{p}: K: must be a finite matrix (list of rows)")
    return data


def as_gains(model, gains: Any) -> dict[str, Any]:
    """A gains.json mapping from what a user holds: the mapping itself, a path to a gains file
    (.json or .mat), the result of :func:`~robustsynth.synthesis.synthesize`, or a bare matrix K
    (no certificate)."""
    if isinstance(gains, (dict, str, Path)):
        gd = gains if isinstance(gains, dict) else load_gains(gains)
        if gd.get("kind") == "lti":  # not a shape mismatch of the robot's K (a review found "another delay range?")
            raise InputError(f"{'gains' if isinstance(gains, dict) else gains}: a linear plant's gains (kind: lti); "
                             "this is the tracked robot's config")
        return gd
    if hasattr(gains, "K") and hasattr(gains, "certificate"):  # a SynthesisResult
        return gains_dict(model, gains)
    try:
        K = np.asarray(gains, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"gains: expected a gains mapping, a SynthesisResult or a matrix K (got {type(gains).__name__})") from None
    if K.ndim != 2:
        raise InputError(f"gains: a matrix K needs 2 dimensions (got shape {K.shape})")
    return {"K": K.tolist()}


def stored_config(gains: dict[str, Any]) -> Any:
    """The config stored in a gains mapping (the one the gain was designed and verified with), as a
    validated :class:`~robustsynth.config.Config`; None when there is none; InputError if invalid."""
    from pydantic import ValidationError

    from ..config import Config, _format_validation_error

    stored = gains.get("config")
    try:
        return Config.model_validate(stored) if isinstance(stored, dict) else None
    except ValidationError as exc:
        raise InputError(f"config (in the gains file): {_format_validation_error(exc)}") from None


def controller_description(gains: dict[str, Any], config: Any | None = None) -> dict[str, Any]:
    """Everything a controller needs, as plain data (what ``export --to json`` writes): the gain,
    sampling time, lifting, integrators, path, reference speed and the motor mapping and limit.

    ``config`` (a :class:`~robustsynth.config.Config`) supplies the path; by default the config
    stored in the gains file (the one it was verified with), else the embedded default.  A config
    whose sampling time, reference speed or integral action differs from the gain's is refused:
    the gain would run a law nobody verified."""
    from ..config import load_config
    from ..law import SEGMENT_EPS  # the law is plain Python and imports nothing of ours
    from ..model import gain_lifting, state_names
    from ..model.slip import turn_feedforward

    base = stored_config(gains)
    cfg = config if config is not None else (base if base is not None else load_config(None))
    if base is not None and config is not None:
        for key, a, b in (("network.sampling_time", base.network.sampling_time, cfg.network.sampling_time),
                          ("reference.speed", base.reference.speed, cfg.reference.speed),
                          ("synthesis.integral_action", base.synthesis.integral_action, cfg.synthesis.integral_action)):
            if a != b:
                raise InputError(f"{key}: {b!r} in the config, but the gain was designed with {a!r}")
        # a turning certificate covers arcs of its radius and wider (slower turns), not tighter ones
        r_gain, r_cfg = base.reference.turn_radius, cfg.reference.turn_radius
        if (r_cfg is None) != (r_gain is None) or (r_cfg is not None and r_cfg < r_gain):
            raise InputError(f"reference.turn_radius: {r_cfg!r} in the config, but the gain was certified for "
                             + ("straight segments only (null)" if r_gain is None else f"arcs of {r_gain!r} m and wider "
                                "(a path that jumps at its waypoints is not what it was verified on)"))
        if (base.slip.compensation is None) != (cfg.slip.compensation is None):
            raise InputError("slip.compensation: " + ("none in the config, but the gain was certified for the "
                             "slip-compensated law" if cfg.slip.compensation is None else "set in the config, but the "
                             "gain was certified without it") + " (the law would not be the one verified)")
        # eased turns: a shorter ramp steps the yaw rate by more than the certificate covers
        ramp_gain, ramp_cfg = base.reference.turn_ramp, cfg.reference.turn_ramp
        if r_gain is not None and ramp_gain is not None and (ramp_cfg or 0.0) < ramp_gain:
            raise InputError(f"reference.turn_ramp: {ramp_cfg!r} in the config, but the gain was certified for turns eased "
                             f"in over {ramp_gain!r} s or longer (a shorter ramp steps the yaw rate by more)")
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
        "law": "u_hat_k = [V^D, 0] + w_k g + K xi_k, xi_k = [e_x, e_y, e_theta, du_{k-1}, ..., du_{k-d_hi}(, int_e_x, int_e_y)]"
               + (" (w_k: the turning reference's yaw rate, turn_radius; g: turn_feedforward)" if cfg.reference.turn_radius
                  is not None else " (w_k = 0: a polyline)"),
        "K": K,
        "state_names": list(names) if isinstance(names, list) and len(names) == len(K[0]) else list(state_names(d_hi, integral)),
        "input_names": ["dV", "omega"],
        "sampling_time": cfg.network.sampling_time,
        "d_hi": d_hi,
        "integral_action": integral,
        "reference_speed": cfg.reference.speed,
        "path": [[float(x), float(y)] for x, y in cfg.reference.path],
        "turn_radius": cfg.reference.turn_radius,
        "turn_ramp": cfg.reference.turn_ramp,
        # the command per rad/s of the reference's yaw rate (model.slip.turn_feedforward): (0, 1) for the tracks model
        "turn_feedforward": [float(v) for v in turn_feedforward(cfg.slip, cfg.robot.track_distance)],
        "segment_eps": SEGMENT_EPS,
        "gear_radius": rob.gear_radius,
        "track_distance": rob.track_distance,
        "max_motor_speed": rob.max_motor_speed,
        "certified": gains.get("certified"),
        "monitor": monitor_description(gains, cfg),
        "compensation": _compensation_description(gains, cfg),
    }


def _compensation_description(gains: dict[str, Any], config: Any) -> dict[str, Any] | None:
    """The slip-compensated law's part of a controller description (law.Compensator; docs/theory.md §18): the
    estimate error its certificate assumes (the gain's), what slip.max_rate lets the traction move while a command
    acts (``lag``, from ``config``) and the true slip box the estimate is clamped to.  None: no compensation."""
    if config.slip.compensation is None:
        return None
    from ..model.compensation import compensation_of

    comp = compensation_of(config)
    certified = (gains.get("compensation") or {}).get("error")
    return {"error": float(certified if certified is not None else comp.error), "lag": float(comp.bound["lag"]),
            "box": [[float(config.slip.right.min), float(config.slip.right.max)],
                    [float(config.slip.left.min), float(config.slip.left.max)]]}


def _certificate_motor_limit(config: Any) -> float | None:
    if config.slip.compensation is None:
        return config.robot.max_motor_speed
    from ..model.compensation import compensation_of

    return compensation_of(config).max_motor_speed


def monitor_description(gains: dict[str, Any], config: Any) -> dict[str, Any] | None:
    """What the runtime monitor (:mod:`robustsynth.monitor`) checks for this gain under ``config``: the delay
    range and loss cap, the certified set (its Lyapunov matrices and level) with the threshold V must pass for
    the true state to be outside it given the pose noise, the heading bound the kinematic channels assume, the
    motor limit, the slip box as the ranges of its six twist components (docs/theory.md §12), the noise bounds
    and the fallback (``config.monitor``).  None for a gain without a certificate's set (``P`` and
    ``ellipsoid_level``): there is nothing to monitor it against."""
    import numpy as np

    from ..law import PathTable
    from ..model.slip import icr_components

    cert = gains.get("certificate") or {}
    if cert.get("P") is None or cert.get("ellipsoid_level") is None:
        return None
    P = np.asarray(cert["P"], dtype=float)
    Ps = [P] if P.ndim == 2 else list(P)
    level = float(cert["ellipsoid_level"])
    from ..model.compensation import estimate_description

    mon, net = config.monitor, config.network
    est = estimate_description(config)["monitor"]  # the noise bounds, window, delay and slip box the estimate reads
    a, b = est["position_noise"], est["heading_noise"]
    # the measured error is the true one plus n, |n| <= (a, a, b) on e_x, e_y, e_theta: sqrt V moves by at most
    # sqrt(n' P n) <= sqrt(sum_ij |P_ij| n_i n_j) (the commands in xi are the controller's own, exact)
    n = np.array([a, a, b])
    shift = max(float(np.sqrt(n @ np.abs(Pm[:3, :3]) @ n)) for Pm in Ps)
    ranges = tuple(tuple(r) for r in est["slip_ranges"])
    comp = icr_components(ranges if len(ranges) == 4 else ranges + ((1.0, 1.0), (0.0, 0.0)))
    nonlinear = cert.get("kinematics") == "nonlinear" and cert.get("heading_bound") is not None
    return {
        "tau_min": float(net.delay.min), "tau_max": est["tau_max"], "max_lost": est["max_lost"],
        "clock_tol": mon.clock_tol,
        "P": [Pm.tolist() for Pm in Ps], "level": level,
        "set_threshold": float((np.sqrt(level) + shift) ** 2 * (1.0 + 1e-12)),
        "heading_limit": float(cert["heading_bound"]) + b if nonlinear else None,
        # a path without turns: its segments' start times (law.PathTable), where the error jumps to the next frame
        "segment_starts": [] if config.reference.turn_radius is not None else
        [float(v) for v in PathTable(config.reference.path, config.reference.speed).t_start],
        "set_entry": float(max(np.sqrt(level) - shift, 0.0) ** 2),
        # a compensated law: the MOTOR check is the certificate's limit on the uncompensated command (rho_max lo),
        # while the motors saturate at rho_max (docs/theory.md §18)
        "rho_limit": _certificate_motor_limit(config),
        "saturation_limit": config.robot.max_motor_speed,
        "window": est["window"], "components": comp.tolist(), "position_noise": a, "heading_noise": b,
        "model_tol": est["model_tol"], "fallback": mon.fallback, "persistence": mon.persistence,
        "slow_factor": mon.slow_factor,
        # what is sure to be flagged: a departure to V/level above set_ratio (the noise can hide 2 shifts of sqrt V),
        # a traction this far outside the box's forward range over a window driven straight at V^D (the slip check's
        # allowance, twice: the noise may move the estimate inside by one), within the window's time
        "detects": {"set_ratio": float(((np.sqrt(level) + 2.0 * shift) / np.sqrt(level)) ** 2),
                    "traction": float(2.0 * (np.sqrt(2.0) * a * 2.0 + mon.window * net.sampling_time * config.reference.speed
                                             * (b + mon.model_tol)) / (mon.window * net.sampling_time * config.reference.speed)),
                    "window_s": float(mon.window * net.sampling_time),
                    # with slip.max_rate: a jump of the traction sum this large, driven straight at V^D (the window's
                    # time at the rate, and each half's allowance twice: the noise may move each estimate by one)
                    **({"rate_jump": float(config.slip.max_rate * mon.window * net.sampling_time + 4.0 * (
                        np.sqrt(2.0) * a * 2.0 + (mon.window // 2) * net.sampling_time * config.reference.speed
                        * (b + mon.model_tol)) / ((mon.window // 2) * net.sampling_time * config.reference.speed))}
                       if config.slip.max_rate is not None else {})},
        "max_rate": est["max_rate"],
        # the slip estimate's box (monitor.Monitor.slip_estimate): the model and its parameters' ranges
        "slip_model": est["slip_model"], "slip_ranges": est["slip_ranges"],
    }


# ------------------------------------------------------------------ any linear plant (plant: kind: lti)


def lti_gains_dict(config: Any, plant: dict[str, Any], design: Any, overrides: dict[str, Any] | None = None,
                   delay_margin: dict[str, Any] | None = None) -> dict[str, Any]:
    """The gains.json mapping of a linear plant's synthesized gain (``kind: lti``): u_k = K xi_k on the
    lifted state xi = [x; u_{k-1}; ...; u_{k-d}], the certified set {xi' P xi <= 1} and its figures.
    ``overrides``: the settings it was made with that differ from the config's (key path -> value), recorded
    as ``synthesis_overrides`` (as for the robot); ``delay_margin``: the gain's delay margin
    (:func:`robustsynth.margins.linear.delay_margin`; margin.json's ``delay_max`` is the same search as a
    Margin), not part of its ``gains_id``."""
    from ..config import config_to_dict

    n, m = plant["B"].shape
    net = config.network
    from .files import record_header

    cert = design.certificate
    out = {
        **record_header(),
        "kind": "lti",
        "K": design.K,
        "law": "u_k = K xi_k, xi_k = [x_k; u_{k-1}; ...; u_{k-d}]",
        "lifting": {"n": n, "m": m, "d": (np.shape(design.K)[1] - n) // m, "states": plant["states"],
                    "units": plant["units"]},
        "objective": design.objective,
        "certified": design.certified,
        "certificate": {k: cert[k] for k in ("P", "alpha", "multipliers", "vertices", "pieces", "check")},
        "network": {"sampling_time": net.sampling_time, "delay": [net.delay.min, net.delay.max],
                    "max_consecutive": net.dropouts.max_consecutive},
        "solver": {"solves": design.solver["solves"], "time_s": design.solver["time_s"]},
        "config": config_to_dict(config),
    }
    if overrides:
        out["synthesis_overrides"] = dict(overrides)
    if delay_margin is not None:
        out["delay_margin"] = delay_margin
    from .files import to_jsonable

    out = to_jsonable(out)
    out["gains_id"] = gains_id(out)  # the files made from this gain carry it (verification.json, margin.json)
    return out


def lti_gains_mat_vars(gd: dict[str, Any]) -> dict[str, Any]:
    """The .mat variables of an lti gains mapping: K, P, Ts and the delay range."""
    from .files import json_bytes

    net = gd["network"]
    return {"K": np.asarray(gd["K"], dtype=float), "P": np.asarray(gd["certificate"]["P"], dtype=float),
            "Ts": float(net["sampling_time"]), "delay": np.asarray(net["delay"], dtype=float),
            "max_consecutive": int(net["max_consecutive"]), "d": int(gd["lifting"]["d"]),
            # the whole gains file: `verify` and `export` read the .mat as they read gains.json
            "lti_gains_json": json_bytes(gd).decode("utf-8")}


def written_by_robustsynth(path: Path) -> tuple[str, dict[str, Any]] | None:
    """What output file of robustsynth ``path`` is ('gains file', 'verification record (verification.json ...)',
    ...) and its top-level mapping, from its top-level keys; None when it is none (a config, or unreadable)."""
    try:
        if not path.is_file():  # a pipe is read once, by load_config
            return None
        with path.open("rb") as fh:
            raw = fh.read(MAX_GAINS_BYTES + 1)
    except OSError:
        return None
    if raw.startswith(b"MATLAB 5.0 MAT-file") or path.suffix.lower() == ".mat":
        return "gains file", {}
    try:
        data = json.loads(raw)
    except (ValueError, UnicodeDecodeError):
        return None
    if not isinstance(data, dict):
        return None
    has = data.__contains__
    if data.get("format") == DESCRIPTION_FORMAT or (data.get("kind") == "lti" and has("law") and has("n")):
        return "controller description (written by `robustsynth export --to json`)", data
    if has("K"):  # no config has a top-level K: gains.json (the robot's or a linear plant's), or a bare gain
        return "gains file", data
    if has("per_episode") and has("straight_max"):
        return "validation record (validation.json, written by `robustsynth validate`)", data
    if has("gains_id") and has("passed") and has("checks"):
        return "verification record (verification.json, written by `robustsynth verify`)", data
    if has("coverage_check") or (has("instants") and has("lifted_states")):
        return "model file (model.json, written by `robustsynth build-model`)", data
    if has("status") and (has("dimensions") or has("verification_passed") or has("margins")) \
            or (data.get("kind") == "lti" and has("verification")):
        return "run summary (summary.json, written by `robustsynth run`)", data
    if has("margins") and has("gain") or has("meta") and isinstance(data.get("meta"), dict) and "gains_id" in data["meta"]:
        return "margin record (margin.json, written by `robustsynth margin`)", data
    if has("rows") and has("columns") and has("spec"):
        return "sweep result (sweep.json, written by `robustsynth sweep`)", data
    if has("robustsynth_version") or has("schema_version"):
        return "file robustsynth wrote", data
    return None


def same_plant(gd: dict[str, Any], n: int, m: int, where: str | Path) -> None:
    """InputError unless a gains file is for a plant of n states and m inputs: a linear plant's file says so
    in ``lifting`` (a K alone is only checked for its shape: 1 x 4 reads as d = 2 on a 2-state plant and as
    d = 1 on a 3-state one, which a review found margin accepting); the robot's gains are refused."""
    if gd.get("kind") != "lti" and gd.get("certificate") is not None:
        raise InputError(f"{where}: the tracked robot's gains, not a linear plant's (kind: lti)")
    lift = gd.get("lifting")
    if isinstance(lift, dict) and (int(lift.get("n", n)), int(lift.get("m", m))) != (n, m):
        raise InputError(f"{where}: made for a plant of n = {lift.get('n')} states and m = {lift.get('m')} inputs; "
                         f"this config's has n = {n}, m = {m}")


def lti_gain(config: Any, plant: dict[str, Any], gains_path: str | Path | None,
             default: Path | None = None) -> tuple[np.ndarray, Path | None, dict[str, Any] | None]:
    """The gain to analyze and where it came from (the gains file and its mapping, or None twice): a gains
    file's K, else the config's controller.gain, else ``default`` (the output directory's gains.json)
    when it exists."""
    from ..core.delays import check_lti_gain

    n, m = plant["B"].shape
    if gains_path is None and plant["K"] is None and default is not None and default.is_file():
        gains_path = default
    if gains_path is not None:
        gd = load_gains(gains_path)
        K = np.asarray(gd["K"], dtype=float)
        same_plant(gd, n, m, gains_path)
        check_lti_gain(K, n, m, f"{gains_path}: K")
        return K, Path(gains_path), gd
    if plant["K"] is None:
        raise InputError("controller.gain: required for a linear plant's margin (or pass --gains, or synthesize "
                         "into the output directory first)")
    return plant["K"], None, None
