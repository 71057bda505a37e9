"""The control law as it runs on the robot, in plain Python: no numpy, no imports beyond ``math``
and ``bisect``.

This one file is the controller everywhere:

* :class:`robustsynth.runtime.Controller` drives one robot with it (floats);
* the simulator that verifies a gain (:mod:`robustsynth.robot_verification.simulate`) runs the same
  :class:`Law` with numpy arrays of N robots in place of the floats: every operation below is
  arithmetic that works on both, in the same order, so the simulated commands are the deployed
  ones bit for bit;
* ``robustsynth export --to python`` copies this file verbatim and appends the controller
  description (gain, path, limits) as ``DESCRIPTION``.

At each sampling instant t_k = k Ts the controller

1. picks the path segment whose desired point is active at t_k (the segment i with the largest
   ``t_start[i] <= t_k + SEGMENT_EPS``; after the last waypoint the last segment goes on);
2. measures the error in that segment's frame L_i (eqs. 13, 16, 17 of the seed paper):
   ``e_x = c dx + s dy - V^D (t - t_start[i])``, ``e_y = -s dx + c dy``,
   ``e_theta = wrap(theta - heading[i])`` with ``(dx, dy)`` the position relative to waypoint i and
   ``(c, s)`` the cosine and sine of the segment's heading;
3. forms the lifted state ``xi_k = [e_x, e_y, e_theta, du_{k-1}, ..., du_{k-d_hi}, z_x, z_y]``
   (the commands it sent itself, newest first, each ``(dV, omega)``; the integrators only with
   integral action) and the correction ``du_k = K xi_k``;
4. updates the integrators ``z_{k+1} = z_k + Ts (e_x, e_y)`` and the command memory;
5. sends ``u_hat_k = (V^D + dV_k, omega_k)``.

With a turn radius r (``reference.turn_radius``) the reference does not jump at the waypoints: each
corner is rounded by an arc of radius r tangent to both segments, and the reference is the unicycle
that moves at V^D with the yaw rate ``w_k`` constant on each sampling period, the path's heading
change over the period divided by Ts (so |w_k| <= V^D / r).  Its poses at the sampling instants are
a table (:class:`PathTable`); step 2 measures in the frame of the reference at t (advanced from
t_k along its arc), and step 5 sends ``(V^D + dV_k + g_V w_k, omega_k + g_omega w_k)``: the turning
feedforward, ``g = (g_V, g_omega)`` per rad/s of the reference's yaw rate (``turn_feedforward``: (0, 1), or
for the icr slip model the command that makes the slip box's centre turn at w_k).
"""

import math
from bisect import bisect_right

__all__ = ["PathTable", "Law", "Controller", "Compensator", "compensate", "segment_at", "turn_shape", "tangent_length", "frame_error", "wrap_angle",
           "SEGMENT_EPS", "sample_at", "advance", "reference_at", "yaw_rate"]

SEGMENT_EPS = 1e-12  # [s] an instant within this of a waypoint time belongs to the new segment
SAMPLE_EPS = 1e-9  # [periods] an instant within this of a sampling instant belongs to its period
_PI = math.pi
_TWO_PI = 2.0 * math.pi


def wrap_angle(a):
    """Angle in [-pi, pi) (floor modulo: the same for floats and numpy arrays)."""
    return (a + _PI) % _TWO_PI - _PI


