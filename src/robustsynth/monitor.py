"""The runtime monitor: every period, does what the certificate assumed still hold?  Plain Python: no numpy,
no imports beyond ``math`` (like :mod:`robustsynth.law`, it is exported verbatim and mirrored in C).

A certificate is a theorem with assumptions (docs/theory.md §7, §9, §12, §16).  Each sampling instant t_k the
controller hands :meth:`Monitor.step` what it can measure — the pose sample, the lifted state its law used, the
command it is about to send and the network's reports (which commands were applied when, which were lost) — and
the monitor checks:

* ``DELAY``: each applied command's delay ``applied - t_j`` against [tau_min, tau_max] (t_j the sampling instant
  it was computed at, the theory's tau), and in-order delivery;
* ``LOSSES``: the run of lost commands against ``network.dropouts.max_consecutive``; a command without a report
  by ``t_j + tau_max`` counts as lost (a report that comes later is a delay beyond tau_max);
* ``SET``: V(xi_k) against the certified level, with the pose noise's largest effect on V added: above that
  threshold the true state is outside the certified set (a proof, given the noise bound).  Only a departure
  counts: once the state was seen inside (V below the level less the noise's effect) since the start or the
  last waypoint of a path without turns (where the error jumps to the next segment's frame), leaving the set is
  an alarm; before, the robot is on its way in (the set attracts);
* ``HEADING``: |e_theta(t_k)| against the heading bound the kinematic channels assume (plus the noise bound);
* ``MOTOR``: the command's motor speeds against robot.max_motor_speed (exact: the monitor computes them);
* ``SLIP``: over the last ``window`` periods, the pose increments in the body frame (forward, heading, lateral)
  against the ranges the slip box allows for the commands that acted (from the reports' applied times), each
  range widened by the pose noise's effect.  The box's twist components (theory §12: traction sum and
  difference, yaw factor times those, x_icr times those) enter by interval arithmetic, so an increment outside
  its range has no explanation inside the box (an estimate from noisy poses: see ``slip_margin``);
* ``RATE`` (with ``slip.max_rate``): the window's two halves each bound the traction sum s = (mu_r + mu_l) / 2 they
  imply (the forward range over the half's commanded travel, driven forward throughout); two bounds farther apart
  than max_rate x the window's time are no traction that changed at most that fast.

The noise bounds are ``noise_sigmas`` standard deviations of the config's ``verification.noise``.  A status is a
word of these bits (0: every assumption holds as far as the monitor can see) with, per bit, by how much.  After
``persistence`` periods in a row with an alarm the fallback engages and stays engaged until :meth:`reset`:
``stop`` sends (0, 0), ``hold`` the last command sent before the alarms began, ``slow`` the law's command times
``slow_factor``.

Assumed: the reports of commands applied up to t_k reach the monitor before its step at t_k (an acknowledgement
latency below the sampling time; otherwise the delay and slip checks see them a period later); the pose noise
stays within ``noise_sigmas`` standard deviations.
"""

import math

__all__ = ["Monitor", "slip_estimate_bound", "OK", "DELAY", "LOSSES", "SET", "HEADING", "MOTOR", "SLIP", "RATE", "CAUSES", "describe"]

OK = 0
DELAY = 1
LOSSES = 2
SET = 4
HEADING = 8
MOTOR = 16
SLIP = 32
RATE = 64
CAUSES = (("delay", DELAY), ("losses", LOSSES), ("set", SET), ("heading", HEADING), ("motor", MOTOR), ("slip", SLIP),
          ("rate", RATE))


def describe(status):
    """The names of the bits set in ``status``, comma-separated ("ok" for 0)."""
    names = [name for name, bit in CAUSES if status & bit]
    return ", ".join(names) if names else "ok"


def _mon_wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _mon_sinc(a):
    """sin(a) / a: below 0.05 its series to a^4 (the next term, a^6 / 5040, is below 4e-12: far inside the slip
    check's model_tol), else by the sine."""
    return 1.0 - a * a / 6.0 + a * a * a * a / 120.0 if abs(a) < 0.05 else math.sin(a) / a


