"""The tracked robot the controller acts on, with the network that delivers its commands.

Unicycle kinematics with slip, ``q_dot = G(theta) J H J^-1 u_hat`` (eq. 12), integrated exactly
between actuation events (constant V, omega: arcs); the motors saturate at rho_max.  The network
delivers the command sent at t_k from t_k + tau_k on, in order: within period k the commands
u_hat_k, ..., u_hat_{k-d_hi} act in turn on the intervals the switching instants s~ mark.  Slip is
constant within a period unless ``period`` is given a jump within it.

:class:`KinematicRobot` is the interface the Monte Carlo and the adversary drive (and the one a
physics-engine robot or a log replayer will offer): ``memory`` (the commands in flight at t_0),
``send`` (the command of t_k enters the network) and ``period`` (the robot moves to t_{k+1}).
Every method works on any leading shape of runs, so a search can branch a state into candidates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.kinematics import JHJinv
from ..model.slip import twist_matrix
from ..law import wrap_angle as law_wrap_angle

__all__ = ["KinematicRobot", "arc_step", "saturate", "period", "wrap_angle"]


def _compact(a: np.ndarray) -> np.ndarray:
    """``a`` without its broadcast axes (stride 0, more than one entry: index 0 kept): elementwise work on it
    and broadcasting back gives the same numbers as on ``a`` at a fraction of the cost (the adversary's candidates
    are broadcast views of a few slips and commands)."""
    a = np.asarray(a)
    return a[tuple(slice(0, 1) if (st == 0 and n > 1) else slice(None) for st, n in zip(a.strides, a.shape))]


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angle in [-pi, pi) (the deployed controller's wrap)."""
    return law_wrap_angle(np.asarray(a, dtype=float))


def arc_step(q: np.ndarray, v: np.ndarray, w: np.ndarray, h: np.ndarray | float,
             vy: np.ndarray | None = None) -> np.ndarray:
    """Exact pose after moving with constant body velocity (v, vy) and yaw rate w for time h: an arc
    (a line when w = 0).  The body frame turns by w h, so the displacement is the body velocity
    rotated by theta + w h / 2 times h sinc(w h / 2): dx = h sinc(w h / 2) (v cos - vy sin)(theta + w h / 2),
    dy likewise; stable for w -> 0.  ``vy`` None: no lateral velocity (the tracks model)."""
    th = q[..., 2]
    half = w * h / 2.0
    scale = h * _sinc(half)
    chord = v * scale
    mid = th + half
    c, s = np.cos(mid), np.sin(mid)
    out = np.empty(np.broadcast_shapes(q.shape, np.shape(mid) + (3,)))
    out[..., 0] = q[..., 0] + chord * c
    out[..., 1] = q[..., 1] + chord * s
    if vy is not None:
        side = vy * scale
        out[..., 0] -= side * s
        out[..., 1] += side * c
    out[..., 2] = th + w * h
    return out


def _sinc(x: np.ndarray) -> np.ndarray:
    """sin(x) / x, 1 at 0 (numpy's sinc without its factor pi and its copies)."""
    x = np.asarray(x, dtype=float)
    small = np.abs(x) < 1e-4
    # below 1e-4 the series 1 - x^2/6 is exact to rounding (the next term, x^4/120, is below 1e-18); each formula
    # evaluated only where it holds (the adversary's arrays are all small on a straight course, all large on an arc)
    if small.all():
        return np.asarray(1.0 - x * x / 6.0)
    out = np.sin(x, out=np.empty_like(x))
    np.divide(out, x, out=out, where=~small)
    if small.any():
        out[small] = 1.0 - x[small] * x[small] / 6.0
    return out


def saturate(u_hat: np.ndarray, J: np.ndarray, J_inv: np.ndarray, rho_max: float | None) -> np.ndarray:
    """The command the actuator can apply: motor speeds rho = J^-1 u_hat clipped to +-rho_max,
    mapped back, u = J rho (identity when rho_max is None)."""
    if rho_max is None:
        return u_hat
    rho = np.clip(u_hat @ J_inv.T, -rho_max, rho_max)
    return rho @ J.T


def period(q: np.ndarray, U: np.ndarray, S: np.ndarray, M: np.ndarray, Ts: float, J: np.ndarray,
           J_inv: np.ndarray, rho_sat: float | None, switch: tuple | list | None = None) -> np.ndarray:
    """Move the robot through one sampling period: ``U[..., j]`` = u_hat_{k-j} acts on
    [s~_j, s~_{j-1}) (s~_{d_hi} = 0, s~_{-1} = Ts), the robot receives M u_hat (exact arcs): M
    (..., 2, 2) gives (v, omega); a twist matrix (..., 3, 2) gives (v, v_y, omega) (the icr model).
    ``switch = (t, M_after)``: from time t within the period on the robot receives M_after u_hat; a
    list of such pairs, in time order (t non-decreasing), changes it at each."""
    d_hi = S.shape[-1]
    changes = [] if switch is None else [switch] if isinstance(switch, tuple) else list(switch)
    start = np.zeros(q.shape[:-1])
    Uc = _compact(U)  # the saturation on the distinct commands only (the same numbers)
    for j in range(d_hi, -1, -1):
        end = S[..., j - 1] if j > 0 else np.full(q.shape[:-1], Ts)
        u = saturate(Uc[..., j, :], J, J_inv, rho_sat)
        # the slip's pieces within this command's interval: M until the first change, ..., the last after
        mats = [M] + [Mc for _, Mc in changes]
        pieces = [(mats[i], np.clip(changes[i][0], start, end)) for i in range(len(changes))] + [(mats[-1], end)]
        for Mp, stop in pieces:
            # on the distinct maps and commands only (a search's candidates broadcast a few of each): the same
            # numbers, broadcast to the runs by the arc below
            Mc = _compact(Mp)
            u_eff = Mc[..., 0] * u[..., None, 0] + Mc[..., 1] * u[..., None, 1]
            if u_eff.shape[-1] == 3:
                q = arc_step(q, u_eff[..., 0], u_eff[..., 2], stop - start, u_eff[..., 1])
            else:
                q = arc_step(q, u_eff[..., 0], u_eff[..., 1], stop - start)
            start = stop
    return q