class PathTable:
    """A polyline followed at constant speed: per segment its origin, heading (and its cosine and
    sine), length and the time the desired point leaves the origin."""

    def __init__(self, waypoints, speed, turn_radius=None, sampling_time=None, turn_ramp=None):
        pts = [(float(p[0]), float(p[1])) for p in waypoints]
        if len(pts) < 2:
            raise ValueError("a path needs at least two waypoints")
        self.speed = float(speed)
        if not self.speed > 0.0:
            raise ValueError("the reference speed must be positive")
        self.waypoints = pts
        self.x0, self.y0, self.heading, self.cos, self.sin, self.length, self.t_start = [], [], [], [], [], [], []
        travelled = 0.0
        for (xa, ya), (xb, yb) in zip(pts[:-1], pts[1:]):
            h = math.atan2(yb - ya, xb - xa)
            self.x0.append(xa)
            self.y0.append(ya)
            self.heading.append(h)
            self.cos.append(math.cos(h))
            self.sin.append(math.sin(h))
            self.length.append(math.hypot(xb - xa, yb - ya))
            self.t_start.append(travelled / self.speed)
            travelled += self.length[-1]
        self.duration = travelled / self.speed
        self.turn_radius = None
        self.turn_ramp = None
        self.turning = False
        if turn_radius is not None:
            self._round_corners(float(turn_radius), float(sampling_time), turn_ramp)

    def _round_corners(self, r, Ts, ramp=None):
        """The reference of a turn radius r (module docstring): per sampling instant k its pose
        (ref_x, ref_y, ref_heading, with cosine and sine) and the yaw rate ref_w[k] on [t_k, t_k+1).
        ``ramp`` [s] > 0: each turn eases in and out (a clothoid easement): its curvature ramps from 0 to 1/r
        over ``ramp`` seconds of travel, holds, and ramps back, so the yaw rate changes by at most
        (V^D / r) Ts / ramp from one period to the next; the turn starts where its curve, symmetric about the
        corner's bisector, ends on the next segment.  Raises ValueError (naming the waypoint) when a corner's
        turn does not fit its segments, a corner turns back (|turn| >= 3 rad), or two turns lie so close that
        the yaw rate would step by more than that between periods."""
        if not (r > 0.0 and Ts > 0.0):
            raise ValueError("the turn radius and the sampling time must be positive")
        ramp = float(ramp or 0.0)
        if not ramp >= 0.0:
            raise ValueError("the turn ramp must be >= 0")
        V = self.speed
        L_e = V * ramp  # the easement's length [m]
        n = len(self.heading)
        turns = [0.0] + [wrap_angle(self.heading[i] - self.heading[i - 1]) for i in range(1, n)]
        tangent = [0.0] * (n + 1)  # at waypoint i: the turn's tangent length
        shapes = [None] * (n + 1)  # at waypoint i: (peak curvature, easement length, length of the whole turn)
        for i in range(1, n):
            if abs(turns[i]) >= 3.0:
                raise ValueError("waypoint %d turns by %.3g rad: an arc cannot round a corner that turns back" % (i, turns[i]))
            shapes[i] = turn_shape(abs(turns[i]), r, L_e)
            tangent[i] = tangent_length(abs(turns[i]), *shapes[i])
        for i in range(n):
            need = tangent[i] + tangent[i + 1]
            if need > self.length[i] * (1.0 + 1e-12):
                raise ValueError("segment %d-%d is %.4g m long, and the turns of radius %g m at its ends need %.4g m of it: "
                                 "lower reference.turn_radius%s or move the waypoints apart"
                                 % (i, i + 1, self.length[i], r, need, " or reference.turn_ramp" if ramp else ""))
        # the heading along the rounded path: pieces (start, end, heading at the start and at the end, turn sign,
        # shape), the straight ones with no shape
        pieces, s, h = [], 0.0, self.heading[0]
        corner_at = []  # (arc length where the turn starts, waypoint)
        self.arcs = []  # per waypoint 1..n-1: (its turn [rad], the time its turn starts [s])
        for i in range(n):
            end = s + self.length[i] - tangent[i] - tangent[i + 1]
            pieces.append((s, end, h, h, 0.0, None))
            s = end
            if i + 1 < n:
                self.arcs.append((turns[i + 1], s / V))
            if i + 1 < n and turns[i + 1] != 0.0:
                corner_at.append((s, i + 1))
                shape = shapes[i + 1]
                pieces.append((s, s + shape[2], h, h + turns[i + 1], math.copysign(1.0, turns[i + 1]), shape))
                s += shape[2]
                h += turns[i + 1]
        total = s
        starts = [p[0] for p in pieces]
        steps = int(math.ceil(total / (V * Ts) - 1e-9))

        def heading_at(sv):
            if sv >= total:
                return h
            j = max(bisect_right(starts, sv) - 1, 0)
            s0, s1, h0, h1, sign, shape = pieces[j]
            if shape is None or s1 <= s0:
                return h0
            if shape[1] <= 0.0:  # an arc: the heading linear in the arc length
                return h0 + (h1 - h0) * (sv - s0) / (s1 - s0)
            return h0 + sign * _turned(sv - s0, *shape)

        wbar = V / r  # |w_k| <= wbar, also after rounding
        step = wbar * min(1.0, Ts / ramp) if ramp > 0.0 else wbar  # the largest change of w_k between periods
        ws = [min(max((heading_at(V * Ts * (k + 1)) - heading_at(V * Ts * k)) / Ts, -wbar), wbar) for k in range(steps)]
        for k in range(1, steps):
            if abs(ws[k] - ws[k - 1]) > step * (1.0 + 1e-9):
                near = min(corner_at, key=lambda c: abs(c[0] - V * Ts * k))[1] if corner_at else 0
                raise ValueError("near waypoint %d: two turns lie so close that the yaw rate steps by %.3g rad/s between "
                                 "periods, more than %.3g (V^D / r%s): move the waypoints apart or lower "
                                 "reference.turn_radius" % (near, abs(ws[k] - ws[k - 1]), step,
                                                             " Ts / turn_ramp" if ramp else ""))
        self._set_reference(ws, Ts, wbar, total)
        self.turn_radius = r
        self.turn_ramp = ramp if ramp > 0.0 else None
        self.max_yaw_step = step

    def _set_reference(self, ws, Ts, wbar, length):
        """The turning reference from the first waypoint on: the unicycle at V^D with the yaw rate
        ws[k] on period k (straight after the last), its pose table, and one frame for the whole path
        (no waypoint switches)."""
        x, y, th = self.waypoints[0][0], self.waypoints[0][1], self.heading[0]
        self.ref_x, self.ref_y, self.ref_heading, self.ref_w = [x], [y], [th], []
        for w in ws:
            x, y, th = advance(x, y, th, w, Ts, self.speed)
            self.ref_x.append(x)
            self.ref_y.append(y)
            self.ref_heading.append(th)
            self.ref_w.append(w)
        self.ref_w.append(0.0)  # after the path's end the reference goes on straight
        self.ref_cos = [math.cos(a) for a in self.ref_heading]
        self.ref_sin = [math.sin(a) for a in self.ref_heading]
        self.turning, self.sampling_time, self.max_yaw_rate = True, Ts, wbar
        self.duration = length / self.speed
        self.x0, self.y0, self.heading = self.x0[:1], self.y0[:1], self.heading[:1]
        self.cos, self.sin, self.length, self.t_start = self.cos[:1], self.sin[:1], [length], [0.0]

    @classmethod
    def from_yaw_rates(cls, start, heading, speed, sampling_time, yaw_rates):
        """The turning reference that leaves ``start`` (x, y) along ``heading`` at ``speed`` with the yaw
        rate ``yaw_rates[k]`` on period k (then straight on): a reference given by its yaw rates rather
        than by waypoints and a turn radius."""
        if sampling_time is None or not sampling_time > 0.0:
            raise ValueError("the sampling time must be positive")
        ws = [float(w) for w in yaw_rates]
        x, y = float(start[0]), float(start[1])
        total = float(speed) * float(sampling_time) * max(len(ws), 1)
        tab = cls([(x, y), (x + total * math.cos(heading), y + total * math.sin(heading))], speed)
        tab.heading[0], tab.cos[0], tab.sin[0] = float(heading), math.cos(heading), math.sin(heading)
        tab._set_reference(ws, float(sampling_time), max([abs(w) for w in ws] + [0.0]), total)
        tab.arcs = []
        return tab


