"""The runtime monitor (:mod:`robustsynth.monitor`) as C99: rs_monitor.h / rs_monitor.c beside rs_controller.c,
the same operations in the same order as the Python class (bit-identical: ``tests/runtime/test_export_monitor.py``),
only <math.h>, no heap (fixed arrays: the commands in flight, the applied schedule of the window, its poses), and
rs_monitor_harness.c, which replays periods from stdin for the tests and times a step (``--bench N``)."""

from __future__ import annotations

import math
from typing import Any

from ..law import Compensator
from ..monitor import _EST_ROUND, CAUSES, Monitor
from .export_compensator import _c_compensator, _compensated_harness, _compensator_h
from .codegen import _c_array as _arr, _f  # C double literals that read back exactly

__all__ = ["c_monitor_files", "c_wrap", "MONITOR_CAPACITY"]

MONITOR_CAPACITY = 64  # commands in flight / overdue / applied in the window the C monitor keeps (fixed arrays)


def c_wrap(name: str, comment: str) -> str:
    """A C function ``name`` giving an angle in [-pi, pi) by floor modulo, as Python's ``(a + pi) % (2 pi) - pi``
    (fmod, then the sign's correction Python's float % makes): the law's and the monitor's C share it."""
    return f"""/* {comment} */
static double {name}(double a)
{{
    double m = a + PI_;
    if (m >= 0.0 && m < TWO_PI_) return m - PI_; /* fmod would return m itself */
    m = fmod(m, TWO_PI_);
    if (m != 0.0) {{
        if (m < 0.0) m += TWO_PI_;
    }} else {{
        m = 0.0;
    }}
    return m - PI_;
}}"""


def c_monitor_files(d: dict[str, Any]) -> dict[str, bytes]:
    """rs_monitor.h, rs_monitor.c and rs_monitor_harness.c of the description ``d`` (with its ``monitor``); for the
    slip-compensated law (``d["compensation"]``, docs/theory.md §18) they carry its compensator too (rs_compensator_*,
    the same operations as :class:`robustsynth.law.Compensator`), and a description without one gives the files it
    gave before the compensator was built, byte for byte."""
    m = Monitor(d)  # validates the description and computes what the Python class derives (the segments' starts)
    k = Compensator(d) if d.get("compensation") else None
    h = _monitor_h(m)
    c = _monitor_c(m)
    harness = _monitor_harness()
    if k is not None:
        h = h.replace("\n#endif /* RS_MONITOR_H */\n", "\n" + _compensator_h() + "\n#endif /* RS_MONITOR_H */\n")
        c = c + "\n" + _c_compensator(k)
        harness = _compensated_harness(harness)
    return {"rs_monitor.h": h.encode(), "rs_monitor.c": c.encode(), "rs_monitor_harness.c": harness.encode()}


def _monitor_h(m: Monitor) -> str:
    """rs_monitor.h: the status bits (RS_MON_*), the sizes, the monitor's state (rs_monitor_t: fixed arrays of
    RS_MON_CAPACITY commands, the window's poses and periods) and the prototypes of rs_monitor_init, _check,
    _fallback, _sent and _step."""
    n_s = len(m.P[0])
    W = m.window
    cap = max(MONITOR_CAPACITY, 4 * W + 16)
    bits = "\n".join(f"#define RS_MON_{name.upper()} {bit}" for name, bit in CAUSES)
    return f"""/* rs_monitor.h: the runtime monitor of the certificate's assumptions (robustsynth.monitor, the same
   operations in the same order: bit-identical to the Python class).  Each period, after rs_step:
     status = rs_monitor_step(&m, t, x, y, theta, c.xi, V, omega, seq, n, seqs, applied, &V_out, &omega_out);
   with the reports of the commands applied since the last period (applied time; NaN: lost), then send
   (V_out, omega_out): the law's command, or the fallback's once engaged.  status: a word of RS_MON_* bits
   (0: every assumption holds as far as the monitor sees); m.amounts[i]: by how much bit i was exceeded. */
#ifndef RS_MONITOR_H
#define RS_MONITOR_H

{bits}
#define RS_MON_CAUSES {len(CAUSES)}
#define RS_MON_N_S {n_s}
#define RS_MON_WINDOW {W}
#define RS_MON_CAPACITY {cap}
#define RS_MON_HAS_ESTIMATE {0 if m.slip_ranges is None else 1} /* rs_monitor_slip_estimate has the slip box */

typedef struct {{
    long pend_seq[RS_MON_CAPACITY];                         /* sent, not yet reported (by seq) */
    double pend_t[RS_MON_CAPACITY], pend_v[RS_MON_CAPACITY], pend_w[RS_MON_CAPACITY];
    int n_pend;
    long over_seq[RS_MON_CAPACITY];                         /* counted lost: no report by t_j + tau_max */
    double over_t[RS_MON_CAPACITY], over_v[RS_MON_CAPACITY], over_w[RS_MON_CAPACITY];
    int n_over;
    double sched_t[RS_MON_CAPACITY], sched_v[RS_MON_CAPACITY], sched_w[RS_MON_CAPACITY]; /* applied, in time order */
    int sched_beyond[RS_MON_CAPACITY];                      /* the command asks the motors for more than rho_max */
    int n_sched, sched_first;
    double last_applied;
    long lost_run;
    double pose_t[RS_MON_WINDOW + 1];                       /* the poses' times: a ring, pose_first the oldest */
    int n_poses, pose_first;
    double last[4], last_mid;                               /* the newest pose, the newest period's mid heading */
    double period[RS_MON_WINDOW][13]; /* ds, dtheta, dlat, Vc, Wc, |dp|, mid heading, unjudged, |turn of mid|, Va, Wa,
                                         the integrals of (t_end - t) |V_hat| and |omega_hat| (the slip estimate's) */
    int n_periods, period_first, n_unjudged;               /* n_unjudged: periods of the ring flagged unjudged */
    double sums[10]; /* the ring's running sums of ds, dtheta, dlat, Vc, Wc, |dp|, |dtheta|, |turn of mid|, Va, Wa */
    int since;                                              /* periods since they were last summed afresh */
    long alarm_run;
    int engaged, inside, segment, has_held, has_sent;
    double held[2], last_sent[2];
    double amounts[RS_MON_CAUSES];                          /* by how much each bit of the last status */
}} rs_monitor_t;

void rs_monitor_init(rs_monitor_t *m);
int rs_monitor_check(rs_monitor_t *m, double t, double x, double y, double theta, const double *xi, double V,
                     double omega, int n_reports, const long *seqs, const double *applied);
void rs_monitor_fallback(const rs_monitor_t *m, double V, double omega, double *V_out, double *omega_out);
void rs_monitor_sent(rs_monitor_t *m, long seq, double t, double V, double omega);
int rs_monitor_step(rs_monitor_t *m, double t, double x, double y, double theta, const double *xi, double V,
                    double omega, long seq, int n_reports, const long *seqs, const double *applied, double *V_out,
                    double *omega_out);
/* the slip estimate (Monitor.slip_estimate): lo[i], hi[i] of mu_r, mu_l, their mean (mu_r + mu_l) / 2, their
   difference mu_r - mu_l, and the icr model's yaw, x_icr (their box; the tracks model's: 1, 0); *windows the periods
   used; returns 1, 0 when no traction in the box explains the window (lo, hi untouched), -1 without the box */
int rs_monitor_slip_estimate(const rs_monitor_t *m, double lo[6], double hi[6], int *windows);

#endif /* RS_MONITOR_H */
"""


