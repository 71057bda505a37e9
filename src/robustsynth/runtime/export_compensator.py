"""The slip-compensated law (:class:`robustsynth.law.Compensator`, docs/theory.md §18) as C99: its part of
rs_monitor.h / rs_monitor.c (rs_monitor_suspend, the compensator, rs_compensate, rs_compensator_step) and of the
harness (``--compensated``), the same operations in the same order as the Python class (bit-identical:
``tests/runtime/test_export_monitor.py``).  :func:`robustsynth.runtime.export_monitor.c_monitor_files` adds them for
a description with ``compensation``."""

from __future__ import annotations

from ..law import Compensator
from .codegen import _c_array as _arr, _f  # C double literals that read back exactly

__all__: list[str] = []


def _compensator_h() -> str:
    """rs_monitor.h's part for the slip-compensated law: rs_monitor_suspend, the compensator's state
    (rs_compensator_t: law.Compensator's mu, holds, margin, wait) and the prototypes of rs_compensator_init, _update,
    _covered, _command, _step and rs_compensate."""
    return """/* the slip-compensated law (robustsynth.law.Compensator, docs/theory.md section 18; the same operations in the same
   order: bit-identical to the Python class).  Each period, after rs_step, in place of rs_monitor_step:
     status = rs_compensator_step(&k, &m, t, x, y, theta, c.xi, V, omega, seq, n, seqs, applied, &V_out, &omega_out);
   the monitor checks the law's own command (V, omega: its MOTOR check is the certificate's limit on it), the
   compensator takes the monitor's slip estimate, and (V_out, omega_out) is the law's command with each track's speed
   divided by the estimated traction (or the fallback's once engaged).  k.holds: the certificate's condition is sure
   to hold for that command; where it has not held for it and the RS_COMP_D_HI before it (rs_compensator_covered 0)
   the monitor's set checks are suspended until the state is seen inside again. */
#define RS_MON_COMPENSATED 1

typedef struct {
    double mu[2];   /* the tractions the commands are divided by: mu_r, mu_l (the box's centre before an estimate) */
    int holds;      /* the condition (each track's half-width + lag <= error) sure to hold for this period's command */
    int has_margin; /* 0: no estimate from a window this period (Python's margin None) */
    double margin;  /* error less the worse track's half-width + lag (0.0 where has_margin is 0) */
    int wait;       /* periods until every command that can act was compensated under the condition (0: covered) */
} rs_compensator_t;

/* the set's claims do not cover the next state: SET, HEADING and MOTOR wait until it is seen inside again */
void rs_monitor_suspend(rs_monitor_t *m);
void rs_compensator_init(rs_compensator_t *k);
/* takes the monitor's slip estimate of this period (rs_monitor_slip_estimate); returns rs_compensator_covered */
int rs_compensator_update(rs_compensator_t *k, const rs_monitor_t *m);
int rs_compensator_covered(const rs_compensator_t *k);
/* the command whose tracks turn at (V, omega)'s track speeds divided by mu_r, mu_l (half_D: half the track distance) */
void rs_compensate(double V, double omega, double mu_r, double mu_l, double half_D, double *V_out, double *omega_out);
void rs_compensator_command(const rs_compensator_t *k, double V, double omega, double *V_out, double *omega_out);
int rs_compensator_step(rs_compensator_t *k, rs_monitor_t *m, double t, double x, double y, double theta,
                        const double *xi, double V, double omega, long seq, int n_reports, const long *seqs,
                        const double *applied, double *V_out, double *omega_out);
"""


def _c_compensator(k: Compensator) -> str:
    """rs_monitor.c's part for the slip-compensated law: its constants (law.Compensator's error, lag, half_D, d_hi and
    the box's centre, as the Python class computes them), rs_monitor_suspend (Monitor.suspend), the compensator
    (Compensator.reset, update, covered, command), rs_compensate (law.compensate) and rs_compensator_step
    (Compensator.step after the law's command): the same operations in the same order."""
    return f"""/* ---------------------------------------------- the slip-compensated law (robustsynth.law.Compensator) */
static const double COMPENSATION_ERROR = {_f(k.error)}; /* the estimate error the certificate assumes */
static const double COMPENSATION_LAG = {_f(k.lag)}; /* what slip.max_rate lets the traction move while a command acts */
static const double COMPENSATION_HALF_D = {_f(k.half_D)}; /* half the track distance [m] */
static const double COMPENSATION_CENTRE[2] = {_arr(k.centre)}; /* the slip box's centre: mu_r, mu_l */
static const int COMPENSATION_D_HI = {k.d_hi}; /* a command acts within this many periods after its own */

void rs_monitor_suspend(rs_monitor_t *m)
{{
    m->inside = 0;
}}

void rs_compensator_init(rs_compensator_t *k)
{{
    k->mu[0] = COMPENSATION_CENTRE[0];
    k->mu[1] = COMPENSATION_CENTRE[1];
    k->holds = 0;
    k->has_margin = 0;
    k->margin = 0.0;
    k->wait = COMPENSATION_D_HI + 1;
}}

int rs_compensator_covered(const rs_compensator_t *k)
{{
    return k->wait == 0;
}}

int rs_compensator_update(rs_compensator_t *k, const rs_monitor_t *m)
{{
    double lo[6], hi[6];
    int windows, ok = rs_monitor_slip_estimate(m, lo, hi, &windows);
    if (ok != 1 || windows == 0) {{ /* no box, inconsistent, or no window: the last estimate stays */
        k->holds = 0;
        k->has_margin = 0;
        k->margin = 0.0;
    }} else {{
        double half_r = (hi[0] - lo[0]) / 2.0, half_l = (hi[1] - lo[1]) / 2.0;
        k->mu[0] = (lo[0] + hi[0]) / 2.0;
        k->mu[1] = (lo[1] + hi[1]) / 2.0;
        k->margin = COMPENSATION_ERROR - (max_(half_r, half_l) + COMPENSATION_LAG);
        k->has_margin = 1;
        k->holds = k->margin >= 0.0;
    }}
    /* periods until every command that can act was compensated under the condition */
    k->wait = k->holds ? (k->wait - 1 > 0 ? k->wait - 1 : 0) : COMPENSATION_D_HI + 1;
    return rs_compensator_covered(k);
}}

void rs_compensate(double V, double omega, double mu_r, double mu_l, double half_D, double *V_out, double *omega_out)
{{
    double vr = (V + omega * half_D) / mu_r;
    double vl = (V - omega * half_D) / mu_l;
    *V_out = (vr + vl) * 0.5;
    *omega_out = (vr - vl) / (half_D + half_D);
}}

void rs_compensator_command(const rs_compensator_t *k, double V, double omega, double *V_out, double *omega_out)
{{
    rs_compensate(V, omega, k->mu[0], k->mu[1], COMPENSATION_HALF_D, V_out, omega_out);
}}

int rs_compensator_step(rs_compensator_t *k, rs_monitor_t *m, double t, double x, double y, double theta,
                        const double *xi, double V, double omega, long seq, int n_reports, const long *seqs,
                        const double *applied, double *V_out, double *omega_out)
{{
    double Vc, wc;
    int status = rs_monitor_check(m, t, x, y, theta, xi, V, omega, n_reports, seqs, applied);
    if (!rs_compensator_update(k, m)) rs_monitor_suspend(m); /* the set's claims do not cover the next state */
    rs_compensator_command(k, V, omega, &Vc, &wc);
    rs_monitor_fallback(m, Vc, wc, V_out, omega_out);
    rs_monitor_sent(m, seq, t, *V_out, *omega_out);
    return status;
}}
"""


