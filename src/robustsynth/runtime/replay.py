"""The runtime monitor (:mod:`robustsynth.monitor`) run over robot logs: ``robustsynth monitor LOG --gains G``,
and what ``verify`` and ``validate`` record of their runs.

Each log row k is one period: the pose measured at t_k, the command sent then (its motor speeds) and when it
started acting (empty: lost).  The lifted state the monitor judges is the law's: the error of the logged pose in
the path's frame (:class:`robustsynth.law.Law`), with the logged commands, less the reference's feedforward, as the
stored corrections (what the robot was really sent).  The reports reach the monitor as they would on the robot:
a command's applied time at the first sampling instant at or after it; a lost command is never reported, so the
monitor counts it lost once tau_max has passed.  The commands in flight before the log's first row are unknown:
the stored corrections start at zero and the slip check starts with the first command the log shows acting.  A
slip-compensated law's log (docs/theory.md §18) is replayed as :meth:`robustsynth.law.Compensator.step` runs it: the
law's memory is its own (the sent commands are divided by the estimate), the monitor checks the law's command, and
each period records whether the certificate's condition was sure to hold (``condition_held``); where the log has
the estimate's columns (mu_hat_r, mu_hat_l, condition), the periods they differ from the replay's are listed
(``estimate_differs``: the controller that wrote the log is not this gain's compensated law, or its inputs are not
the log's).
"""

from __future__ import annotations

import math
from typing import Any

from ..law import Compensator, Controller
from ..monitor import CAUSES, Monitor, describe

# the replay's estimate against a log's own: the log holds motor speeds, from which the replay recomputes the commands
# (V, omega) the monitor integrates, so its estimate differs from the controller's in the last bits (measured on
# verify's compensated run logs: at most 6e-16); a traction that differs by more is another controller's
ESTIMATE_TOL = 1e-9

__all__ = ["estimate_summary", "monitor_log", "monitor_logs", "monitor_summary", "monitor_files"]


def monitor_log(log: Any, description: dict[str, Any], estimate: bool = False) -> dict[str, Any]:
    """The monitor over one :class:`~robustsynth.artifacts.logs.RobotLog` with the controller ``description``
    (:func:`robustsynth.artifacts.gains.controller_description`, with its ``monitor``): per period the status word,
    and the alarms (period, t, causes, by how much), the period the fallback would have engaged (None: never).
    ``estimate``: also the slip estimate of every period (:meth:`~robustsynth.monitor.Monitor.slip_estimate`),
    ``"estimates"``."""
    ctl = Controller(description)
    mon = Monitor(description)
    R, D = float(description["gear_radius"]), float(description["track_distance"])
    V, d_hi = float(description["reference_speed"]), ctl.d_hi
    law = ctl.law
    corrections: list[tuple[float, float]] = []  # the logged commands less u^D and the feedforward, newest last
    pending = sorted((float(log.applied[k]), k) for k in range(len(log)) if math.isfinite(float(log.applied[k])))
    nxt = 0
    statuses, alarms, engaged, estimates, held, differs = [], [], None, [], [], []
    comp = Compensator(description) if description.get("compensation") else None
    for k in range(len(log)):
        t = float(log.t[k])
        reports = []
        while nxt < len(pending) and pending[nxt][0] <= t + 1e-12:
            applied, j = pending[nxt]
            reports.append((int(log.seq[j]), applied))
            nxt += 1
        if comp is None:  # the law's memory holds what was sent (a log of another run of this law: the same)
            past = [c for pair in reversed(corrections[-d_hi:]) for c in pair]
            law.past = past + [0.0] * (2 * d_hi - len(past))
        law_command = ctl.step(t, float(log.x[k]), float(log.y[k]), float(log.theta[k]))
        rr, rl = float(log.rho_r[k]), float(log.rho_l[k])
        command = (R / 2.0 * (rr + rl), R / D * (rr - rl))  # u_hat = J rho
        w = law.feedforward(t)
        corrections.append((command[0] - V - w * ctl.ff_V, command[1] - w * ctl.ff_omega))
        # a compensated law: the monitor checks the law's own command (the sent one is divided by the estimate) and
        # the law's memory is its own, as Compensator.step runs them (docs/theory.md §18)
        status = mon.check(t, float(log.x[k]), float(log.y[k]), float(log.theta[k]), ctl.state,
                           command if comp is None else law_command, reports)
        if comp is not None:
            est = comp.take(mon)  # as Compensator.step
            held.append(comp.holds)
            if log.estimate is not None and (max(abs(float(log.estimate[k, 0]) - comp.mu[0]),
                                                 abs(float(log.estimate[k, 1]) - comp.mu[1])) > ESTIMATE_TOL
                                             or bool(log.estimate[k, 2]) != comp.holds):
                differs.append(k)  # the controller that wrote the log estimated otherwise than this replay
        mon.sent(int(log.seq[k]), t, command)  # what the robot was sent (the fallback only says when it would engage)
        statuses.append(status)
        if estimate:
            estimates.append(est if comp is not None else mon.slip_estimate())
        if status:
            alarms.append({"period": k, "t": t, "causes": describe(status), "by": dict(mon.amounts)})
        if mon.engaged and engaged is None:
            engaged = k
    counts = {name: sum(1 for s in statuses if s & bit) for name, bit in CAUSES}
    out = {"log": str(log.path), "periods": len(statuses), "statuses": statuses, "alarms": alarms,
           "alarm_periods": counts, "fallback_engaged_at": engaged, "fallback": description["monitor"]["fallback"]}
    if estimate:
        out["estimates"] = estimates
    if comp is not None:  # the periods in which the compensated law's condition was sure to hold
        out["condition_held"] = held
        # with the log's own estimate columns: the periods whose logged estimate or condition is not the replay's
        out["estimate_differs"] = None if log.estimate is None else differs
    return out