def _monitor_c(m: Monitor) -> str:
    """rs_monitor.c: its sections in the file's order, each a C function or a few (the constants, the helpers,
    the queues of commands, reports_, V_, commanded_, rate_, slip_, the public functions)."""
    lyapunov = _c_lyapunov(m)  # its terms' literals first: a non-finite one is the error raised before a constant's
    return "\n".join((_c_constants(m), _c_helpers(), _c_queues(_saturation_differs(m)), _c_reports(), lyapunov,
                      _c_commanded(), _c_rate(), _c_slip(), _c_public(), _c_estimate()))


def _saturation_differs(m: Monitor) -> bool:
    """Whether the motors' own limit (``saturation_limit``: beyond it a command that acted is left out of the slip
    check and estimate) is not the MOTOR check's ``rho_limit``: a compensated law's (docs/theory.md §18).  Only then
    does rs_monitor.c carry it as a constant of its own (every other description's file stays as it was)."""
    return m.saturation_limit != m.rho_limit


def _c_constants(m: Monitor) -> str:
    """rs_monitor.c's head: its includes and the certificate's and the config's constants (delays, losses,
    the set's level, the limits, the slip box's components, the noise, the fallback, the segments' starts)."""
    comp_mid, comp_rad = _arr(m.comp_mid), _arr(m.comp_rad)
    fallback = {"stop": 0, "hold": 1, "slow": 2}[m.fallback]
    ranges = list(m.slip_ranges or [(1.0, 1.0)] * 2) + [(1.0, 1.0), (0.0, 0.0)]  # padded to four
    ranges = ranges[:4]
    seg = _arr(m.segment_starts) if m.segment_starts else "{0.0}"
    return f"""/* rs_monitor.c: see rs_monitor.h (generated by robustsynth from the gain's certificate). */
#include <math.h>
#include "rs_monitor.h"

static const double TS = {_f(m.Ts)};
static const double D_ = {_f(m.D)};
static const double INV_R = {_f(m.inv_R)};
static const double HALF_D_OVER_R = {_f(m.half_D_over_R)};
static const double TAU_MIN = {_f(m.tau_min)};
static const double TAU_MAX = {_f(m.tau_max)};
static const double CLOCK_TOL = {_f(m.clock_tol)};
static const long MAX_LOST = {m.max_lost};
static const double LEVEL = {_f(m.level)};
static const double SET_THRESHOLD = {_f(m.set_threshold)};
static const double SET_ENTRY = {_f(m.set_entry)};
static const int HAS_HEADING = {0 if m.heading_limit is None else 1};
static const double HEADING_LIMIT = {_f(m.heading_limit if m.heading_limit is not None else 0.0)};
static const int HAS_RHO = {0 if m.rho_limit is None else 1};
static const double RHO_LIMIT = {_f(m.rho_limit if m.rho_limit is not None else 0.0)};
{_c_saturation(m) if _saturation_differs(m) else ''}static const double COMP_MID[6] = {comp_mid}; /* the slip box's twist components: centres and radii */
static const double COMP_RAD[6] = {comp_rad};
static const double POS_NOISE = {_f(m.pos_noise)};
static const double HEAD_NOISE = {_f(m.head_noise)};
static const double MODEL_TOL = {_f(m.model_tol)};
static const int HAS_RATE = {0 if m.max_rate is None else 1};
static const double MAX_RATE = {_f(m.max_rate if m.max_rate is not None else 0.0)}; /* slip.max_rate [1/s] */
static const int TRACKS_MODEL = {1 if m.slip_model == "tracks" else 0}; /* the slip estimate's heading slabs */
static const double SLIP_LO[4] = {_arr([r[0] for r in ranges])}; /* the slip parameters' box: mu_r, mu_l (, yaw, x_icr) */
static const double SLIP_HI[4] = {_arr([r[1] for r in ranges])};
static const double EST_ROUND = {_f(_EST_ROUND)};
static const int FALLBACK = {fallback}; /* 0 stop, 1 hold, 2 slow */
static const long PERSISTENCE = {m.persistence};
static const double SLOW_FACTOR = {_f(m.slow_factor)};
#define N_SEG {len(m.segment_starts)}
static const double SEGMENT_STARTS[N_SEG > 0 ? N_SEG : 1] = {seg};
static const double PI_ = {_f(math.pi)};
static const double TWO_PI_ = {_f(2.0 * math.pi)};
"""


