"""Interoperability with python-control (optional extra ``robustsynth[control]``).

:func:`to_statespace` gives the closed-loop lifted system of a gain at fixed switching instants
and slip as a discrete-time ``control.StateSpace`` (dt = Ts) with named signals:

    xi_{k+1} = (A(s) + B(s) K) xi_k + B(s) w_k + c(mu) v_k
    y_k      = [e_k; du_k] = [I 0] xi_k ; K xi_k + w_k

Inputs: ``w_dV``, ``w_omega`` (a disturbance added to the command the controller sends, stored
in its memory like the command) and ``slip`` (the slip offset c(mu) = B~_d (mu - 1); a unit step
of it, from xi = 0, is the transition to the steady state of the constant slip mu).  Outputs: the
errors and the corrections sent.  The time-varying delay and slip of the certificate are not in a
frozen system: use it for intuition and classical analysis, not as a guarantee.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError

__all__ = ["to_statespace", "closed_loop_matrices", "lti_config"]


def _gain(model: Any, gains: Any) -> np.ndarray:
    if hasattr(gains, "K"):  # a SynthesisResult
        gains = gains.K
    K = np.asarray(gains["K"] if isinstance(gains, dict) else gains, dtype=float)
    if K.shape != (model.n_u, model.n_s):
        raise InputError(f"K: has shape {K.shape}, the model needs {(model.n_u, model.n_s)}")
    return K


def closed_loop_matrices(model: Any, gains: Any, instants: Any = None, slip: Any = None) -> dict[str, np.ndarray]:
    """(A, B, C, D) of :func:`to_statespace` as numpy arrays, with the instants and slip used."""
    K = _gain(model, gains)
    s = model.nominal_instants() if instants is None else np.asarray(instants, dtype=float).reshape(-1)
    if s.shape != (model.d_hi,):
        raise InputError(f"instants: need {model.d_hi} switching instants (one per stored command), got {s.size}")
    if np.any(s < 0) or np.any(s > model.Ts):
        raise InputError(f"instants: must lie in [0, Ts = {model.Ts:g}] s")
    mid = np.array([(lo + hi) / 2.0 for lo, hi in model.slip_ranges])
    mu = mid if slip is None else np.asarray(slip, dtype=float).reshape(-1)
    if mu.shape != mid.shape or np.any(mu[:2] <= 0):
        raise InputError(f"slip: need ({', '.join(model.slip_names)}), the tracks' factors > 0")
    A, B = model.exact(s, mu)
    c = model.constant(mu)
    n_e = model.n_e
    C = np.vstack([np.eye(n_e, model.n_s), K])
    D = np.vstack([np.zeros((n_e, model.n_u + 1)), np.hstack([np.eye(model.n_u), np.zeros((model.n_u, 1))])])
    return {"A": A + B @ K, "B": np.hstack([B, c[:, None]]), "C": C, "D": D, "instants": s, "slip": mu}


def to_statespace(model: Any, gains: Any, instants: Any = None, slip: Any = None):
    """The closed loop of ``gains`` (a gains mapping, a SynthesisResult or K) on ``model`` at the
    switching instants ``instants`` (d_hi values in [0, Ts]; default the middle of each range)
    and slip ``slip`` = (mu_r, mu_l) (default the middle of the slip box), as a discrete-time
    ``control.StateSpace`` with dt = Ts and named states, inputs and outputs.

    Parameters
    ----------
    model : Model
        The robot's lifted model.
    gains : Mapping, SynthesisResult or numpy.ndarray
        The gain.
    instants : sequence of float or None
        The switching instants (above).
    slip : sequence of float or None
        The slip (above).

    Returns
    -------
    control.StateSpace
        The closed loop, discrete time.
    """
    try:
        import control
    except ImportError:
        raise InputError("python-control is not installed: pip install 'robustsynth[control]'") from None
    m = closed_loop_matrices(model, gains, instants, slip)
    return control.ss(m["A"], m["B"], m["C"], m["D"], model.Ts, name=f"{model.config.name}-closed-loop",
                      states=list(model.state_names),
                      inputs=["w_dV", "w_omega", "slip"],
                      outputs=[*model.state_names[: model.n_e], "dV", "omega"])


def lti_config(sys: Any, *, sampling_time: float, delay: Any, max_consecutive: int = 0, name: str = "lti",
               **sections: Any) -> Any:
    """A ``plant: kind: lti`` config (:class:`robustsynth.config.LtiConfig`) from a continuous-time
    python-control ``StateSpace``: its A and B, its state names, and its C (with the output names) as
    the outputs the certificate bounds.  ``sections``: the config's other keys, e.g.
    ``disturbance={"E": ..., "bound": ...}``, ``input_limits=[...]``, ``controller={"gain": ...}``,
    ``synthesis={...}``, ``margin={...}`` (plant keys go into ``plant``).  Problems raise ConfigError
    naming the key, as for a YAML file.

    Parameters
    ----------
    sys : control.StateSpace
        A continuous-time plant.
    sampling_time : float
        Ts [s].
    delay : tuple of float
        (tau_min, tau_max) [s].
    max_consecutive : int
        Commands lost in a row at most.
    name : str
        The scenario's name.
    **sections : Any
        Other keys of the config (above).

    Returns
    -------
    LtiConfig
        The validated config.
    """
    from .config import config_from_dict

    for attr in ("A", "B", "C", "dt"):
        if not hasattr(sys, attr):
            raise InputError(f"sys: not a python-control StateSpace (no {attr})")
    if sys.dt not in (0, None):
        raise InputError(f"sys: must be continuous time (dt = 0), got dt = {sys.dt}: robustsynth samples the plant itself")
    A, B, C = (np.asarray(getattr(sys, k), dtype=float) for k in ("A", "B", "C"))
    D = np.asarray(getattr(sys, "D", np.zeros((C.shape[0], B.shape[1]))), dtype=float)
    if D.size and np.any(D != 0) and "outputs" not in sections:
        raise InputError("sys: has a feedthrough D != 0; the certificate bounds y = C x only (pass outputs=... to "
                         "choose the bounded outputs yourself)")
    plant: dict[str, Any] = {"kind": "lti", "A": A.tolist(), "B": B.tolist()}
    states = list(getattr(sys, "state_labels", None) or [])
    if len(states) == A.shape[0]:
        plant["states"] = states
    plant_keys = {"disturbance", "input_limits", "outputs", "units"}
    for key in plant_keys & set(sections):
        plant[key] = sections.pop(key)
    if "outputs" not in plant and C.size:
        labels = list(getattr(sys, "output_labels", None) or [])
        plant["outputs"] = {"C": C.tolist(), **({"names": labels} if len(labels) == C.shape[0] else {})}
    data = {"name": name, "plant": plant,
            "network": {"sampling_time": sampling_time, "delay": {"min": float(delay[0]), "max": float(delay[1])},
                        "dropouts": {"max_consecutive": max_consecutive}}, **sections}
    return config_from_dict(data)