def _compensated_harness(harness: str) -> str:
    """rs_monitor_harness.c with the compensated law's modes: ``--compensated`` replays the periods through
    rs_compensator_step and prints after the estimate ``C holds covered wait has_margin margin mu_r mu_l``;
    ``--bench N C`` times N of its steps (each with its slip estimate)."""
    edits = (
        ("""   rs_monitor_harness --bench N [E]   mean time of N calls of rs_monitor_step [ns] (E: each followed by one of
                                      rs_monitor_slip_estimate) */""",
         """   rs_monitor_harness --bench N [E]   mean time of N calls of rs_monitor_step [ns] (E: each followed by one of
                                      rs_monitor_slip_estimate)
   rs_monitor_harness --compensated   the same lines (V omega: the law's command) through rs_compensator_step, each
                                      output line ending "C holds covered wait has_margin margin mu_r mu_l"
   rs_monitor_harness --bench N C     mean time of N calls of rs_compensator_step [ns] (its estimate included) */"""),
        ("""    rs_monitor_t m;
""", """    rs_monitor_t m;
    rs_compensator_t comp;
    int compensated = argc == 2 && strcmp(argv[1], "--compensated") == 0;
"""),
        ("""    rs_monitor_init(&m);
    if (argc""", """    rs_monitor_init(&m);
    rs_compensator_init(&comp);
    if (argc"""),
        ("""        int estimate = argc == 4 && strcmp(argv[3], "E") == 0;
""", """        int estimate = argc == 4 && strcmp(argv[3], "E") == 0, comp_step = argc == 4 && strcmp(argv[3], "C") == 0;
"""),
        ("""            if (kk == 0) rs_monitor_init(&m);
""", """            if (kk == 0) { rs_monitor_init(&m); rs_compensator_init(&comp); }
"""),
        ("""            status = rs_monitor_step(&m, (double)kk * 0.1, 0.05 * (double)kk, 0.0, 0.0, xi, 0.5, 0.0, kk, kk > 0 ? 1 : 0,
                                     seqs, applied, &Vo, &wo);
""", """            if (comp_step)
                status = rs_compensator_step(&comp, &m, (double)kk * 0.1, 0.05 * (double)kk, 0.0, 0.0, xi, 0.5, 0.0, kk,
                                             kk > 0 ? 1 : 0, seqs, applied, &Vo, &wo);
            else
                status = rs_monitor_step(&m, (double)kk * 0.1, 0.05 * (double)kk, 0.0, 0.0, xi, 0.5, 0.0, kk,
                                         kk > 0 ? 1 : 0, seqs, applied, &Vo, &wo);
"""),
        ("""        status = rs_monitor_step(&m, t, x, y, th, xi, V, w, seq, n, seqs, applied, &Vo, &wo);
""", """        if (compensated)
            status = rs_compensator_step(&comp, &m, t, x, y, th, xi, V, w, seq, n, seqs, applied, &Vo, &wo);
        else
            status = rs_monitor_step(&m, t, x, y, th, xi, V, w, seq, n, seqs, applied, &Vo, &wo);
"""),
        ("""#endif
        printf("\\n");
""", """#endif
        if (compensated)
            printf(" C %d %d %d %d %.17g %.17g %.17g", comp.holds, rs_compensator_covered(&comp), comp.wait,
                   comp.has_margin, comp.margin, comp.mu[0], comp.mu[1]);
        printf("\\n");
"""),
    )
    for old, new in edits:
        if harness.count(old) != 1:
            raise AssertionError(f"rs_monitor_harness.c: the compensated mode's anchor is not there once: {old[:60]!r}")
        harness = harness.replace(old, new)
    return harness