def _c_saturation(m: Monitor) -> str:
    """The motors' own limit where it is not RHO_LIMIT (the schedule's "beyond" flag: Monitor.saturation_limit)."""
    lim = m.saturation_limit
    return f"""/* the motors' own limit: a command beyond it that acted did not become motion as commanded (the slip check and
   estimate leave its periods out); RHO_LIMIT above is the MOTOR check's, the certificate's (docs/theory.md section 18) */
static const int HAS_SATURATION = {0 if lim is None else 1};
static const double SATURATION_LIMIT = {_f(lim if lim is not None else 0.0)};
"""


def _c_helpers() -> str:
    """The small functions the checks share: wrap_ (as the monitor's _mon_wrap), sinc_, max_ and min_ (as
    Python's), add_ / sub_ (a period into / out of the window's sums), planar_, range_ and rho_."""
    return f"""{c_wrap("wrap_", "Python's float % (floor modulo), as the monitor's _mon_wrap")}
static double sinc_(double a) {{ return fabs(a) < 0.05 ? 1.0 - a * a / 6.0 + a * a * a * a / 120.0 : sin(a) / a; }}
static double max_(double a, double b) {{ return b > a ? b : a; }} /* Python's max(a, b) */
static double min_(double a, double b) {{ return b < a ? b : a; }} /* Python's min(a, b) */
/* what a period p adds to the window's running sums (Python's _mon_summands), added or taken off */
static void add_(double *sum, const double *p)
{{
    sum[0] = sum[0] + p[0]; sum[1] = sum[1] + p[1]; sum[2] = sum[2] + p[2]; sum[3] = sum[3] + p[3];
    sum[4] = sum[4] + p[4]; sum[5] = sum[5] + p[5]; sum[6] = sum[6] + fabs(p[1]); sum[7] = sum[7] + p[8];
    sum[8] = sum[8] + p[9]; sum[9] = sum[9] + p[10];
}}
static void sub_(double *sum, const double *p)
{{
    sum[0] = sum[0] - p[0]; sum[1] = sum[1] - p[1]; sum[2] = sum[2] - p[2]; sum[3] = sum[3] - p[3];
    sum[4] = sum[4] - p[4]; sum[5] = sum[5] - p[5]; sum[6] = sum[6] - fabs(p[1]); sum[7] = sum[7] - p[8];
    sum[8] = sum[8] - p[9]; sum[9] = sum[9] - p[10];
}}
/* the noise's and the model's allowance on a forward or lateral sum (Python's Monitor._planar) */
static double planar_(double turns, double travel)
{{
    return sqrt(2.0) * POS_NOISE * (2.0 + turns) + travel * (HEAD_NOISE + MODEL_TOL);
}}
static void range_(double mid, double rad, double c, double a, double *out_lo, double *out_hi)
{{
    *out_lo = mid * c - rad * a;
    *out_hi = mid * c + rad * a;
}}
static double rho_(double v, double w)
{{
    return max_(fabs(v * INV_R + w * HALF_D_OVER_R), fabs(v * INV_R - w * HALF_D_OVER_R));
}}
"""


def _c_queues(saturation: bool = False) -> str:
    """rs_monitor_init, and the bookkeeping of the commands: find_ / remove_ in the arrays of commands in
    flight or overdue, and the applied schedule (SCH_* macros, drop_first_, schedule_: a stable insertion by time).
    ``saturation``: the schedule's "beyond the motor limit" flag compares with SATURATION_LIMIT (else RHO_LIMIT,
    the same number)."""
    text = """void rs_monitor_init(rs_monitor_t *m)
{
    int i;
    m->n_pend = m->n_over = m->n_sched = m->n_poses = m->n_periods = m->pose_first = m->period_first = 0;
    m->n_unjudged = m->sched_first = m->since = 0;
    for (i = 0; i < 10; ++i) m->sums[i] = 0.0;
    m->last_mid = 0.0;
    m->last_applied = -HUGE_VAL;
    m->lost_run = 0;
    m->alarm_run = 0;
    m->engaged = m->inside = m->segment = m->has_held = m->has_sent = 0;
    m->held[0] = m->held[1] = m->last_sent[0] = m->last_sent[1] = 0.0;
    for (i = 0; i < RS_MON_CAUSES; ++i) m->amounts[i] = 0.0;
}

static int find_(const long *seqs, int n, long seq)
{
    int i;
    for (i = 0; i < n; ++i) if (seqs[i] == seq) return i;
    return -1;
}

static void remove_(long *s, double *a, double *b, double *c, int *n, int i)
{
    for (; i + 1 < *n; ++i) { s[i] = s[i + 1]; a[i] = a[i + 1]; b[i] = b[i + 1]; c[i] = c[i + 1]; }
    --*n;
}

/* the applied schedule: entries sched_first .. sched_first + n_sched - 1 of its arrays, in time order */
#define SCH_T(i) m->sched_t[m->sched_first + (i)]
#define SCH_V(i) m->sched_v[m->sched_first + (i)]
#define SCH_W(i) m->sched_w[m->sched_first + (i)]
#define SCH_B(i) m->sched_beyond[m->sched_first + (i)]

static void drop_first_(rs_monitor_t *m)
{
    ++m->sched_first;
    --m->n_sched;
}

static void schedule_(rs_monitor_t *m, double applied, double v, double w) /* a stable insertion by time */
{
    int i;
    if (m->n_sched == RS_MON_CAPACITY) drop_first_(m); /* full: the oldest goes (it acted before the window) */
    if (m->sched_first + m->n_sched == RS_MON_CAPACITY) { /* at the arrays' end: the entries move to their start */
        for (i = 0; i < m->n_sched; ++i) {
            m->sched_t[i] = SCH_T(i); m->sched_v[i] = SCH_V(i); m->sched_w[i] = SCH_W(i); m->sched_beyond[i] = SCH_B(i);
        }
        m->sched_first = 0;
    }
    i = m->n_sched;
    while (i > 0 && SCH_T(i - 1) > applied) {
        SCH_T(i) = SCH_T(i - 1); SCH_V(i) = SCH_V(i - 1); SCH_W(i) = SCH_W(i - 1); SCH_B(i) = SCH_B(i - 1);
        --i;
    }
    SCH_T(i) = applied; SCH_V(i) = v; SCH_W(i) = w;
    SCH_B(i) = HAS_RHO && rho_(v, w) > RHO_LIMIT;
    ++m->n_sched;
}
"""
    if saturation:
        text = text.replace("SCH_B(i) = HAS_RHO && rho_(v, w) > RHO_LIMIT;",
                            "SCH_B(i) = HAS_SATURATION && rho_(v, w) > SATURATION_LIMIT; /* the motors' own limit */")
    return text