def estimate_summary(estimates: list[Any]) -> dict[str, Any]:
    """What the slip estimates of some periods (:meth:`~robustsynth.monitor.Monitor.slip_estimate`, None or with no
    window skipped) show: the periods estimated, those no traction in the box explains (``inconsistent``), and per
    parameter the median and the largest half-width and the share of periods it was narrower than the box."""
    used = [e for e in estimates if e is not None and e["windows"] > 0]
    ok = [e for e in used if e["consistent"]]
    out: dict[str, Any] = {"periods": len(used), "inconsistent": len(used) - len(ok), "parameters": {}}
    for name in (ok[0]["bound"] if ok else ()):
        half = sorted(e["bound"][name] for e in ok)
        out["parameters"][name] = {"median_half": half[len(half) // 2], "max_half": half[-1],
                                   "observed_share": sum(1 for e in ok if e["observed"][name]) / len(ok)}
    return out


def monitor_logs(logs: list[Any], description: dict[str, Any], estimate: bool | None = None) -> dict[str, Any]:
    """:func:`monitor_log` of each log, and the totals: runs with an alarm, alarm periods per cause, the first
    alarm of each cause (log and period), and each log's first alarm (``first_per_log``: period and causes, or None).
    ``estimate``: also the slip estimates of every period, summed up in ``slip_estimate`` (:func:`estimate_summary`)
    and, per run, its last one (``last_estimate``); None: where the description has slip.max_rate (without, the
    estimate is the box).  A slip-compensated law's (``compensation``): the share of periods its condition held and,
    over the logs with the estimate's columns, the periods whose logged estimate or condition is not the replay's."""
    if estimate is None:
        estimate = description["monitor"].get("max_rate") is not None
    runs = [monitor_log(lg, description, estimate=estimate) for lg in logs]
    summary = {}
    if estimate:
        summary["slip_estimate"] = estimate_summary([e for r in runs for e in r["estimates"]])
        for r in runs:
            r["last_estimate"] = r.pop("estimates")[-1] if r["estimates"] else None
    if description.get("compensation"):  # the compensated law's condition over the logs (docs/theory.md §18)
        held = [h for r in runs for h in r["condition_held"]]
        differs = [r["estimate_differs"] for r in runs if r["estimate_differs"] is not None]
        summary["compensation"] = {
            "condition_held_share": sum(held) / max(len(held), 1), "periods": len(held),
            "logs_with_the_estimate": len(differs), "periods_the_logged_estimate_differs": sum(len(d) for d in differs)}
    first: dict[str, Any] = {}
    for r in runs:
        for a in r["alarms"]:
            for cause in a["causes"].split(", "):
                first.setdefault(cause, {"log": r["log"], "period": a["period"], "t": a["t"], "by": a["by"].get(cause)})
    return {"runs": runs, "logs": len(runs), "runs_with_alarms": sum(1 for r in runs if r["alarms"]),
            "alarm_periods": {name: sum(r["alarm_periods"][name] for r in runs) for name, _ in CAUSES},
            "fallback_engaged": sum(1 for r in runs if r["fallback_engaged_at"] is not None), "first": first,
            "first_per_log": [{"period": r["alarms"][0]["period"], "causes": r["alarms"][0]["causes"]} if r["alarms"] else None
                              for r in runs], **summary}


def monitor_summary(logs: list[Any], gains: dict[str, Any], config: Any) -> dict[str, Any] | None:
    """What ``verify`` and ``validate`` record of the monitor over their runs' logs (not in a verdict): the totals of
    :func:`monitor_logs` without the per-run detail, and what the monitor is sure to see.  None where there is
    nothing to monitor: a gain without a certified set, or a config it cannot be deployed with (the verdict says
    why)."""
    from ..artifacts.gains import controller_description
    from ..errors import InputError

    try:
        desc = controller_description(gains, config)
    except InputError:
        return None
    if not desc.get("monitor"):
        return None
    res = monitor_logs(logs, desc)
    keys = ("logs", "runs_with_alarms", "alarm_periods", "fallback_engaged", "first", "first_per_log", "slip_estimate",
            "compensation")
    return {**{k: res[k] for k in keys if k in res}, "detects": desc["monitor"]["detects"]}


def monitor_files(log_paths: list[Any], gains_path: Any, config: Any = None, outdir: Any = None) -> dict[str, Any]:
    """``robustsynth monitor``: the monitor of the gain in ``gains_path`` (with ``config``, else the config stored in
    the gains file) over the robot logs ``log_paths``; the totals of :func:`monitor_logs` with every alarm, and,
    with ``outdir``, ``monitor.json`` written there (atomically).  A linear plant's gains, a gains file without a
    config or without a certificate, a malformed log: InputError (exit 2), nothing written."""
    from ..artifacts.files import commit_files, json_bytes
    from ..artifacts.gains import controller_description, load_gains, stored_config
    from ..artifacts.logs import read_log
    from ..errors import InputError

    gains = load_gains(gains_path)
    if gains.get("kind") == "lti":
        raise InputError(f"{gains_path}: a linear plant's gains (kind: lti); the monitor watches the tracked robot's certificate")
    cfg = config if config is not None else stored_config(gains)
    if cfg is None:
        raise InputError(f"{gains_path}: config: the gains file holds no config (give CONFIG)")
    description = controller_description(gains, cfg)
    if not description.get("monitor"):
        raise InputError(f"{gains_path}: certificate: no certified set (P, ellipsoid_level) to monitor against")
    logs = [read_log(p) for p in log_paths]
    out = monitor_logs(logs, description)
    out.update({"gains": str(gains_path), "gains_id": gains.get("gains_id"), "config": cfg.name,
                "monitor": description["monitor"]})
    if outdir is not None:
        commit_files(outdir, {"monitor.json": json_bytes(out)}, primary="monitor.json")
    return out
