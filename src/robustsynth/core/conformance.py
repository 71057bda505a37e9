"""The conformance suite every plant passes (:class:`robustsynth.core.plant.Plant`), as scikit-learn's
``check_estimator`` is for its estimators: a new plant is done when :func:`check_plant` passes on it.

Each check is a ``robustsynth.results.Check``:

- **shapes**: the lifted map's shapes, also batched over two leading axes;
- **the lifted map is the plant's ODE over a period**: at random admissible switching instants (delays
  and losses drawn from the plant's :class:`~robustsynth.core.network.Network`) and at every parameter
  corner, the first n_x rows of ``A~ xi + B~ u`` against the continuous plant integrated piece by
  piece with the command in force (scipy's DOP853 at rtol 1e-10: a method independent of the matrix
  exponentials and closed forms the plants use).  The extra states after the commands (the robot's
  integrators) start at zero and their own rows are not checked here: they are the plant's own
  discrete law (tested beside it);
- **the commands' shift register**: the newest command enters slot 1, each stored one moves down;
- **the network's depth**: the lifted state keeps every command that can still act
  (tau_max + m Ts <= d_hi Ts);
- **coverage**: the plant's vertex description contains its exact map on random samples;
- **to_dict**: plain JSON that reads back equal, whose ``kind`` is the plant's ``plant_kind`` (what the library
  dispatches on: ``robustsynth.synthesize``, ``robustsynth.verify``, the objectives a plant kind serves).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from ..results import Check
from .network import s_tilde_sequence
from .plant import Plant

__all__ = ["check_plant", "ODE_TOL", "period_by_ode"]

ODE_TOL = 1e-7  # relative gap between the lifted map and DOP853 at rtol 1e-10, atol 1e-12 over one period
DEPTH_TOL = 1e-9  # relative slack on tau_max + m Ts <= d_hi Ts (the delay range is given in decimals)


def period_by_ode(A_c: np.ndarray, B_c: np.ndarray, Ts: float, x0: np.ndarray, commands: np.ndarray,
                  s_tilde: np.ndarray) -> np.ndarray:
    """x(Ts) of ``x' = A_c x + B_c u(t)`` from ``x0`` when ``commands[j]`` = u_{k-j} (j = 0..d_hi) is in
    force on [s~_j, s~_{j-1}) (s~_{-1} = Ts; the oldest from 0), integrated piece by piece."""
    from scipy.integrate import solve_ivp

    d_hi = len(s_tilde)
    edges = np.concatenate([[0.0], np.asarray(s_tilde, dtype=float)[::-1], [Ts]])  # 0, s~_{d-1}, ..., s~_0, Ts
    x = np.asarray(x0, dtype=float)
    for i in range(d_hi + 1):
        a, b = edges[i], edges[i + 1]
        if b <= a:
            continue
        u = commands[d_hi - i]
        sol = solve_ivp(lambda t, z: A_c @ z + B_c @ u, (a, b), x, method="DOP853", rtol=1e-10, atol=1e-12)
        x = sol.y[:, -1]
    return x


def _instants(plant: Plant, rng: np.random.Generator, samples: int) -> np.ndarray:
    """Admissible switching instants (samples + 2, d_hi): random delays with the link's losses, and the
    two constant extremes."""
    net, d = plant.network, plant.d_hi
    steps = d + 2
    taus = net.lose(net.uniform(rng, (samples, d + steps)), rng, 0.3, max(1.0, net.max_lost), arrived=d)
    ends = np.vstack([net.pattern(k, (1, d + steps)) for k in ("constant-min", "constant-max")])
    return s_tilde_sequence(np.vstack([taus, ends]), net.sampling_time, d)[:, -1]


TO_DICT = "to_dict is plain JSON that reads back equal, of kind plant_kind"


def check_plant(plant: Plant, samples: int = 6, seed: int = 0) -> list[dict[str, Any]]:
    """The conformance checks of the module docstring on ``plant``.

    Parameters
    ----------
    plant : Plant
        The plant to check (:class:`~robustsynth.core.plant.Plant`).
    samples : int
        Random admissible switching instants (the two constant extremes are added), each at every
        parameter corner, for the ODE check.
    seed : int
        Seeds the instants, states and commands drawn.

    Returns
    -------
    list of dict
        One ``robustsynth.results.Check`` dict per check (name, passed, value, threshold, detail); a
        conforming plant passes all.
    """
    rng = np.random.default_rng(seed)
    n_x, n_u, d, n_s = plant.n_x, plant.n_u, plant.d_hi, plant.n_s
    corners = np.asarray(plant.parameter_corners(), dtype=float)
    theta = None if corners.shape[-1] == 0 else corners
    s = _instants(plant, rng, samples)
    out: list[Check] = []

    # shapes, also batched over (instants, corners)
    th = None if theta is None else theta[None, :, :]
    A, B = plant.lifted(s[:, None, :], th)
    want = (len(s), 1 if theta is None else len(corners))

    def batch_ok(M: np.ndarray) -> bool:  # a map that does not depend on theta may keep that axis at 1
        try:
            return np.broadcast_shapes(M.shape[:-2], want) == want and M.ndim == 4
        except ValueError:
            return False

    ok = A.shape[-2:] == (n_s, n_s) and B.shape[-2:] == (n_s, n_u) and batch_ok(A) and batch_ok(B)
    if ok:
        A, B = np.broadcast_to(A, want + A.shape[-2:]), np.broadcast_to(B, want + B.shape[-2:])
    out.append(Check("shapes of the lifted map", bool(ok and n_s >= n_x + d * n_u), f"{A.shape} {B.shape}",
                     f"(..., {n_s}, {n_s}) (..., {n_s}, {n_u})", f"n_x {n_x}, n_u {n_u}, d_hi {d}"))

    if not ok:  # the other checks index the batch
        return [c.to_dict() for c in out]

    # the lifted map against the ODE
    worst = 0.0
    Ts = plant.network.sampling_time
    for c in range(want[1]):
        A_c, B_c = plant.continuous(None if theta is None else corners[c])
        for i in range(len(s)):
            xi = rng.normal(size=n_s)
            xi[n_x + d * n_u:] = 0.0
            u = rng.normal(size=n_u)
            cmds = np.vstack([u, xi[n_x : n_x + d * n_u].reshape(d, n_u)]) if d else u[None]
            x_ode = period_by_ode(A_c, B_c, Ts, xi[:n_x], cmds, s[i])
            x_lift = (A[i, c] @ xi + B[i, c] @ u)[:n_x]
            worst = max(worst, float(np.max(np.abs(x_lift - x_ode)) / max(1.0, float(np.max(np.abs(x_ode))))))
    out.append(Check("the lifted map is the plant's ODE over a period", worst <= ODE_TOL, worst, ODE_TOL,
                     f"{len(s)} instants x {want[1]} parameter corners, DOP853"))

    # the commands' shift register
    E = np.zeros((d * n_u, n_s))  # the rows of the stored commands: u_k into slot 1, slot j into j + 1
    E_B = np.zeros((d * n_u, n_u))
    E_B[:n_u] = np.eye(n_u)[: d * n_u]
    for j in range(1, d):
        E[j * n_u : (j + 1) * n_u, n_x + (j - 1) * n_u : n_x + j * n_u] = np.eye(n_u)
    rows = slice(n_x, n_x + d * n_u)
    gap = max(float(np.max(np.abs(A[..., rows, :] - E), initial=0.0)),
              float(np.max(np.abs(B[..., rows, :] - E_B), initial=0.0)))
    out.append(Check("the commands' shift register", gap == 0.0, gap, 0.0, f"{d} stored commands of {n_u}"))

    # the network's depth
    net = plant.network
    need = (net.delay_max + net.max_lost * Ts) / Ts
    out.append(Check("the lifted state keeps every command that can act", need <= d * (1.0 + DEPTH_TOL), need, d,
                     f"(tau_max + m Ts) / Ts, tau_max {net.delay_max:g} s, m {net.max_lost}"))

    cov = plant.coverage()
    out.append(Check("the vertex description covers the exact map", bool(cov["passed"]), cov.get("samples"), None,
                     ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in cov.items()
                               if k not in ("passed",))))

    d0 = plant.to_dict()
    try:
        text = json.dumps(d0, allow_nan=False, sort_keys=True)
    except (TypeError, ValueError) as exc:  # arrays, NaN, objects: not plain JSON
        out.append(Check(TO_DICT, False, None, None, f"not JSON: {exc}"))
    else:
        kind = getattr(plant, "plant_kind", None)
        ok = json.loads(text) == d0 and bool(d0.get("kind")) and d0.get("kind") == kind
        out.append(Check(TO_DICT, ok, len(text), None,
                         f"kind {d0.get('kind')!r}, plant_kind {kind!r}"))
    return [c.to_dict() for c in out]