def _c_reports() -> str:
    """reports_: the reports of applied commands against the delay range [tau_min, tau_max] (RS_MON_DELAY), and
    the commands without a report by t_k + tau_max counted lost (RS_MON_LOSSES past max_lost in a row)."""
    return """static int reports_(rs_monitor_t *m, double t, int n, const long *seqs, const double *applied)
{
    int status = 0, r, i, late;
    for (r = 0; r < n; ++r) {
        double tk, v, w, tau, excess;
        i = find_(m->over_seq, m->n_over, seqs[r]);
        late = i >= 0;
        if (late) {
            tk = m->over_t[i]; v = m->over_v[i]; w = m->over_w[i];
            remove_(m->over_seq, m->over_t, m->over_v, m->over_w, &m->n_over, i);
        } else {
            i = find_(m->pend_seq, m->n_pend, seqs[r]);
            if (i < 0) continue;
            tk = m->pend_t[i]; v = m->pend_v[i]; w = m->pend_w[i];
            remove_(m->pend_seq, m->pend_t, m->pend_v, m->pend_w, &m->n_pend, i);
        }
        if (applied[r] != applied[r]) { /* lost */
            if (!late) m->lost_run += 1;
            continue;
        }
        tau = applied[r] - tk;
        excess = max_(TAU_MIN - CLOCK_TOL - tau, tau - TAU_MAX - CLOCK_TOL);
        if (applied[r] < m->last_applied - CLOCK_TOL) excess = max_(excess, m->last_applied - applied[r]);
        if (excess > 0.0) {
            status |= RS_MON_DELAY;
            m->amounts[0] = max_(m->amounts[0], excess);
        }
        m->last_applied = max_(m->last_applied, applied[r]);
        schedule_(m, applied[r], v, w);
        if (!late) m->lost_run = 0;
    }
    i = 0;
    while (i < m->n_pend) { /* in seq order: the arrays are kept sorted by seq */
        if (t - m->pend_t[i] > TAU_MAX + CLOCK_TOL) {
            if (m->n_over < RS_MON_CAPACITY) {
                m->over_seq[m->n_over] = m->pend_seq[i]; m->over_t[m->n_over] = m->pend_t[i];
                m->over_v[m->n_over] = m->pend_v[i]; m->over_w[m->n_over] = m->pend_w[i];
                ++m->n_over;
            }
            remove_(m->pend_seq, m->pend_t, m->pend_v, m->pend_w, &m->n_pend, i);
            m->lost_run += 1;
        } else {
            ++i;
        }
    }
    i = 0;
    while (i < m->n_over) {
        if (t - m->over_t[i] > TAU_MAX + TS * (double)(MAX_LOST + 2))
            remove_(m->over_seq, m->over_t, m->over_v, m->over_w, &m->n_over, i);
        else
            ++i;
    }
    if (m->lost_run > MAX_LOST) {
        status |= RS_MON_LOSSES;
        m->amounts[1] = (double)(m->lost_run - MAX_LOST);
    }
    return status;
}
"""


def _c_lyapunov(m: Monitor) -> str:
    """V_: the certificate's Lyapunov function, the max over its P's of xi' P xi, written out term by term
    (the nonzero upper-triangle terms, in the Python class's order)."""
    V_body = "\n".join("    acc = 0.0;\n" + "".join(f"    acc = acc + {_f(c)} * xi[{i}] * xi[{j}];\n" for c, i, j in terms)
                       + "    best = max_(best, acc);" for terms in m.V_terms)
    return f"""static double V_(const double *xi) /* max over the P's of xi' P xi: their nonzero upper-triangle terms, in order */
{{
    double best = 0.0, acc;
{V_body}
    return best;
}}
"""