def _mon_summands(p):
    """What a period adds to the window's running sums: ds, dtheta, dlat, Vc, Wc, |dp|, |dtheta|, |turn of mid|, Va, Wa."""
    return (p[0], p[1], p[2], p[3], p[4], p[5], abs(p[1]), p[8], p[9], p[10])


def _mon_range(mid, rad, c, a):
    """Where the integral of x(t) u(t) lies when x(t) stays in [mid - rad, mid + rad], the integral of u is c and that
    of |u| is a: mid c +- rad a (u may change sign: a command turning one way, then the other)."""
    return mid * c - rad * a, mid * c + rad * a


def _mon_clip(poly, a, b, c):
    """The part of the convex polygon ``poly`` (vertices in order) where ``a x + b y <= c`` (Sutherland-Hodgman,
    one edge): a convex polygon again, empty where none of it is."""
    f = [a * P[0] + b * P[1] - c for P in poly]  # each vertex's side, once
    if all(v <= 0.0 for v in f):
        return poly  # wholly inside: unchanged
    out = []
    for i in range(len(poly)):
        P, Q, fp, fq = poly[i - 1], poly[i], f[i - 1], f[i]
        if (fp <= 0.0) != (fq <= 0.0):  # the edge crosses the line
            t = fp / (fp - fq)
            out.append((P[0] + t * (Q[0] - P[0]), P[1] + t * (Q[1] - P[1])))
        if fq <= 0.0:
            out.append(Q)
    return out


# the estimate's intervals are widened by this much (absolute) for the rounding of the sums and of the clipping: far
# below the allowances they carry (model_tol alone is 2 % of the travel)
_EST_ROUND = 1e-9


def slip_estimate_bound(description):
    """What the slip estimate (:meth:`Monitor.slip_estimate`) is sure to achieve, from the description alone: on a
    straight segment driven at the reference speed with constant commands, each track's traction is estimated
    within ``half[name]`` of its value at the sampling instant (the best window of 1, 2, 4, ... ``window`` periods;
    docs/theory.md §17), and a command it is used for meets a traction within ``at_action[name]`` of the estimate
    (``lag``: what max_rate lets the traction move between t_k and the end of the command's action).  None without
    ``slip.max_rate`` (the traction now may then be anywhere in the box).  ``observable``: False for the traction
    difference of the icr model (its yaw factor, free to jump, hides it), whose bound is then the box's."""
    m = description.get("monitor") or {}
    if m.get("max_rate") is None or m.get("slip_ranges") is None:
        return None
    r, Ts = float(m["max_rate"]), float(description["sampling_time"])
    V, D = float(description["reference_speed"]), float(description["track_distance"])
    a, b, tol = float(m["position_noise"]), float(m["heading_noise"]), float(m["model_tol"])
    (r_lo, r_hi), (l_lo, l_hi) = m["slip_ranges"][0], m["slip_ranges"][1]
    h_s = h_d = math.inf
    W = int(m["window"])
    for n in [k for k in range(1, W + 1) if k & (k - 1) == 0 or k == W]:  # the windows the estimate uses
        T = n * Ts
        MV = V * T * T / 2.0 + Ts * V * T  # the integral of (t_k - t + Ts) V over the window
        h_s = min(h_s, (math.sqrt(2.0) * a * 2.0 + V * T * (b + tol) + r * MV) / (V * T))
        h_d = min(h_d, (2.0 * b + 2.0 * r * MV / D) * D / (V * T))
    tracks = m.get("slip_model", "tracks") == "tracks"
    if not tracks:  # the heading says nothing of the traction difference now: its range is the box's
        h_d = ((r_hi - l_lo) - (r_lo - l_hi)) / 2.0
    half = {"mu_r": min(h_s + h_d / 2.0, (r_hi - r_lo) / 2.0), "mu_l": min(h_s + h_d / 2.0, (l_hi - l_lo) / 2.0)}
    lag = r * (float(m["tau_max"]) + Ts * (int(m["max_lost"]) + 1) + Ts)
    return {"half": half, "lag": lag, "at_action": {k: v + lag for k, v in half.items()},
            "box_half": {"mu_r": (r_hi - r_lo) / 2.0, "mu_l": (l_hi - l_lo) / 2.0}, "observable": tracks,
            "speed": V, "max_rate": r}


