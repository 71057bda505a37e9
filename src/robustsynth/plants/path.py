"""The path a robot follows and the frames its error is measured in.

A polyline of waypoints driven at the reference speed V^D: segment i is the frame L_i (origin,
heading) of eqs. 13, 16, 17.  The numbers are the deployed controller's
(:class:`~robustsynth.law.PathTable`), on numpy arrays of N robots."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..law import PathTable, reference_at, segment_at, wrap_angle, yaw_rate
from ..law import frame_error as law_frame_error

__all__ = ["PathGeometry", "make_path", "path_from_yaw_rates", "path_of", "frame_error", "pose_from_error",
           "arc_frame_error"]


@dataclass(frozen=True)
class PathGeometry:
    """Polyline path followed at speed V^D; segment i is the frame L_i (origin, heading).  The
    numbers are those of the deployed controller's :class:`~robustsynth.law.PathTable`."""

    waypoints: np.ndarray  # (n+1, 2)
    headings: np.ndarray  # (n,)
    lengths: np.ndarray  # (n,)
    t_start: np.ndarray  # (n,) time the desired point leaves waypoint i
    duration: float
    speed: float
    table: PathTable = field(repr=False, compare=False)

    def segment(self, t: float) -> int:
        return segment_at(self.table.t_start, t)

    @property
    def turning(self) -> bool:
        """The corners are rounded by arcs (a turn radius): the reference of the law's table."""
        return bool(self.table.turning)

    def feedforward(self, t: float) -> float:
        """The reference's yaw rate w_k on the period of t (0 without a turn radius)."""
        return yaw_rate(self.table, t)

    def desired_pose(self, t: float) -> np.ndarray:
        if self.table.turning:  # the reference at t, advanced along its period's arc
            return np.array(reference_at(self.table, t))
        i = self.segment(t)
        s = self.speed * (t - self.t_start[i])
        c, sn = self.table.cos[i], self.table.sin[i]
        return np.array([self.waypoints[i, 0] + s * c, self.waypoints[i, 1] + s * sn, self.headings[i]])


def make_path(waypoints, speed: float, turn_radius: float | None = None, sampling_time: float | None = None,
              turn_ramp: float | None = None) -> PathGeometry:
    """The path of ``waypoints`` at ``speed``; with ``turn_radius`` its corners rounded by arcs (eased in and out
    over ``turn_ramp`` seconds) and the reference sampled every ``sampling_time`` (:class:`~robustsynth.law.PathTable`)."""
    return _geometry(PathTable(np.asarray(waypoints, dtype=float).tolist(), speed, turn_radius, sampling_time, turn_ramp))


def path_from_yaw_rates(yaw_rates, speed: float, sampling_time: float) -> PathGeometry:
    """The turning reference that leaves the origin along the x axis at ``speed`` with the yaw rate
    ``yaw_rates[k]`` on period k, then goes on straight (:meth:`~robustsynth.law.PathTable.from_yaw_rates`)."""
    return _geometry(PathTable.from_yaw_rates((0.0, 0.0), 0.0, speed, sampling_time, np.asarray(yaw_rates, dtype=float).tolist()))


def _geometry(tab: PathTable) -> PathGeometry:
    return PathGeometry(np.array(tab.waypoints), np.array(tab.heading), np.array(tab.length), np.array(tab.t_start),
                        tab.duration, tab.speed, tab)


def path_of(config) -> PathGeometry:
    """The verification path of a config: ``reference.path`` at ``reference.speed``, with its corners
    rounded by ``reference.turn_radius`` when set."""
    return make_path(config.reference.path, config.reference.speed, config.reference.turn_radius,
                     config.network.sampling_time, config.reference.turn_ramp)


def frame_error(path: PathGeometry, seg: int, q: np.ndarray, t: float) -> np.ndarray:
    """e = R(theta_0)(q - q_0) - [V^D (t - t_seg), 0, 0] in frame L of segment ``seg`` (eqs. 13, 16,
    17): the deployed controller's :func:`~robustsynth.law.frame_error` on arrays."""
    q = np.asarray(q, dtype=float)
    return np.stack(law_frame_error(path.table, seg, t, q[..., 0], q[..., 1], q[..., 2]), axis=-1)


def pose_from_error(path: PathGeometry, e: np.ndarray) -> np.ndarray:
    """World pose at t = 0 whose error in the first segment's frame is ``e`` (..., 3)."""
    e = np.asarray(e, dtype=float)
    th0 = path.headings[0]
    c, s = math.cos(th0), math.sin(th0)
    q = np.empty_like(e)
    q[..., 0] = path.waypoints[0, 0] + c * e[..., 0] - s * e[..., 1]
    q[..., 1] = path.waypoints[0, 1] + s * e[..., 0] + c * e[..., 1]
    q[..., 2] = th0 + e[..., 2]
    return q


def arc_frame_error(q: np.ndarray, w: np.ndarray, t: float, V: float) -> np.ndarray:
    """The error (..., 3) of poses ``q`` given in the frame of the reference at t_k (origin, heading 0), at t_k + t
    in the frame of the reference then: it moved at ``V`` along an arc turning at ``w`` (...; 0: a straight
    line), along the arc's chord at half the turn (:func:`~robustsynth.law.advance`).  At t = Ts this is the
    error the law measures at t_{k+1}."""
    psi = np.asarray(w, dtype=float) * t
    chord = V * t * np.sinc(psi / (2.0 * np.pi))  # np.sinc(x) = sin(pi x) / (pi x)
    dx, dy = q[..., 0] - chord * np.cos(psi / 2.0), q[..., 1] - chord * np.sin(psi / 2.0)
    c, sn = np.cos(psi), np.sin(psi)
    return np.stack([c * dx + sn * dy, -sn * dx + c * dy, wrap_angle(q[..., 2] - psi)], axis=-1)