def _c_commanded() -> str:
    """commanded_: the integrals of the applied commands (and of their magnitudes) over [t0, t1], and whether
    a part of it is unjudged (no command known, or one beyond the motor limit)."""
    return """static void commanded_(const rs_monitor_t *m, double t0, double t1, double *Vc, double *Wc, double *Va, double *Wa,
                       int *clipped, double *mV, double *mW)
{
    int i;
    *Vc = *Wc = *Va = *Wa = *mV = *mW = 0.0;
    *clipped = m->n_sched == 0 || SCH_T(0) > t0;
    i = m->n_sched > 0 ? m->n_sched - 1 : 0;
    while (i > 0 && SCH_T(i) > t0) --i; /* the entries before the last one starting by t0 ended by t0 */
    for (; i < m->n_sched; ++i) {
        double end = i + 1 < m->n_sched ? SCH_T(i + 1) : HUGE_VAL;
        double a = max_(SCH_T(i), t0), b = min_(end, t1);
        if (b > a) {
            *Vc = *Vc + (b - a) * SCH_V(i);
            *Wc = *Wc + (b - a) * SCH_W(i);
            *Va = *Va + (b - a) * fabs(SCH_V(i));
            *Wa = *Wa + (b - a) * fabs(SCH_W(i));
            if (RS_MON_HAS_ESTIMATE && HAS_RATE) { /* the integral of (t1 - t) over [a, b], times |V_hat|, |omega_hat| */
                double moment = (b - a) * ((t1 - a) + (t1 - b)) / 2.0;
                *mV = *mV + moment * fabs(SCH_V(i));
                *mW = *mW + moment * fabs(SCH_W(i));
            }
            *clipped = *clipped || SCH_B(i);
        }
    }
}
"""


def _c_rate() -> str:
    """rate_: by how much the traction the window's two halves imply changed faster than slip.max_rate."""
    return """/* by how much the traction sums the window's halves imply lie farther apart than MAX_RATE x the window's time */
static double rate_(const rs_monitor_t *m)
{
    int h = m->n_periods / 2, part, i, i0, i1;
    double lo[2], hi[2], q = D_ / 4.0;
    for (part = 0; part < 2; ++part) {
        double S = 0.0, Vc = 0.0, Wc = 0.0, Va = 0.0, Wa = 0.0, travel = 0.0, turns = 0.0, err, q_lo, q_hi;
        i0 = part ? h : 0;
        i1 = part ? m->n_periods : h;
        for (i = i0; i < i1; ++i) {
            const double *p = m->period[(m->period_first + i) % RS_MON_WINDOW];
            S = S + p[0]; Vc = Vc + p[3]; Wc = Wc + p[4]; travel = travel + p[5]; Va = Va + p[9]; Wa = Wa + p[10];
            if (i > i0) turns = turns + p[8];
        }
        if (!(Vc > 0.0 && Va == Vc)) return 0.0; /* a command with V_hat < 0 acted in it */
        err = planar_(turns, travel);
        range_(COMP_MID[1], COMP_RAD[1], q * Wc, q * Wa, &q_lo, &q_hi);
        lo[part] = (S - err - q_hi) / Vc;
        hi[part] = (S + err - q_lo) / Vc;
    }
    return max_(lo[1] - hi[0], lo[0] - hi[1]) - MAX_RATE * ((double)m->n_periods * TS);
}
"""


def _c_slip() -> str:
    """slip_: a period's pose increment into the window (its ring and running sums), then the window's sums
    against the slip box's range of the commanded motion (RS_MON_SLIP) and the rate check (RS_MON_RATE)."""
    return """static int slip_(rs_monitor_t *m, double t, double x, double y, double theta)
{
    int i, j, n, e, status;
    double S, TH, L, Vc, Wc, Va, Wa, travel, turns, turned, planar, worst, err, p_lo, p_hi, q_lo, q_hi;
    if (m->n_poses > 0) {
        const double *q0 = m->last;
        double dth = wrap_(theta - q0[3]);
        double mid = q0[3] + dth / 2.0;
        double c = cos(mid), s = sin(mid), k = 1.0 / sinc_(dth / 2.0);
        double dx = x - q0[1], dy = y - q0[2], vc, wc, va, wa, mv, mw, dmid = 0.0, *p, *sum = m->sums;
        int clipped;
        commanded_(m, q0[0], t, &vc, &wc, &va, &wa, &clipped, &mv, &mw);
        if (m->n_periods > 0) dmid = fabs(wrap_(mid - m->last_mid));
        m->last_mid = mid;
        if (m->n_periods == RS_MON_WINDOW) { /* the oldest goes */
            const double *o = m->period[m->period_first];
            sub_(sum, o);
            m->n_unjudged -= o[7] != 0.0;
            m->period_first = m->period_first + 1 == RS_MON_WINDOW ? 0 : m->period_first + 1;
            --m->n_periods;
        }
        e = m->period_first + m->n_periods;
        p = m->period[e >= RS_MON_WINDOW ? e - RS_MON_WINDOW : e];
        p[0] = (dx * c + dy * s) * k;
        p[1] = dth;
        p[2] = (dy * c - dx * s) * k;
        p[3] = vc;
        p[4] = wc;
        p[5] = sqrt(dx * dx + dy * dy);
        p[6] = mid;
        p[7] = clipped ? 1.0 : 0.0;
        p[8] = dmid;
        p[9] = va;
        p[10] = wa;
        p[11] = mv;
        p[12] = mw;
        m->n_unjudged += clipped != 0;
        ++m->n_periods;
        if (++m->since == RS_MON_WINDOW) { /* the sums afresh, in the ring's order */
            m->since = 0;
            for (i = 0; i < 10; ++i) sum[i] = 0.0;
            for (n = 0, j = m->period_first; n < m->n_periods; ++n, j = j + 1 == RS_MON_WINDOW ? 0 : j + 1)
                add_(sum, m->period[j]);
        } else {
            add_(sum, p);
        }
    }
    if (m->n_poses == RS_MON_WINDOW + 1) { /* the oldest pose's time goes */
        m->pose_first = m->pose_first == RS_MON_WINDOW ? 0 : m->pose_first + 1;
        --m->n_poses;
    }
    e = m->pose_first + m->n_poses;
    m->pose_t[e > RS_MON_WINDOW ? e - (RS_MON_WINDOW + 1) : e] = t;
    m->last[0] = t; m->last[1] = x; m->last[2] = y; m->last[3] = theta;
    ++m->n_poses;
    while (m->n_sched > 1 && SCH_T(1) <= m->pose_t[m->pose_first]) drop_first_(m);
    if (m->n_periods < RS_MON_WINDOW || m->n_unjudged > 0) return 0;
    S = m->sums[0]; TH = m->sums[1]; L = m->sums[2]; Vc = m->sums[3]; Wc = m->sums[4]; travel = m->sums[5];
    turned = m->sums[6]; Va = m->sums[8]; Wa = m->sums[9];
    turns = m->sums[7] - m->period[m->period_first][8]; /* the mid direction's turns between the window's periods */
    planar = planar_(turns, travel);
    worst = 0.0;
    range_(COMP_MID[0], COMP_RAD[0], Vc, Va, &p_lo, &p_hi);
    range_(COMP_MID[1], COMP_RAD[1], D_ / 4.0 * Wc, D_ / 4.0 * Wa, &q_lo, &q_hi);
    worst = max_(max_(worst, p_lo + q_lo - planar - S), S - (p_hi + q_hi + planar));
    err = 2.0 * HEAD_NOISE + MODEL_TOL * turned;
    range_(COMP_MID[2], COMP_RAD[2], Wc, Wa, &p_lo, &p_hi); range_(COMP_MID[3], COMP_RAD[3], Vc / D_, Va / D_, &q_lo, &q_hi);
    worst = max_(max_(worst, p_lo + q_lo - err - TH), TH - (p_hi + q_hi + err));
    range_(-COMP_MID[4], COMP_RAD[4], Wc, Wa, &p_lo, &p_hi); range_(-COMP_MID[5], COMP_RAD[5], Vc / D_, Va / D_, &q_lo, &q_hi);
    worst = max_(max_(worst, p_lo + q_lo - planar - L), L - (p_hi + q_hi + planar));
    status = 0;
    if (worst > 0.0) {
        m->amounts[5] = worst;
        status = RS_MON_SLIP;
    }
    if (HAS_RATE) {
        double excess = rate_(m);
        if (excess > 0.0) {
            m->amounts[6] = excess;
            status |= RS_MON_RATE;
        }
    }
    return status;
}
"""