def turn_shape(turn, r, L_e):
    """(peak curvature, easement length, length) of a turn by ``turn`` > 0 rad: its curvature ramps linearly from
    0 to the peak over L_e, holds, ramps back; the peak is 1/r, or less where the turn is too small to reach it
    (turn < L_e / r: two ramps only).  L_e = 0: an arc of radius r."""
    if L_e <= 0.0:
        return 1.0 / r, 0.0, turn * r
    if turn >= L_e / r:
        return 1.0 / r, L_e, turn * r + L_e
    return turn / L_e, L_e, 2.0 * L_e


def _turned(sigma, k, L_e, length):
    """How far a turn of shape (k, L_e, length) has turned after ``sigma`` of its length [rad]."""
    sigma = min(max(sigma, 0.0), length)
    if L_e <= 0.0:
        return k * sigma
    if sigma <= L_e:
        return k * sigma * sigma / (2.0 * L_e)
    if sigma <= length - L_e:
        return k * L_e / 2.0 + k * (sigma - L_e)
    rest = length - sigma
    return k * (length - L_e) - k * rest * rest / (2.0 * L_e)


def tangent_length(turn, k, L_e, length):
    """The distance from a turn's start to the corner it rounds: its curve, symmetric about the corner's bisector,
    moves (dx, dy) in the frame of the segment before it, and ends on the segment after it when the tangent length
    is dy / sin(turn) (Simpson's rule on the heading, which is smooth; an arc: r tan(turn / 2) exactly)."""
    if L_e <= 0.0:
        return (1.0 / k) * math.tan(turn / 2.0)
    n = 2000  # even; the heading's second derivative is bounded: the error is O(length (k length / n)^4)
    hstep = length / n
    acc = 0.0
    for i in range(n + 1):
        w = 1.0 if i in (0, n) else (4.0 if i % 2 else 2.0)
        acc += w * math.sin(_turned(i * hstep, k, L_e, length))
    return acc * hstep / 3.0 / math.sin(turn)