@dataclass(frozen=True)
class KinematicRobot:
    """N tracked robots of one model behind the network (exact arcs, saturating motors, slip).

    The state of a run is its pose ``q`` (..., 3) and the network's command memory ``U``
    (..., d_hi + 1, 2), ``U[..., j]`` = u_hat_{k-j} once u_hat_k was sent."""

    Ts: float
    d_hi: int
    speed: float  # V^D: the commanded forward speed before any correction
    track_distance: float
    J: np.ndarray
    J_inv: np.ndarray
    rho_max: float | None  # motor saturation (None: ideal motors)

    @classmethod
    def of(cls, model) -> "KinematicRobot":
        """The robot of a :class:`~robustsynth.model.Model` (saturating when
        ``verification.motor_saturation``)."""
        cfg = model.config
        return cls(model.Ts, model.d_hi, model.V, cfg.robot.track_distance, np.asarray(model.J),
                   np.asarray(model.J_inv), cfg.robot.max_motor_speed if cfg.verification.motor_saturation else None)

    def memory(self, du0: np.ndarray | None, runs: int) -> np.ndarray:
        """The commands in flight before t_0: V^D + du0 (``du0`` (N, d_hi, 2) the stored
        corrections du_{-1}, ..., du_{-d_hi}; None: none); the oldest slot, shifted out before
        it could act, repeats du_{-d_hi}."""
        uD = np.array([self.speed, 0.0])
        U = np.tile(uD, (runs, self.d_hi + 1, 1))  # before step k: U[:, j] = u_hat_{k-1-j}
        if du0 is not None:
            U[:, : self.d_hi] = uD + du0
            U[:, self.d_hi] = uD + du0[:, -1]
        return U

    def send(self, U: np.ndarray, u_hat: np.ndarray) -> np.ndarray:
        """The memory after the command ``u_hat`` (..., 2) of t_k was sent (a new array)."""
        out = np.empty_like(U)
        out[..., 1:, :] = U[..., :-1, :]
        out[..., 0, :] = u_hat
        return out

    def period(self, q: np.ndarray, U: np.ndarray, S: np.ndarray, mu: np.ndarray,
               switch: tuple | list | None = None) -> np.ndarray:
        """The poses at t_{k+1} from ``q`` at t_k: the commands ``U`` act on the intervals of the
        switching instants ``S`` (..., d_hi), under slip ``mu`` (..., 2) = (mu_r, mu_l); with
        ``switch = (t, mu_after)`` the slip jumps to mu_after at time t (...) within the period (a list of
        such pairs, in time order: at each)."""
        return period(q, U, S, self._map(mu), self.Ts, self.J, self.J_inv, self.rho_max, self._changes(switch))

    def partial(self, q: np.ndarray, U: np.ndarray, S: np.ndarray, mu: np.ndarray, t: float,
                switch: tuple | list | None = None) -> np.ndarray:
        """The poses at t_k + t (0 < t <= Ts) from ``q`` at t_k: :meth:`period` cut at t (the commands and
        slip changes after t have not acted yet)."""
        return period(q, U, np.minimum(S, t), self._map(mu), float(t), self.J, self.J_inv, self.rho_max,
                      self._changes(switch))

    def _changes(self, switch: tuple | list | None) -> list | None:
        """The slip changes ``(t, mu_after)`` (one pair or a list in time order) as :func:`period` takes them,
        with the slip's maps."""
        if switch is None:
            return None
        pairs = [switch] if isinstance(switch, tuple) else switch
        return [(np.asarray(t, dtype=float), self._map(after)) for t, after in pairs]

    def _map(self, mu: np.ndarray) -> np.ndarray:
        """J H J^-1 (..., 2, 2) for the tracks model's (mu_r, mu_l); the twist matrix (..., 3, 2) for the
        icr model's (mu_r, mu_l, yaw, x_icr)."""
        mu = np.asarray(mu, dtype=float)
        c = _compact(mu)  # the maps of the distinct slips only, broadcast back
        M = twist_matrix(c, self.track_distance) if mu.shape[-1] > 2 else JHJinv(c[..., 0], c[..., 1], self.track_distance)
        return np.broadcast_to(M, mu.shape[:-1] + M.shape[-2:])