def _c_public() -> str:
    """The public functions: rs_monitor_check (every check of a period), rs_monitor_fallback (the command sent
    once engaged), rs_monitor_sent (a command into the queue of those in flight) and rs_monitor_step (all three)."""
    return """int rs_monitor_check(rs_monitor_t *m, double t, double x, double y, double theta, const double *xi, double V,
                     double omega, int n_reports, const long *seqs, const double *applied)
{
    int status, i, seg = 0;
    double v;
    for (i = 0; i < RS_MON_CAUSES; ++i) m->amounts[i] = 0.0;
    status = reports_(m, t, n_reports, seqs, applied);
    for (i = 0; i < N_SEG; ++i) if (SEGMENT_STARTS[i] <= t + 1e-12) ++seg;
    seg = seg - 1 > 0 ? seg - 1 : 0;
    if (seg != m->segment) { m->segment = seg; m->inside = 0; }
    v = V_(xi);
    if (m->inside) {
        double rho;
        if (v > SET_THRESHOLD) { status |= RS_MON_SET; m->amounts[2] = v / LEVEL; }
        if (HAS_HEADING && fabs(xi[2]) > HEADING_LIMIT) { status |= RS_MON_HEADING; m->amounts[3] = fabs(xi[2]) - HEADING_LIMIT; }
        rho = rho_(V, omega);
        if (HAS_RHO && rho > RHO_LIMIT) { status |= RS_MON_MOTOR; m->amounts[4] = rho - RHO_LIMIT; }
    }
    m->inside = m->inside || v <= SET_ENTRY;
    status |= slip_(m, t, x, y, theta);
    if (status) {
        if (m->alarm_run == 0) { m->has_held = m->has_sent; m->held[0] = m->last_sent[0]; m->held[1] = m->last_sent[1]; }
        m->alarm_run += 1;
        if (m->alarm_run >= PERSISTENCE) m->engaged = 1;
    } else {
        m->alarm_run = 0;
    }
    return status;
}

void rs_monitor_fallback(const rs_monitor_t *m, double V, double omega, double *V_out, double *omega_out)
{
    if (!m->engaged) { *V_out = V; *omega_out = omega; }
    else if (FALLBACK == 0) { *V_out = 0.0; *omega_out = 0.0; }
    else if (FALLBACK == 1) { *V_out = m->has_held ? m->held[0] : 0.0; *omega_out = m->has_held ? m->held[1] : 0.0; }
    else { *V_out = V * SLOW_FACTOR; *omega_out = omega * SLOW_FACTOR; }
}

void rs_monitor_sent(rs_monitor_t *m, long seq, double t, double V, double omega)
{
    int i = m->n_pend;
    if (i == RS_MON_CAPACITY) { /* full: the oldest goes */
        remove_(m->pend_seq, m->pend_t, m->pend_v, m->pend_w, &m->n_pend, 0);
        i = m->n_pend;
    }
    while (i > 0 && m->pend_seq[i - 1] > seq) { /* kept sorted by seq */
        m->pend_seq[i] = m->pend_seq[i - 1]; m->pend_t[i] = m->pend_t[i - 1];
        m->pend_v[i] = m->pend_v[i - 1]; m->pend_w[i] = m->pend_w[i - 1];
        --i;
    }
    m->pend_seq[i] = seq; m->pend_t[i] = t; m->pend_v[i] = V; m->pend_w[i] = omega;
    ++m->n_pend;
    m->has_sent = 1;
    m->last_sent[0] = V;
    m->last_sent[1] = omega;
}

int rs_monitor_step(rs_monitor_t *m, double t, double x, double y, double theta, const double *xi, double V,
                    double omega, long seq, int n_reports, const long *seqs, const double *applied, double *V_out,
                    double *omega_out)
{
    int status = rs_monitor_check(m, t, x, y, theta, xi, V, omega, n_reports, seqs, applied);
    rs_monitor_fallback(m, V, omega, V_out, omega_out);
    rs_monitor_sent(m, seq, t, *V_out, *omega_out);
    return status;
}
"""