def _sinc(a):
    """sin(a) / a, 1 at 0."""
    return math.sin(a) / a if a != 0.0 else 1.0


def advance(x, y, heading, w, tau, speed):
    """The unicycle at ``speed`` and yaw rate ``w`` from (x, y, heading) after ``tau``: it moves along
    the chord of its arc, at half the turn."""
    phi = w * tau
    chord = speed * tau * _sinc(phi / 2.0)
    return x + chord * math.cos(heading + phi / 2.0), y + chord * math.sin(heading + phi / 2.0), heading + phi


def reference_at(path, t):
    """(x, y, heading) of a turning path's reference at t: the table's pose k, advanced along period
    k's arc."""
    k = sample_at(path, t)
    tau = t - k * path.sampling_time
    if tau == 0.0:
        return path.ref_x[k], path.ref_y[k], path.ref_heading[k]
    return advance(path.ref_x[k], path.ref_y[k], path.ref_heading[k], path.ref_w[k], tau, path.speed)


def yaw_rate(path, t):
    """The reference's yaw rate w_k on the period of t (0 on a polyline without a turn radius)."""
    return path.ref_w[sample_at(path, t)] if path.turning else 0.0


def sample_at(path, t):
    """Index k of the sampling period [t_k, t_k+1) that holds t, within the turning reference's table
    (the last entry goes on straight)."""
    k = int(math.floor(t / path.sampling_time + SAMPLE_EPS))
    return min(max(k, 0), len(path.ref_w) - 1)


def segment_at(t_start, t):
    """Index of the segment active at time ``t`` (see the module docstring, step 1)."""
    i = bisect_right(t_start, t + SEGMENT_EPS) - 1
    return min(max(i, 0), len(t_start) - 1)


def frame_error(path, seg, t, x, y, theta):
    """(e_x, e_y, e_theta) of the pose (x, y, theta) at time t in the frame of segment ``seg`` (with a
    turn radius: of the reference at t, ``seg`` unused)."""
    if path.turning:
        xr, yr, th = reference_at(path, t)
        c, s = math.cos(th), math.sin(th)  # at a sampling instant: the table's ref_cos, ref_sin (the C export's)
        dx = x - xr
        dy = y - yr
        return c * dx + s * dy, -s * dx + c * dy, wrap_angle(theta - th)
    c, s = path.cos[seg], path.sin[seg]
    dx = x - path.x0[seg]
    dy = y - path.y0[seg]
    return (c * dx + s * dy - path.speed * (t - path.t_start[seg]), -s * dx + c * dy,
            wrap_angle(theta - path.heading[seg]))


def compensate(v_hat, omega_hat, mu_r, mu_l, half_D):
    """The command whose tracks turn at the law's track speeds divided by the tractions ``mu_r``, ``mu_l`` it expects
    (the slip-compensated law, docs/theory.md §18): a track with traction mu then moves at mu / mu_hat times the
    law's speed.  ``half_D`` is half the track distance.  Floats or numpy arrays (the same operations in order)."""
    vr = (v_hat + omega_hat * half_D) / mu_r
    vl = (v_hat - omega_hat * half_D) / mu_l
    return (vr + vl) * 0.5, (vr - vl) / (half_D + half_D)