class Monitor:
    """The monitor of one controller description's certificate (``description["monitor"]``, written by
    ``robustsynth.artifacts.gains.monitor_description``).  One instance per robot; :meth:`step` once per
    sampling instant, in order."""

    def __init__(self, description):
        m = description.get("monitor")
        if not m:
            raise ValueError("this controller description has no monitor: its gain has no certificate (P and "
                             "ellipsoid_level) to watch")
        self.description = description
        self.Ts = float(description["sampling_time"])
        self.R, self.D = float(description["gear_radius"]), float(description["track_distance"])
        self.inv_R, self.half_D_over_R = 1.0 / self.R, self.D / (2.0 * self.R)  # J^-1 = [[1/R, D/2R], [1/R, -D/2R]]
        self.tau_min, self.tau_max = float(m["tau_min"]), float(m["tau_max"])
        self.clock_tol = float(m["clock_tol"])
        self.max_lost = int(m["max_lost"])
        self.P = [[[float(v) for v in row] for row in P] for P in m["P"]]
        # V(xi) = max over the P's of xi' P xi, as a sum of its nonzero upper-triangle terms (coef, i, j), in order
        self.V_terms = [[(P[i][i] if i == j else P[i][j] + P[j][i], i, j) for i in range(len(P)) for j in range(i, len(P))
                         if (P[i][i] if i == j else P[i][j] + P[j][i]) != 0.0] for P in self.P]
        self.level = float(m["level"])
        self.set_threshold = float(m["set_threshold"])
        self.set_entry = float(m["set_entry"])
        self.heading_limit = None if m.get("heading_limit") is None else float(m["heading_limit"])
        # a path without turns: the error jumps at each waypoint (its segments' start times re-arm the set check)
        self.segment_starts = [float(v) for v in m["segment_starts"]]
        self.rho_limit = m.get("rho_limit")
        # the motors' own limit, beyond which a command that acted did not become motion as commanded (the slip
        # check and estimate leave such periods out); a compensated law's MOTOR check is the certificate's lower
        # limit on the uncompensated command (docs/theory.md §18), its motors still turn up to this
        self.saturation_limit = m.get("saturation_limit", self.rho_limit)
        self.window = int(m["window"])
        self.components = [(float(lo), float(hi)) for lo, hi in m["components"]]  # s, d, ys, yd, xs, xd
        self.comp_mid = [(lo + hi) / 2.0 for lo, hi in self.components]  # their centres and radii
        self.comp_rad = [(hi - lo) / 2.0 for lo, hi in self.components]
        self.pos_noise, self.head_noise = float(m["position_noise"]), float(m["heading_noise"])
        self.model_tol = float(m["model_tol"])
        self.max_rate = None if m.get("max_rate") is None else float(m["max_rate"])  # slip.max_rate [1/s]
        # the slip model and its parameters' ranges (the slip estimate's box; None in descriptions made before)
        self.slip_model = m.get("slip_model", "tracks")
        self.slip_ranges = None if m.get("slip_ranges") is None else [(float(lo), float(hi)) for lo, hi in m["slip_ranges"]]
        self.fallback = m["fallback"]
        self.persistence = int(m["persistence"])
        self.slow_factor = float(m["slow_factor"])
        self.reset()

    def reset(self):
        """Forget everything (a new run): no command in flight, no pose, the fallback disengaged."""
        self.pending = {}  # seq -> (t_k, V_hat, omega_hat) of the commands not yet reported
        self.overdue = {}  # the same, of the commands counted as lost for want of a report by t_k + tau_max
        self.schedule = []  # (applied time, V_hat, omega_hat, beyond rho_max) of the applied commands, in order
        self.last_applied = -math.inf
        self.lost_run = 0
        self.poses = []  # (t, x, y, theta) of the last window + 1 samples
        # per period of the window: (ds, dtheta, dlat, Vc, Wc, |dp|, mid heading, unjudged, |turn of mid|, Va, Wa,
        # the integrals of (t_end - t) |V_hat| and (t_end - t) |omega_hat| over it)
        self.periods = []
        # the window's running sums of ds, dtheta, dlat, Vc, Wc, |dp|, |dtheta|, |turn of mid|, Va, Wa: each period adds
        # its own and takes off the oldest's; every window periods they are summed afresh (the rounding of window sums)
        self.sums = [0.0] * 10
        self.since = 0
        self.alarm_run = 0
        self.engaged = False
        self.inside = False  # the state was seen inside the set (since the start or the last waypoint)
        self.segment = 0
        self.held = None  # the last command sent before the alarms began
        self.last_sent = None
        self.amounts = {}

    # ------------------------------------------------------------------------------------------ the checks
    def _reports(self, t, reports, amounts):
        status = 0
        for seq, applied in reports:
            late = seq in self.overdue
            if not late and seq not in self.pending:
                continue  # reported twice, or a command this monitor never saw
            tk, v, w = self.overdue.pop(seq) if late else self.pending.pop(seq)
            if applied is None or applied != applied:  # lost (None or NaN)
                if not late:  # (an overdue one was counted already)
                    self.lost_run += 1
                continue
            tau = applied - tk
            excess = max(self.tau_min - self.clock_tol - tau, tau - self.tau_max - self.clock_tol)
            if applied < self.last_applied - self.clock_tol:  # overtook a newer command
                excess = max(excess, self.last_applied - applied)
            if excess > 0.0:
                status |= DELAY
                amounts["delay"] = max(amounts.get("delay", 0.0), excess)
            self.last_applied = max(self.last_applied, applied)
            self.schedule.append((applied, v, w, self.saturation_limit is not None
                                  and self._rho(v, w) > self.saturation_limit))
            self.schedule.sort(key=lambda e: e[0])
            if not late:
                self.lost_run = 0
        for seq in sorted(self.pending):  # no report by t_j + tau_max: lost, as far as the certificate goes
            tk, v, w = self.pending[seq]
            if t - tk > self.tau_max + self.clock_tol:
                self.overdue[seq] = self.pending.pop(seq)
                self.lost_run += 1
        for seq in [s for s in self.overdue if t - self.overdue[s][0] > self.tau_max + self.Ts * (self.max_lost + 2)]:
            del self.overdue[seq]  # long gone: a report now would be a delay far beyond any bound anyway
        if self.lost_run > self.max_lost:
            status |= LOSSES
            amounts["losses"] = float(self.lost_run - self.max_lost)
        return status

    def _V(self, xi):
        best = 0.0
        for terms in self.V_terms:
            acc = 0.0
            for c, i, j in terms:
                acc = acc + c * xi[i] * xi[j]
            best = max(best, acc)
        return best

    def _rho(self, v, w):
        """The larger motor speed of the command (V_hat, omega_hat): |J^-1 u| (rad/s)."""
        return max(abs(v * self.inv_R + w * self.half_D_over_R), abs(v * self.inv_R - w * self.half_D_over_R))

    def _commanded(self, t0, t1):
        """The integrals of the commanded V_hat, omega_hat, |V_hat| and |omega_hat| over [t0, t1] by the applied
        schedule, and whether the period cannot be judged: a command beyond the motor limit acted in it (the motors then
        give less than commanded: not slip), or no command is known to act from its start (the first periods of a run)."""
        Vc = Wc = Va = Wa = mV = mW = 0.0
        sched = self.schedule
        clipped = not sched or sched[0][0] > t0  # no command known to act from the period's start: not judged
        for i, (start, v, w, beyond) in enumerate(sched):
            end = sched[i + 1][0] if i + 1 < len(sched) else math.inf
            a, b = max(start, t0), min(end, t1)
            if b > a:
                Vc = Vc + (b - a) * v
                Wc = Wc + (b - a) * w
                Va = Va + (b - a) * abs(v)
                Wa = Wa + (b - a) * abs(w)
                moment = (b - a) * ((t1 - a) + (t1 - b)) / 2.0  # the integral of (t1 - t) over [a, b]
                mV = mV + moment * abs(v)
                mW = mW + moment * abs(w)
                clipped = clipped or beyond
        return Vc, Wc, Va, Wa, clipped, mV, mW

    def _slip(self, t, x, y, theta, amounts):
        """The window's body-frame increments against the ranges the box allows (module docstring).  Forward:
        sum_k (p_k - p_k-1) . c_k / sinc(dtheta_k / 2), c_k the direction at the period's mid heading: the
        position noise (|n| <= sqrt 2 a) telescopes to sqrt 2 a (2 + sum |mid_k - mid_k-1|), the heading noise
        turns each projection by at most b (|dp_k| b); heading: the increments telescope to theta_end -
        theta_start (2 b)."""
        if self.poses:
            t0, x0, y0, th0 = self.poses[-1]
            dth = _mon_wrap(theta - th0)
            mid = th0 + dth / 2.0
            c, s, k = math.cos(mid), math.sin(mid), 1.0 / _mon_sinc(dth / 2.0)
            dx, dy = x - x0, y - y0
            Vc, Wc, Va, Wa, clipped, mV, mW = self._commanded(t0, t)
            dmid = abs(_mon_wrap(mid - self.periods[-1][6])) if self.periods else 0.0  # the direction's turn since
            sums = self.sums
            if len(self.periods) == self.window:  # the oldest goes
                o = self.periods.pop(0)
                for i, v in enumerate(_mon_summands(o)):
                    sums[i] = sums[i] - v
            p = ((dx * c + dy * s) * k, dth, (dy * c - dx * s) * k, Vc, Wc, math.sqrt(dx * dx + dy * dy), mid, clipped, dmid,
                 Va, Wa, mV, mW)
            self.periods.append(p)
            self.since += 1
            if self.since == self.window:  # afresh, in the window's order
                self.since = 0
                sums[:] = [0.0] * 10
            for o in (self.periods if self.since == 0 else [p]):
                for i, v in enumerate(_mon_summands(o)):
                    sums[i] = sums[i] + v
        self.poses = (self.poses + [(t, x, y, theta)])[-(self.window + 1):]
        while len(self.schedule) > 1 and self.schedule[1][0] <= self.poses[0][0]:
            self.schedule.pop(0)  # acted wholly before the window
        if len(self.periods) < self.window or any(p[7] for p in self.periods):
            return 0  # a window not yet full, or one in which the motors were asked for more than they give
        S, TH, L, Vc, Wc, travel, turned, turns, Va, Wa = self.sums
        turns = turns - self.periods[0][8]  # the mid direction's turns between the window's periods
        (s_m, d_m, ys_m, yd_m, xs_m, xd_m), (s_r, d_r, ys_r, yd_r, xs_r, xd_r) = self.comp_mid, self.comp_rad
        planar = self._planar(turns, travel)
        # forward: v_x = s v + d (D/4) omega_c; yaw: omega = ys omega_c + yd v / D; lateral: v_y = -(xs omega_c + xd v / D)
        q = self.D / 4.0
        ranges = (
            ("forward", S, _mon_range(s_m, s_r, Vc, Va), _mon_range(d_m, d_r, q * Wc, q * Wa), planar),
            ("heading", TH, _mon_range(ys_m, ys_r, Wc, Wa), _mon_range(yd_m, yd_r, Vc / self.D, Va / self.D),
             2.0 * self.head_noise + self.model_tol * turned),
            ("lateral", L, _mon_range(-xs_m, xs_r, Wc, Wa), _mon_range(-xd_m, xd_r, Vc / self.D, Va / self.D), planar),
        )
        worst = 0.0
        for _name, got, (p_lo, p_hi), (q_lo, q_hi), err in ranges:
            lo, hi = p_lo + q_lo - err, p_hi + q_hi + err
            worst = max(worst, lo - got, got - hi)
        status = 0
        if worst > 0.0:
            amounts["slip"] = worst
            status = SLIP
        if self.max_rate is not None:
            excess = self._rate()
            if excess > 0.0:
                amounts["rate"] = excess
                status |= RATE
        return status

    def _planar(self, turns, travel):
        """The noise's and the model's allowance on a forward or lateral sum over ``travel`` metres whose directions
        turned by ``turns`` between periods (module docstring, :meth:`_slip`)."""
        return math.sqrt(2.0) * self.pos_noise * (2.0 + turns) + travel * (self.head_noise + self.model_tol)

    def _rate(self):
        """By how much the traction sums the window's halves imply lie farther apart than max_rate x the window's
        time (0 where a half was not driven forward throughout: its travel is then no weighted average of s)."""
        h = len(self.periods) // 2
        q = self.D / 4.0
        bounds = []
        for part in (self.periods[:h], self.periods[h:]):
            S = Vc = Wc = Va = Wa = travel = turns = 0.0
            for i, p in enumerate(part):
                S, Vc, Wc, travel, Va, Wa = S + p[0], Vc + p[3], Wc + p[4], travel + p[5], Va + p[9], Wa + p[10]
                if i:
                    turns = turns + p[8]
            if not (Vc > 0.0 and Va == Vc):  # a command with V_hat < 0 acted in it
                return 0.0
            err = self._planar(turns, travel)
            q_lo, q_hi = _mon_range(self.comp_mid[1], self.comp_rad[1], q * Wc, q * Wa)
            bounds.append(((S - err - q_hi) / Vc, (S + err - q_lo) / Vc))
        (lo1, hi1), (lo2, hi2) = bounds
        return max(lo2 - hi1, lo1 - hi2) - self.max_rate * (len(self.periods) * self.Ts)

    def slip_estimate(self):
        """The tracks' traction now (at the last pose's instant t_k), as far as the poses and the commands that acted
        show it (docs/theory.md §17): a set-membership estimate, sure to contain the true value when the slip stays
        in its box, moves as ``slip.max_rate`` r allows (``|mu(t) - mu(t')| <= r (|t - t'| + Ts)``: a rate bound,
        or jumps of at most r Ts no two closer than Ts) and the pose noise stays within its bound.  Each window of
        the last 1, 2, 4, 8, ... judged periods and the longest bounds ``s = (mu_r + mu_l) / 2`` and
        ``d = mu_r - mu_l`` by a slab (forward: ``s Vc + d (D/4) Wc``; heading, tracks model only:
        ``s Wc + d Vc / D``), widened by the noise's, the model's and the rate's allowances; their intersection with
        the box is a convex polygon in (s, d), whose extremes give mu_r and mu_l.

        Returns None when the description has no slip ranges (made before); else ``{"t", "windows" (periods
        used), "consistent" (False: no traction in the box explains the window, as the SLIP check says), "ranges"
        {name: (lo, hi)} (mu_r, mu_l, their mean ``traction`` s and their ``difference`` d; icr: yaw, icr_offset),
        "estimate" {name: centre}, "bound" {name: half-width}, "observed" {name: narrower than the box}}``.
        Without ``slip.max_rate`` the traction now is anywhere in the box (windows 0).  The icr model's yaw factor
        and x_icr have no rate bound: they stay their box, and so does the traction difference they hide (the
        heading window bounds yaw x d)."""
        if self.slip_ranges is None:
            return None
        ranges = [tuple(rg) for rg in self.slip_ranges]
        (r_lo, r_hi), (l_lo, l_hi) = ranges[0], ranges[1]
        poly = [((r + l) / 2.0, r - l) for r, l in ((r_lo, l_lo), (r_hi, l_lo), (r_hi, l_hi), (r_lo, l_hi))]
        used = 0
        if self.max_rate is not None and self.poses:
            poly, used = self._estimate_windows(poly)
        t = self.poses[-1][0] if self.poses else None
        if not poly:
            return {"t": t, "windows": used, "consistent": False, "ranges": {}, "estimate": {}, "bound": {},
                    "observed": {}}
        box = dict(zip(("mu_r", "mu_l", "yaw", "icr_offset"), ranges))
        box["traction"] = ((r_lo + l_lo) / 2.0, (r_hi + l_hi) / 2.0)
        box["difference"] = (r_lo - l_hi, r_hi - l_lo)
        out = {"mu_r": (min(s + d / 2.0 for s, d in poly) - _EST_ROUND, max(s + d / 2.0 for s, d in poly) + _EST_ROUND),
               "mu_l": (min(s - d / 2.0 for s, d in poly) - _EST_ROUND, max(s - d / 2.0 for s, d in poly) + _EST_ROUND),
               "traction": (min(s for s, d in poly) - _EST_ROUND, max(s for s, d in poly) + _EST_ROUND),
               "difference": (min(d for s, d in poly) - _EST_ROUND, max(d for s, d in poly) + _EST_ROUND)}
        out = {k: (max(lo, box[k][0]), min(hi, box[k][1])) for k, (lo, hi) in out.items()}
        if self.slip_model == "icr":
            out["yaw"], out["icr_offset"] = ranges[2], ranges[3]
        return {"t": t, "windows": used, "consistent": True, "ranges": out,
                "estimate": {k: (lo + hi) / 2.0 for k, (lo, hi) in out.items()},
                "bound": {k: (hi - lo) / 2.0 for k, (lo, hi) in out.items()},
                "observed": {k: hi - lo < (box[k][1] - box[k][0]) * (1.0 - 1e-9) for k, (lo, hi) in out.items()}}

    @property
    def estimate_names(self):
        """The parameters :meth:`slip_estimate` gives ranges of, in the order the C estimate and the ROS 2 topic use:
        mu_r, mu_l, their mean and difference, and on the icr model its yaw factor and x_icr."""
        return ("mu_r", "mu_l", "traction", "difference") + (("yaw", "icr_offset") if self.slip_model == "icr" else ())

    def _estimate_windows(self, poly):
        """``poly`` clipped by the slabs of every window of the last 1 ... len(periods) judged periods (newest
        first; :meth:`slip_estimate`).  Returns the polygon and the number of periods used."""
        r, Ts, q, D = self.max_rate, self.Ts, self.D / 4.0, self.D
        tk = self.poses[-1][0]
        S = TH = Vc = Wc = Va = Wa = travel = turned = turns = MV = MW = 0.0
        n = len(self.periods)
        used = 0
        for j in range(n):
            p = self.periods[n - 1 - j]
            if p[7]:  # a command beyond the motor limit acted (or none was known): not judged, nor anything before
                break
            if j:
                turns = turns + self.periods[n - j][8]  # the mid direction's turn between this period and the next
            t_end = self.poses[len(self.poses) - 1 - j][0]
            S, TH, Vc, Wc, travel = S + p[0], TH + p[1], Vc + p[3], Wc + p[4], travel + p[5]
            turned, Va, Wa = turned + abs(p[1]), Va + p[9], Wa + p[10]
            MV = MV + p[11] + (tk - t_end) * p[9]  # the integrals of (t_k - t) |V_hat| and |omega_hat| so far
            MW = MW + p[12] + (tk - t_end) * p[10]
            rv, rw = r * (MV + Ts * Va), r * (MW + Ts * Wa)  # what the rate lets s move under them (d: twice)
            e = self._planar(turns, travel) + rv + 2.0 * q * rw
            slabs = [(Vc, q * Wc, S, e)]
            if self.slip_model == "tracks":
                slabs.append((Wc, Vc / D, TH, 2.0 * self.head_noise + self.model_tol * turned + rw + 2.0 * rv / D))
            # the windows of 1, 2, 4, 8, ... periods and the longest judged one (all of them: twice the clipping, and
            # on bench_slip_estimate's runs the same median half-widths, 3 % narrower on one of three rows)
            if (j + 1) & j == 0 or j + 1 == n or self.periods[n - 2 - j][7]:
                for a, b, c, err in slabs:
                    poly = _mon_clip(_mon_clip(poly, a, b, c + err), -a, -b, err - c)
            used = j + 1
            if not poly:
                break
        return poly, used

    def step(self, t, x, y, theta, xi, command, seq, reports=()):
        """One period: :meth:`check`, then the command to send (the law's, or the fallback's once engaged),
        registered as sent with sequence number ``seq`` (:meth:`sent`).  Returns (status, command to send)."""
        status = self.check(t, x, y, theta, xi, command, reports)
        out = self.fallback_command(command)
        self.sent(seq, t, out)
        return status, out

    def check(self, t, x, y, theta, xi, command, reports=()):
        """The checks of one period: the pose (x, y, theta) measured at t_k, the lifted state ``xi`` the law
        used, the ``command`` (V_hat, omega_hat) it computed, and the network's ``reports`` since the last step,
        ``(seq, applied time)`` per command (None or NaN: lost).  Returns the status word; ``self.amounts`` says
        by how much each of its bits was exceeded, ``self.engaged`` whether the fallback is engaged."""
        amounts = {}
        status = self._reports(t, reports, amounts)
        seg = max(sum(1 for s in self.segment_starts if s <= t + 1e-12) - 1, 0)  # the path's segment at t
        if seg != self.segment:
            self.segment, self.inside = seg, False
        V = self._V(xi)
        v_hat, w_hat = command
        if self.inside:  # the set's claims: the heading the channels assume, the motor bound
            if V > self.set_threshold:
                status |= SET
                amounts["set"] = V / self.level
            if self.heading_limit is not None and abs(xi[2]) > self.heading_limit:
                status |= HEADING
                amounts["heading"] = abs(xi[2]) - self.heading_limit
            rho = self._rho(v_hat, w_hat)
            if self.rho_limit is not None and rho > self.rho_limit:
                status |= MOTOR
                amounts["motor"] = rho - self.rho_limit
        self.inside = self.inside or V <= self.set_entry
        status |= self._slip(t, x, y, theta, amounts)
        self.amounts = amounts
        if status:
            if self.alarm_run == 0:
                self.held = self.last_sent
            self.alarm_run += 1
            if self.alarm_run >= self.persistence:
                self.engaged = True
        else:
            self.alarm_run = 0
        return status

    def suspend(self):
        """The certificate's claims on the set do not apply to the command about to be sent (a slip-compensated law
        whose estimate is not sure to be within its error, docs/theory.md §18): the SET, HEADING and MOTOR checks wait
        until the state is seen inside the set again, as after a waypoint."""
        self.inside = False

    def fallback_command(self, command):
        """The command to send: ``command`` (the law's), or once the fallback is engaged: stop (0, 0), hold (the
        last command sent before the alarms began), slow (``command`` times slow_factor)."""
        if not self.engaged:
            return (command[0], command[1])
        if self.fallback == "stop":
            return (0.0, 0.0)
        if self.fallback == "hold":
            return self.held if self.held is not None else (0.0, 0.0)
        return (command[0] * self.slow_factor, command[1] * self.slow_factor)

    def sent(self, seq, t, command):
        """The command (V_hat, omega_hat) sent at t_k with sequence number ``seq`` (what the robot will apply:
        the slip check integrates it over the time it acts)."""
        self.pending[seq] = (t, command[0], command[1])
        self.last_sent = (command[0], command[1])