def _monitor_harness() -> str:
    """rs_monitor_harness.c: replays periods from stdin through rs_monitor_step and prints its status, command,
    amounts and whether the fallback engaged (17 digits); ``--bench N`` times N steps."""
    return """/* rs_monitor_harness.c: replays periods through rs_monitor_step (generated by robustsynth).
   rs_monitor_harness < periods.txt   a line per period: t x y theta V omega seq xi[RS_MON_N_S] n (seq applied)*n
                                      (applied: nan for lost) -> "status V_out omega_out amounts[6] engaged" (17 digits)
   (then, with the slip box: "E ok windows lo hi x6", rs_monitor_slip_estimate's)
   rs_monitor_harness --bench N [E]   mean time of N calls of rs_monitor_step [ns] (E: each followed by one of
                                      rs_monitor_slip_estimate) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "rs_monitor.h"

int main(int argc, char **argv)
{
    rs_monitor_t m;
    double t, x, y, th, V, w, xi[RS_MON_N_S], Vo, wo, applied[RS_MON_CAPACITY];
    long seq, seqs[RS_MON_CAPACITY];
    int n, i, status;
    rs_monitor_init(&m);
    if (argc >= 3 && strcmp(argv[1], "--bench") == 0) {
        long N = atol(argv[2]), k;
        int estimate = argc == 4 && strcmp(argv[3], "E") == 0;
        double sink = 0.0, lo[6], hi[6];
        clock_t t0 = clock();
        for (i = 0; i < RS_MON_N_S; ++i) xi[i] = 0.0;
        for (k = 0; k < N; ++k) {
            long kk = k % 600;
            if (kk == 0) rs_monitor_init(&m);
            seqs[0] = kk - 1; applied[0] = (double)(kk - 1) * 0.1 + 0.05;
            status = rs_monitor_step(&m, (double)kk * 0.1, 0.05 * (double)kk, 0.0, 0.0, xi, 0.5, 0.0, kk, kk > 0 ? 1 : 0,
                                     seqs, applied, &Vo, &wo);
            sink += Vo + (double)status;
            if (estimate) {
                int windows;
                sink += (double)rs_monitor_slip_estimate(&m, lo, hi, &windows) + (double)windows;
            }
        }
        printf("%.3f ns/step (checksum %.6g)\\n", 1e9 * (double)(clock() - t0) / CLOCKS_PER_SEC / (double)N, sink);
        return 0;
    }
    while (scanf("%lf %lf %lf %lf %lf %lf %ld", &t, &x, &y, &th, &V, &w, &seq) == 7) {
        for (i = 0; i < RS_MON_N_S; ++i) if (scanf("%lf", &xi[i]) != 1) return 2;
        if (scanf("%d", &n) != 1 || n < 0 || n > RS_MON_CAPACITY) return 2;
        for (i = 0; i < n; ++i) if (scanf("%ld %lf", &seqs[i], &applied[i]) != 2) return 2;
        status = rs_monitor_step(&m, t, x, y, th, xi, V, w, seq, n, seqs, applied, &Vo, &wo);
        printf("%d %.17g %.17g", status, Vo, wo);
        for (i = 0; i < RS_MON_CAUSES; ++i) printf(" %.17g", m.amounts[i]);
        printf(" %d", m.engaged);
#if RS_MON_HAS_ESTIMATE
        {
            double lo[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, hi[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}; /* kept if inconsistent */
            int windows, ok = rs_monitor_slip_estimate(&m, lo, hi, &windows);
            printf(" E %d %d", ok, windows);
            for (i = 0; i < 6; ++i) printf(" %.17g %.17g", lo[i], hi[i]);
        }
#endif
        printf("\\n");
    }
    return 0;
}
"""