class Compensator:
    """The slip-compensated law's own part (docs/theory.md §18), beside a monitor of the same description: each
    period, after the monitor's check at t_k, :meth:`update` takes its slip estimate
    (``robustsynth.monitor.Monitor.slip_estimate``) and :meth:`command` divides the law's command's track speeds by
    the estimated tractions (the estimate's centres, inside the box; the box's centre before the first estimate,
    the last consistent one's after an inconsistent period).

    ``holds``: the condition the certificate assumes is sure to hold for the command about to be sent (given the
    estimate's own assumptions): the estimate consistent and, for each track, its half-width plus ``lag`` (what
    slip.max_rate lets the traction move while the command acts) at most ``error``.  ``covered``: it held for this
    command and the d_hi before it, every command that can act until the next sampling instant.  ``margin``: error
    less the worse track's half-width + lag (None without an estimate)."""

    def __init__(self, description):
        c = description.get("compensation")
        if not c:
            raise ValueError("this controller description has no slip compensation")
        self.error, self.lag = float(c["error"]), float(c["lag"])
        self.half_D = float(description["track_distance"]) / 2.0
        self.d_hi = int(description["d_hi"])  # a command acts within this many periods after its own
        (r_lo, r_hi), (l_lo, l_hi) = c["box"][0], c["box"][1]
        self.centre = ((float(r_lo) + float(r_hi)) / 2.0, (float(l_lo) + float(l_hi)) / 2.0)
        self.reset()

    def reset(self):
        """The box's centre as the estimate, the condition not (yet) known to hold."""
        self.mu = self.centre
        self.holds = False
        self.margin = None
        self.wait = self.d_hi + 1
        self.estimate = None  # the monitor's last slip estimate taken (:meth:`take`)

    def update(self, estimate):
        """Take the monitor's slip estimate of this period; returns :attr:`covered`: whether the condition held for
        every command that can act until the next sampling instant (this one and the d_hi before it), i.e. whether the
        certificate's claims apply to the next state.  :attr:`holds`: the condition for this period's command."""
        if estimate is None or not estimate["consistent"] or not estimate["windows"]:
            self.holds, self.margin = False, None
        else:
            centre, half = estimate["estimate"], estimate["bound"]
            self.mu = (centre["mu_r"], centre["mu_l"])
            self.margin = self.error - (max(half["mu_r"], half["mu_l"]) + self.lag)
            self.holds = self.margin >= 0.0
        # periods until every command that can act was compensated under the condition
        self.wait = max(self.wait - 1, 0) if self.holds else self.d_hi + 1
        return self.covered

    @property
    def covered(self):
        """The condition held for this period's command and the d_hi before it (the certificate's claims apply to the
        state at the next sampling instant, when they applied to this one)."""
        return self.wait == 0

    def take(self, monitor):
        """This period's slip estimate taken from ``monitor`` (after its check at t_k; :meth:`update`), and where the
        condition does not cover the next state the monitor's set checks suspended (``Monitor.suspend``: the theorem
        claims nothing of that state).  Returns the estimate (also kept as :attr:`estimate`)."""
        self.estimate = monitor.slip_estimate()
        if not self.update(self.estimate):
            monitor.suspend()
        return self.estimate

    def command(self, command):
        """The compensated command (V_hat, omega_hat) for the law's ``command``."""
        return compensate(command[0], command[1], self.mu[0], self.mu[1], self.half_D)

    def step(self, controller, monitor, t, x, y, theta, seq, reports=()):
        """One period of the compensated law for one robot, with its :class:`Controller` and its monitor
        (``robustsynth.monitor.Monitor`` of the same description): the law's command for the pose measured at
        t_k, the monitor's check of it (its MOTOR check is the certificate's limit on this uncompensated command),
        the slip estimate taken (where the condition is not sure to have held for every command that can act until
        the next instant, the monitor's set checks are suspended until the state is seen inside again: the theorem
        claims nothing of the next state), the command compensated (or the fallback's, once engaged) and registered as sent
        with sequence number ``seq``.  Returns (status, command to send); :attr:`holds` says whether the
        certificate's condition is sure to hold for it."""
        command = controller.step(t, x, y, theta)
        status = monitor.check(t, x, y, theta, controller.state, command, reports)
        self.take(monitor)
        out = monitor.fallback_command(self.command(command))
        monitor.sent(seq, t, out)
        return status, out


def _dot(row, xi):
    acc = 0.0
    for a, b in zip(row, xi):
        acc = acc + a * b
    return acc