def _c_estimate() -> str:
    """rs_monitor_slip_estimate (Monitor.slip_estimate and _estimate_windows, the same operations in the same order):
    the box as a polygon in (s, d), clipped by every window's forward (and, tracks model, heading) slab; clip_ is
    _mon_clip."""
    return """#define RS_MON_POLY (8 + 4 * RS_MON_WINDOW) /* the box's 4 vertices, at most one more per half-plane */

/* the part of the convex polygon in[0 .. n-1] where a x + b y <= c (Python's _mon_clip), into out; its size
   (-1: wholly inside, out untouched: the polygon is in[] as it was) */
static int clip_(double (*in)[2], int n, double (*out)[2], double a, double b, double c)
{
    double f[RS_MON_POLY];
    int i, k = 0, inside = 1;
    for (i = 0; i < n; ++i) { /* each vertex's side, once */
        f[i] = a * in[i][0] + b * in[i][1] - c;
        inside = inside && f[i] <= 0.0;
    }
    if (inside) return -1;
    for (i = 0; i < n; ++i) {
        const double *P = in[i == 0 ? n - 1 : i - 1], *Q = in[i];
        double fp = f[i == 0 ? n - 1 : i - 1], fq = f[i];
        if ((fp <= 0.0) != (fq <= 0.0)) { /* the edge crosses the line */
            double t = fp / (fp - fq);
            out[k][0] = P[0] + t * (Q[0] - P[0]);
            out[k][1] = P[1] + t * (Q[1] - P[1]);
            ++k;
        }
        if (fq <= 0.0) { out[k][0] = Q[0]; out[k][1] = Q[1]; ++k; }
    }
    return k;
}


/* the polygon (*cur)[0 .. n-1] cut by a x + b y <= c: clipped into *spare, then the two swap; its size */
static int cut_(double (**cur)[2], double (**spare)[2], int n, double a, double b, double c)
{
    double (*t)[2];
    int k = clip_(*cur, n, *spare, a, b, c);
    if (k < 0) return n; /* wholly inside: unchanged */
    t = *cur; *cur = *spare; *spare = t;
    return k;
}

int rs_monitor_slip_estimate(const rs_monitor_t *m, double lo[6], double hi[6], int *windows)
{
    double A[RS_MON_POLY][2], B[RS_MON_POLY][2], (*P)[2] = A, (*Q)[2] = B, r[4], l[4], box_lo[4], box_hi[4];
    double S = 0.0, TH = 0.0, Vc = 0.0, Wc = 0.0, Va = 0.0, Wa = 0.0, travel = 0.0, turned = 0.0, turns = 0.0;
    double MV = 0.0, MW = 0.0, q = D_ / 4.0;
    int n = 4, i, j, np = m->n_periods;
    *windows = 0;
    if (!RS_MON_HAS_ESTIMATE) return -1;
    r[0] = SLIP_LO[0]; l[0] = SLIP_LO[1]; r[1] = SLIP_HI[0]; l[1] = SLIP_LO[1];
    r[2] = SLIP_HI[0]; l[2] = SLIP_HI[1]; r[3] = SLIP_LO[0]; l[3] = SLIP_HI[1];
    for (i = 0; i < 4; ++i) { A[i][0] = (r[i] + l[i]) / 2.0; A[i][1] = r[i] - l[i]; }
    if (HAS_RATE && m->n_poses > 0) {
        double tk = m->last[0];
        for (j = 0; j < np; ++j) {
            const double *p = m->period[(m->period_first + np - 1 - j) % RS_MON_WINDOW];
            double t_end, rv, rw, e;
            if (p[7] != 0.0) break; /* not judged, nor anything before */
            if (j) turns = turns + m->period[(m->period_first + np - j) % RS_MON_WINDOW][8];
            t_end = m->pose_t[(m->pose_first + m->n_poses - 1 - j) % (RS_MON_WINDOW + 1)];
            S = S + p[0]; TH = TH + p[1]; Vc = Vc + p[3]; Wc = Wc + p[4]; travel = travel + p[5];
            turned = turned + fabs(p[1]); Va = Va + p[9]; Wa = Wa + p[10];
            MV = MV + p[11] + (tk - t_end) * p[9];
            MW = MW + p[12] + (tk - t_end) * p[10];
            rv = MAX_RATE * (MV + TS * Va);
            rw = MAX_RATE * (MW + TS * Wa);
            e = planar_(turns, travel) + rv + 2.0 * q * rw;
            /* the windows of 1, 2, 4, 8, ... periods and the longest judged one */
            if (((j + 1) & j) == 0 || j + 1 == np || m->period[(m->period_first + np - 2 - j) % RS_MON_WINDOW][7] != 0.0) {
                n = cut_(&P, &Q, n, Vc, q * Wc, S + e);
                n = cut_(&P, &Q, n, -Vc, -(q * Wc), e - S);
                if (TRACKS_MODEL) {
                    double a = Wc, b = Vc / D_, err = 2.0 * HEAD_NOISE + MODEL_TOL * turned + rw + 2.0 * rv / D_;
                    n = cut_(&P, &Q, n, a, b, TH + err);
                    n = cut_(&P, &Q, n, -a, -b, err - TH);
                }
            }
            *windows = j + 1;
            if (n == 0) break;
        }
    }
    if (n == 0) return 0;
    lo[0] = hi[0] = P[0][0] + P[0][1] / 2.0;
    lo[1] = hi[1] = P[0][0] - P[0][1] / 2.0;
    lo[2] = hi[2] = P[0][0];
    lo[3] = hi[3] = P[0][1];
    for (i = 1; i < n; ++i) {
        lo[0] = min_(lo[0], P[i][0] + P[i][1] / 2.0); hi[0] = max_(hi[0], P[i][0] + P[i][1] / 2.0);
        lo[1] = min_(lo[1], P[i][0] - P[i][1] / 2.0); hi[1] = max_(hi[1], P[i][0] - P[i][1] / 2.0);
        lo[2] = min_(lo[2], P[i][0]); hi[2] = max_(hi[2], P[i][0]);
        lo[3] = min_(lo[3], P[i][1]); hi[3] = max_(hi[3], P[i][1]);
    }
    box_lo[0] = SLIP_LO[0]; box_hi[0] = SLIP_HI[0]; box_lo[1] = SLIP_LO[1]; box_hi[1] = SLIP_HI[1];
    box_lo[2] = (SLIP_LO[0] + SLIP_LO[1]) / 2.0; box_hi[2] = (SLIP_HI[0] + SLIP_HI[1]) / 2.0;
    box_lo[3] = SLIP_LO[0] - SLIP_HI[1]; box_hi[3] = SLIP_HI[0] - SLIP_LO[1];
    for (i = 0; i < 4; ++i) {
        lo[i] = max_(lo[i] - EST_ROUND, box_lo[i]);
        hi[i] = min_(hi[i] + EST_ROUND, box_hi[i]);
    }
    for (i = 4; i < 6; ++i) { lo[i] = SLIP_LO[i - 2]; hi[i] = SLIP_HI[i - 2]; }
    return 1;
}
"""