class Law:
    """``du_k = K xi_k`` with its memory: the last ``d_hi`` corrections and the integrators.

    ``K`` is 2 rows of ``3 + 2 d_hi (+ 2 with integrators)`` numbers. The memory entries are floats
    for one robot or numpy arrays (one value per robot) for a vectorized simulation."""

    def __init__(self, K, Ts, integral, path):
        self.K = [tuple(float(v) for v in row) for row in K]
        self.n_z = 2 if integral else 0
        past = len(self.K[0]) - 3 - self.n_z if len(self.K) == 2 else -1
        if len(self.K) != 2 or past < 2 or past % 2 or len(self.K[1]) != len(self.K[0]):
            raise ValueError("K must have 2 rows of 3 + 2 d_hi" + (" + 2" if integral else "") + " numbers")
        self.d_hi = past // 2
        self.Ts = float(Ts)
        self.path = path
        self.reset()

    def reset(self, past=None, z=None):
        """Forget the past: stored corrections ``[dV_{k-1}, omega_{k-1}, dV_{k-2}, ...]`` and
        integrators set to ``past`` and ``z`` (zero when omitted)."""
        self.past = list(past) if past is not None else [0.0] * (2 * self.d_hi)
        self.z = list(z) if z is not None else [0.0] * self.n_z
        self.xi = None  # the last lifted state used

    def correction(self, t, x, y, theta):
        """du_k = (dV, omega) for the measured pose at t_k; advances the memory by one period."""
        seg = segment_at(self.path.t_start, t)
        ex, ey, eth = frame_error(self.path, seg, t, x, y, theta)
        xi = [ex, ey, eth] + self.past + self.z
        dv = _dot(self.K[0], xi)
        dw = _dot(self.K[1], xi)
        if self.n_z:
            self.z = [self.z[0] + self.Ts * ex, self.z[1] + self.Ts * ey]
        self.past = [dv, dw] + self.past[:-2]
        self.xi = xi
        return dv, dw

    def feedforward(self, t):
        """The reference's yaw rate w_k on the period of t (0 on a polyline without a turn radius)."""
        return yaw_rate(self.path, t)


class Controller:
    """``u_hat_k = [V^D, 0] + w_k g + K xi_k`` for one robot (w_k = 0 without a turn radius; g the turning
    feedforward, ``turn_feedforward``, (0, 1) when the description has none), exactly as verified, from a
    controller description (the mapping ``robustsynth export --to json`` writes).

    Call :meth:`step` once per sampling instant t_k = k Ts with the time since the start of the
    path and the measured pose in the world frame; it returns the command (V_hat, omega_hat) to
    send.  :meth:`motor_speeds` maps a command to the motor speeds (rho_r, rho_l) = J^-1 u_hat.  The
    law was verified with the commanded (not the clipped) corrections in its memory: clip in the
    motor driver, not here."""

    def __init__(self, description):
        d = description
        self.description = d
        self.path = PathTable(d["path"], d["reference_speed"], d.get("turn_radius"), d["sampling_time"], d.get("turn_ramp"))
        self.law = Law(d["K"], d["sampling_time"], d["integral_action"], self.path)
        if self.law.d_hi != d["d_hi"]:
            raise ValueError("d_hi is %d but K has columns for %d past inputs" % (d["d_hi"], self.law.d_hi))
        self.Ts = float(d["sampling_time"])
        self.V = float(d["reference_speed"])
        R, D = float(d["gear_radius"]), float(d["track_distance"])
        self._inv_R, self._half_D_over_R = 1.0 / R, D / (2.0 * R)  # J^-1 = [[1/R, D/2R], [1/R, -D/2R]]
        self.max_motor_speed = d.get("max_motor_speed")
        g = d.get("turn_feedforward") or (0.0, 1.0)
        self.ff_V, self.ff_omega = float(g[0]), float(g[1])

    @property
    def d_hi(self):
        return self.law.d_hi

    def reset(self, past=None, integrators=None):
        """Past commands and integrators to zero (or to ``past`` = [dV_{k-1}, omega_{k-1}, ...,
        newest first] and ``integrators`` = [int_e_x, int_e_y], e.g. a steady state); the path
        restarts at t = 0."""
        self.law.reset(past, integrators)

    def step(self, t, x, y, theta):
        """The command (V_hat, omega_hat) for the pose measured at t_k (once per sampling instant)."""
        dv, dw = self.law.correction(t, x, y, theta)
        w = self.law.feedforward(t)
        return self.V + dv + w * self.ff_V, dw + w * self.ff_omega

    def motor_speeds(self, V_hat, omega_hat):
        """(rho_r, rho_l) = J^-1 (V_hat, omega_hat) [rad/s], not clipped."""
        return (V_hat * self._inv_R + omega_hat * self._half_D_over_R,
                V_hat * self._inv_R - omega_hat * self._half_D_over_R)

    @property
    def state(self):
        """The lifted state xi the last step used (empty before the first step)."""
        return list(self.law.xi or [])

    def __repr__(self):
        return "Controller(name=%r, Ts=%g, d_hi=%d, integral=%s, segments=%d)" % (
            self.description.get("name"), self.Ts, self.d_hi, bool(self.law.n_z), len(self.path.t_start))
