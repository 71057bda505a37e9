"""Figures of a verification (the only module that imports matplotlib; Agg backend).

Each function takes computed data and an optional ``ax`` and returns the figure; nothing here
computes a check."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from ..objectives import objective

__all__ = ["write_figures", "FIGURES", "FIGURE_CAPTIONS"]

FIGURES = {
    "path": "Path in the plane",
    "errors": "Tracking errors with certified bounds",
    "commands": "Commands and motor speeds",
    "network": "Delay and slip realizations",
    "lyapunov": "V(xi_k) against the certified decay",
    "ellipsoid": "Certified ellipsoid projections with simulated states",
    "frozen": "Frozen-delay spectral radius",
}
# what a figure's title leaves out (a title is one line: issue 50 found lyapunov.png's taking three); the
# reports print it under the figure
FIGURE_CAPTIONS = {
    "path": ("Top: the robot's paths in the plane. Bottom: the cross-track error against the certified band; grey, "
             "where there are any: the steps after a waypoint the verdict excludes until the robot is back in the "
             "certified set (as in the tracking errors)."),
    "lyapunov": ("Top: V on the lifted model, solid the maximum over the runs, dotted the median. The runs are named "
                 "delays/start: random, alternating or greedy delays (arcs: random delays along arcs; arcs-greedy: the "
                 "greedy search along arcs), starting on the set's boundary (V = level) or outside it (V = 25 level); "
                 "dashed: the certified decay from V = 25 level. Bottom: V of the nonlinear robot's true lifted state "
                 "relative to the certified ellipsoid; grey: the steps excluded after a waypoint, until back in the set."),
    "frozen": ("The spectral radius of the closed loop with the delay held at each constant tau, the largest over the "
               "slip corners."),
}
EXCLUDED_LABEL = "excluded (some run outside the set after a waypoint)"


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _ellipse(Qsub: np.ndarray, level: float, n: int = 200) -> np.ndarray:
    """Boundary of {x : x' Qsub^-1 x <= level}, the projection of {xi' P xi <= level}."""
    L = np.linalg.cholesky(Qsub * level)
    t = np.linspace(0, 2 * np.pi, n)
    return (L @ np.vstack([np.cos(t), np.sin(t)])).T


def _legend_right(ax, **kw) -> Any:
    """A legend beside the axes, right of them: it covers no data (issue 50: one covered a trace)."""
    return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=7, frameon=False, **kw)


def _legend_below(fig, handles, labels, ncol: int, rows: int = 1, **kw) -> None:
    """One legend for the figure, under its axes (laid out with room for it): it covers no data."""
    fig.tight_layout(rect=(0, 0.02 + 0.035 * rows, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=7, frameon=False, **kw)


def _shade_excluded(ax, t: np.ndarray, excluded: np.ndarray, label: str = EXCLUDED_LABEL) -> None:
    """Grey over the steps the verdict excludes (``~_covered(res)``, the one source every figure shades from);
    a legend entry only for something drawn (a path rounded by arcs excludes nothing)."""
    n = min(len(t), len(excluded))
    if excluded[:n].any():
        ax.fill_between(t[:n], 0, 1, where=excluded[:n], transform=ax.get_xaxis_transform(), color="grey", alpha=0.12,
                        label=label)


def fig_path(res, model) -> Any:
    plt = _plt()
    sim = res.sim
    W = np.asarray(model.config.reference.path)
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(10, 7), gridspec_kw={"height_ratios": [1.3, 1.0]})
    for n in range(sim.q.shape[0]):
        ax.plot(sim.q[n, :, 0], sim.q[n, :, 1], color="tab:blue", alpha=0.06, lw=0.8)
    ax.plot([], [], color="tab:blue", alpha=0.4, label=f"Monte Carlo runs ({sim.q.shape[0]})")
    r = model.config.reference.turn_radius
    if r is None:
        ax.plot(W[:, 0], W[:, 1], "k--", lw=1.2, label="desired polyline")
    else:  # the reference the law follows: the corners rounded by arcs (law.PathTable)
        from ..plants.path import path_of

        tab = path_of(model.config).table
        ax.plot(W[:, 0], W[:, 1], ":", color="0.6", lw=1.0, label="waypoints' polyline")
        ax.plot(tab.ref_x, tab.ref_y, "k--", lw=1.2, label=f"reference (corners rounded, r = {r:g} m)")
    ax.plot(W[:, 0], W[:, 1], "ko", ms=4)
    ax.plot(sim.q[0, :, 0], sim.q[0, :, 1], color="tab:red", lw=1.5, label="sample run (run 0)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Path in the plane: desired " + ("polyline" if r is None else "path") + " and the robot over the network")
    _legend_right(ax)
    ax.grid(alpha=0.3)
    # at the path's scale the tracking error is invisible: the cross-track error itself, in cm
    t = sim.t[: sim.e.shape[1]]
    ey = 100.0 * sim.e[:, :, 1]
    ax2.fill_between(t, ey.min(axis=0), ey.max(axis=0), color="tab:blue", alpha=0.25, label="Monte Carlo min–max")
    ax2.plot(t, ey[0], color="tab:red", lw=1, label="sample run (run 0)")
    ub = (res.certificate.figures.get("ultimate_bound") or {}) if res.certificate.passed else {}
    if ub.get("e_y") is not None:
        ax2.axhspan(-100 * ub["e_y"], 100 * ub["e_y"], color="tab:green", alpha=0.1, label=f"certified ±{100 * ub['e_y']:.2f} cm")
    for ts in model_path_switches(res, model):
        ax2.axvline(ts, color="0.6", lw=0.8, ls=":")
    # the steps errors.png shades: e_y there (a turn) is judged separately, not against the band (issue 50)
    _shade_excluded(ax2, t, ~_covered(res))
    ax2.set_xlabel("time t [s] (dotted: waypoints)")
    ax2.set_ylabel("cross-track error e_y [cm]")
    _legend_right(ax2)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def fig_errors(res, model) -> Any:
    plt = _plt()
    sim = res.sim
    ub = res.certificate.figures.get("ultimate_bound") if res.certificate.passed else None
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    labels = [("e_x", "m", 100.0, "cm"), ("e_y", "m", 100.0, "cm"), ("e_theta", "rad", 180 / np.pi, "deg")]
    for i, (ax, (name, _u, scale, unit)) in enumerate(zip(axes, labels)):
        e = sim.e[:, :, i] * scale
        lo, hi = np.percentile(e, [0, 100], axis=0)
        p5, p95 = np.percentile(e, [5, 95], axis=0)
        ax.fill_between(sim.t, lo, hi, color="tab:blue", alpha=0.15, label="Monte Carlo min–max")
        ax.fill_between(sim.t, p5, p95, color="tab:blue", alpha=0.3, label="5–95 %")
        ax.plot(sim.t, e[0], color="tab:red", lw=1, label="sample run")
        if ub:
            b = ub[name] * scale
            ax.axhspan(-b, b, color="tab:green", alpha=0.08)
            ax.axhline(b, color="tab:green", ls="--", lw=1, label="certified bound")
            ax.axhline(-b, color="tab:green", ls="--", lw=1)
        for ts in model_path_switches(res, model):
            ax.axvline(ts, color="grey", lw=0.8, ls=":")
        _shade_excluded(ax, sim.t, ~_covered(res))
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    axes[-1].set_xlabel("time t [s]")
    axes[0].set_title("Tracking error in the segment frame L (dotted: waypoint switches)" if model.config.reference.turn_radius
                      is None else "Tracking error in the reference's frame (corners rounded by arcs: no switches)")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=7, frameon=False)  # below the plots, off the data
    return fig


def _covered(res) -> np.ndarray:
    """(steps + 1,) True where every run's step is covered by the verdict's rule (res.mask)."""
    mask = res.mask if res.mask is not None else np.broadcast_to(res.sim.settled[None, :-1], res.sim.rho.shape[:2])
    cov = np.all(mask, axis=0)
    return np.concatenate([cov, cov[-1:]])


def model_path_switches(res, model) -> list[float]:
    from ..plants.path import path_of

    p = path_of(model.config)
    return list(p.t_start[1:])  # a turning reference has no switches


def fig_commands(res, model) -> Any:
    plt = _plt()
    sim = res.sim
    tk = sim.t[:-1]
    cfg = model.config
    fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
    for ax, data, name, unit in ((axes[0, 0], sim.du[:, :, 0], "dV", "m/s"), (axes[0, 1], sim.du[:, :, 1], "omega", "rad/s"),
                                 (axes[1, 0], sim.rho[:, :, 0], "rho_r (commanded)", "rad/s"),
                                 (axes[1, 1], sim.rho[:, :, 1], "rho_l (commanded)", "rad/s")):
        ax.fill_between(tk, data.min(axis=0), data.max(axis=0), color="tab:blue", alpha=0.25, label="Monte Carlo min–max")
        ax.plot(tk, data[0], color="tab:red", lw=1, label="sample run")
        if name.startswith("rho") and cfg.robot.max_motor_speed is not None:
            for s in (1, -1):
                ax.axhline(s * cfg.robot.max_motor_speed, color="k", ls="--", lw=1, label="rho_max" if s == 1 else None)
            msb = res.certificate.figures.get("motor_speed_bound") if res.certificate.passed else None
            if msb is not None:  # drawn wide under rho_max: the certificate often uses all of it
                for s in (1, -1):
                    ax.axhline(s * msb, color="tab:green", lw=4, alpha=0.35, zorder=0,
                               label=f"certified on the set: ±{msb:.2f} (rho_max ±{cfg.robot.max_motor_speed:g})" if s == 1 else None)
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time t [s]")
    fig.suptitle("Commands du_k = K xi_k and nominal motor speeds rho = J^-1 u_hat")
    handles, labels = axes[1, 0].get_legend_handles_labels()  # every entry: the rho axes draw them all
    _legend_below(fig, handles, labels, ncol=4)
    return fig


def fig_network(res, model) -> Any:
    plt = _plt()
    sim = res.sim
    cfg = model.config
    tk = sim.t[:-1]
    scen_taus, scen_mu = res.scenario.taus, res.scenario.mu
    fig, axes = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    ax = axes[0]
    taus = scen_taus[0, model.d_hi :] * 1000
    lost = np.isinf(taus)
    ax.plot(tk[~lost], taus[~lost], ".", ms=3, color="tab:purple", label="tau_k (sample run)")
    if lost.any():  # lost commands (network.dropouts): marked above the delay range
        y = cfg.network.delay.max * 1000 + 0.15 * cfg.network.sampling_time * 1000
        ax.plot(tk[lost], np.full(lost.sum(), y), "x", ms=4, color="tab:red",
                label=f"lost ({lost.sum()} of {lost.size}, bursts <= {cfg.network.dropouts.max_consecutive})")
    ax.axhline(cfg.network.delay.min * 1000, color="k", ls="--", lw=1, label="tau_min, tau_max")
    ax.axhline(cfg.network.delay.max * 1000, color="k", ls="--", lw=1)
    ax.axhline(cfg.network.sampling_time * 1000, color="grey", ls=":", lw=1, label="Ts")
    ax.set_ylabel("delay [ms]")
    _legend_right(ax)
    ax.grid(alpha=0.3)
    ax = axes[1]
    colors = {"constant": "tab:blue", "random-walk": "tab:orange", "steps": "tab:green", "corners": "tab:purple"}
    sw = res.scenario.mu_switch  # slip that changes within the periods: each new value from t_k + mu_switch[k]
    for n in range(min(3, scen_mu.shape[0])):
        tr, tl = (tk, tk) if sw is None else (tk + sw[n, :, 0], tk + sw[n, :, 1])
        ax.step(tr, scen_mu[n, :, 0], where="post", lw=1, color=list(colors.values())[n % 3], label=f"mu_r run {n}")
        ax.step(tl, scen_mu[n, :, 1], where="post", lw=1, ls="--", color=list(colors.values())[n % 3], label=f"mu_l run {n}")
    ax.axhline(min(cfg.slip.right.min, cfg.slip.left.min), color="k", ls=":", lw=1)
    ax.axhline(max(cfg.slip.right.max, cfg.slip.left.max), color="k", ls=":", lw=1)
    ax.set_ylabel("slip mu [-]")
    ax.set_xlabel("time t [s]")
    _legend_right(ax)
    ax.grid(alpha=0.3)
    axes[0].set_title("Network delay and track slip realizations (runs 0–2: constant, random walk, steps)")
    fig.tight_layout()
    return fig


def fig_lyapunov(res, model) -> Any:
    plt = _plt()
    vr = res.nonlinear_V_over_level
    if vr is None:
        fig, ax = plt.subplots(figsize=(10, 4.5))
    else:
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(11, 8))
        t = res.sim.t[:-1]
        ax2.semilogy(t, vr.max(axis=0), color="tab:red", lw=1.2, label="max over Monte Carlo runs")
        ax2.semilogy(t, np.median(vr, axis=0), color="tab:blue", lw=1, label="median")
        ax2.axhline(1.0, color="k", lw=1.5, label="ellipsoid level (V = level)")
        _shade_excluded(ax2, t, ~_covered(res)[:-1], "excluded (after a waypoint, until back in the set)")
        ax2.set_xlabel("time t [s]")
        ax2.set_ylabel("V(xi) / level [-]")
        ax2.set_title("Nonlinear robot: V of its true lifted state relative to the certified ellipsoid")
        _legend_right(ax2)
        ax2.grid(alpha=0.3, which="both")
    cert = res.certificate
    traces = res.lifted_traces
    for i, (name, V) in enumerate(sorted(traces.items())):
        col = f"C{i}"
        k = np.arange(V.shape[1])
        ax.semilogy(k, V.max(axis=0), color=col, lw=1.2, label=name)
        ax.semilogy(k, np.median(V, axis=0), color=col, lw=0.8, ls=":")
    if traces:
        ax.plot([], [], color="0.3", lw=1.2, label="solid: max over runs")
        ax.plot([], [], color="0.3", lw=0.8, ls=":", label="dotted: median")
    if cert.passed:
        c = res.gains["certificate"]
        if objective(c["objective"]).guarantee == "set":
            level = cert.figures["ellipsoid_level"]
            alpha = float(c["alpha"])
            k = np.arange(max(v.shape[1] for v in traces.values()))
            V0 = 25.0 * level
            ax.semilogy(k, level + (V0 - level) * (1 - alpha) ** k, "k--", lw=1,
                        label="certified: level + (V0 − level)(1−α)^k,\nV0 = 25·level")
            ax.axhline(level, color="k", lw=1.5, label="ellipsoid level")
        elif cert.figures.get("decay_rate"):
            r = cert.figures["decay_rate"]
            k = np.arange(max(v.shape[1] for v in traces.values()))
            V0 = max(float(np.max(v[:, 0])) for v in traces.values())
            ax.semilogy(k, V0 * r ** (2 * k), "k--", lw=1, label="certified r^(2k) V0")
    if not traces:
        ax.text(0.5, 0.5, "no valid certificate: V is not available", ha="center", transform=ax.transAxes)
    ax.set_xlabel("step k")
    ax.set_ylabel("V(xi_k) = xi' P xi [-]")
    # one line (issue 50: three); what the runs' names mean is in the legend and FIGURE_CAPTIONS["lyapunov"]
    ax.set_title("Lifted model under time-varying delays: V by run (delays/start)")
    if ax.get_legend_handles_labels()[0]:
        _legend_right(ax)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    return fig


def fig_ellipsoid(res, model) -> Any:
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.5))
    sim = res.sim
    mask = res.mask if res.mask is not None else np.broadcast_to(sim.settled[None, :-1], sim.rho.shape[:2])
    e = sim.e[:, :-1][mask] if np.any(mask) else sim.e.reshape(-1, 3)
    pairs = [((1, 2), ("e_y [cm]", "e_theta [deg]"), (100.0, 180 / np.pi)), ((0, 1), ("e_x [cm]", "e_y [cm]"), (100.0, 100.0))]
    cert = res.certificate
    for ax, (idx, labels, scales) in zip(axes, pairs):
        pts = e[..., list(idx)].reshape(-1, 2) * np.array(scales)
        ax.plot(pts[:, 0], pts[:, 1], ".", ms=1, alpha=0.15, color="tab:blue", label="nonlinear MC states (certified steps)")
        if cert.passed and cert.figures.get("ellipsoid_level") is not None:
            c = res.gains["certificate"]
            mats = [c["Q"]] if c.get("lyapunov", "common") == "common" else c["S"]
            for j, Q in enumerate(mats):
                Qs = np.asarray(Q, dtype=float)[np.ix_(idx, idx)]
                b = _ellipse(Qs, cert.figures["ellipsoid_level"]) * np.array(scales)
                ax.plot(b[:, 0], b[:, 1], color="tab:green", lw=1.5, ls="-" if j == 0 else "--",
                        label="certified set (projection)" if j == 0 else (
                            {"slip-dependent": "per slip corner", "delay-dependent": "per slip corner and delay vertex"}.get(
                                c.get("lyapunov"), "per slip corner and pair of delay vertices")
                            if j == 1 else None))
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        ax.grid(alpha=0.3)
    fig.suptitle("Certified invariant ellipsoid, projected, with simulated states")
    handles, labels = axes[0].get_legend_handles_labels()
    _legend_below(fig, handles, labels, ncol=3, markerscale=6)
    return fig


def fig_frozen(res, model) -> Any:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.6))
    fr = res.frozen
    ax.plot(np.asarray(fr["tau"]) * 1000, fr["spectral_radius_vs_tau"], color="tab:blue", lw=1.5, label="rho(A~(tau) + B~(tau) K)")
    ax.axhline(1.0, color="k", ls="--", lw=2, alpha=0.6, label="stability limit (1)")
    r = res.certificate.figures.get("decay_rate") if res.certificate.passed else None
    if r is not None:
        ax.axhline(r, color="tab:green", ls=":", lw=1.2, label=f"certified decay rate r = {r:.3f}")
    ax.set_xlabel("constant delay tau [ms]")
    ax.set_ylabel("spectral radius [-]")
    names = ", ".join(model.slip_names)
    corners = ", ".join("(" + ", ".join(f"{x:g}" for x in c) + ")" for c in np.asarray(model.corners))
    if len(corners) > 90:
        corners = f"{np.asarray(model.corners).shape[0]} corners"
    ax.set_title("Closed loop with the delay frozen at tau", fontsize=10)  # one line; the corners: in the legend
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    labels[0] += f", the largest over the slip corners ({names}): {corners}"
    _legend_below(fig, handles, labels, ncol=1, rows=len(labels))
    return fig


def write_figures(res, model, outdir: str | Path, fmt: str = "png") -> dict[str, Path]:
    """Render every figure into ``outdir/figures/`` (atomically); returns name -> path."""
    import io

    from ..artifacts.files import atomic_write

    plt = _plt()
    outdir = Path(outdir) / "figures"
    makers = {
        "path": lambda: fig_path(res, model),
        "errors": lambda: fig_errors(res, model),
        "commands": lambda: fig_commands(res, model),
        "network": lambda: fig_network(res, model),
        "lyapunov": lambda: fig_lyapunov(res, model),
        "ellipsoid": lambda: fig_ellipsoid(res, model),
        "frozen": lambda: fig_frozen(res, model),
    }
    from ..errors import check_interrupt
    from ..forked import beside

    def render(names: list[str]) -> dict[str, Path]:
        out = {}
        for name in names:
            check_interrupt()
            fig = makers[name]()
            buf = io.BytesIO()
            meta = {"Software": None} if fmt == "png" else ({"Creator": None, "Producer": None, "CreationDate": None} if fmt == "pdf" else {"Date": None})
            fig.savefig(buf, format=fmt, dpi=110, metadata=meta)
            plt.close(fig)
            path = outdir / f"{name}.{fmt}"
            atomic_write(path, buf.getvalue())
            out[name] = path
        return out

    # every other figure rendered beside (a forked child where there are two cores: ~0.5 s a figure on one core);
    # the files are the same bytes whoever renders them
    names = list(makers)
    with beside(lambda: render(names[1::2])) as theirs:
        written = {**render(names[0::2]), **theirs.result()}
    return {name: written[name] for name in names}


# ------------------------------------------------------------------------------------ sweeps

_SWEEP_FIGURES = {  # figure key -> (row column, label, scale)
    "e_x": ("e_x_m", "certified |e_x| [cm]", 100.0),
    "e_y": ("e_y_m", "certified |e_y| [cm]", 100.0),
    "e_theta": ("e_theta_rad", "certified |e_theta| [rad]", 1.0),
    "rho": ("rho_bound_rad_s", "certified |rho| [rad/s]", 1.0),
    "decay_rate": ("decay_rate", "certified decay rate", 1.0),
    "hinf_gain": ("hinf_gain", "certified l2 gain", 1.0),
    "output_bound": ("output_bound", "certified largest output bound / scale", 1.0),
}
_STATUS_MARK = {"infeasible": ("x", "tab:red"), "solver-failure": ("s", "tab:orange"), "invalid": ("^", "tab:gray")}


def _axis_positions(values: list[Any]) -> tuple[np.ndarray, list[str] | None]:
    """Numeric axes plot at their values; others (strings, booleans) at 0, 1, ... with labels."""
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) and v is not None for v in values):
        return np.asarray(values, dtype=float), None
    return np.arange(len(values), dtype=float), [str(v) for v in values]


def _key_label(key: str) -> str:
    """A config key with its unit, from the config's own field descriptions ('... [m/s]')."""
    import re

    from ..config import Config

    node: Any = Config
    field = None
    for part in key.split("."):
        fields = getattr(node, "model_fields", None)
        if not fields or part not in fields:
            return key
        field = fields[part]
        node = field.annotation
    m = re.search(r"\[([^\]]+)\]", (field.description or "") if field is not None else "")
    return f"{key} [{m.group(1)}]" if m else key


def _short(v: float) -> str:
    """A cell value that fits its cell: 3 significant digits, thousands as k."""
    return f"{v / 1000:.3g}k" if abs(v) >= 1000 else f"{v:.3g}"


def fig_sweep_1d(result) -> Any:
    plt = _plt()
    key = result.spec.keys[0]
    rows = result.rows
    x, labels = _axis_positions([r[key] for r in rows])
    ok = np.array([r["status"] == "certified" for r in rows])
    fig, ax = plt.subplots(figsize=(7, 4.2))
    plotted = False
    for col, lab, style in (("e_x_m", "certified |e_x|", "-o"), ("e_y_m", "certified |e_y|", "-s")):
        y = np.array([np.nan if r.get(col) is None else 100.0 * r[col] for r in rows])
        if np.any(np.isfinite(y)):
            ax.plot(x, y, style, label=lab, ms=4)
            plotted = True
    if "max_e_y_m" in result.columns:
        y = np.array([np.nan if r.get("max_e_y_m") is None else 100.0 * r["max_e_y_m"] for r in rows])
        if np.any(np.isfinite(y)):
            ax.plot(x, y, "--", color="k", lw=1, label="nonlinear robot max |e_y|")
    ax.set_ylabel("certified bound, observed maximum [cm]")
    if not plotted:
        key_fig = result.spec.figure
        col, lab, scale = _SWEEP_FIGURES[key_fig]
        y = np.array([np.nan if r.get(col) is None else scale * r[col] for r in rows])
        ax.plot(x, y, "-o", ms=4, label=lab)
        ax.set_ylabel(lab)
    for status, (marker, color) in _STATUS_MARK.items():
        sel = np.array([r["status"] == status for r in rows])
        if np.any(sel):
            ax.plot(x[sel], np.zeros(sel.sum()), marker, color=color, ms=8, ls="none", label=status, clip_on=False)
    # certified points that failed verification, on their certified |e_y| (or the axis): marked, as the title
    # counts them (a review found the title counting a point the figure did not show)
    failed = np.array([r.get("status") == "certified" and r.get("verified") is False for r in rows])
    if np.any(failed):
        y = np.array([0.0 if r.get("e_y_m") is None else 100.0 * r["e_y_m"] for r in rows])
        ax.plot(x[failed], y[failed], "X", color="tab:red", ms=10, ls="none", label="failed verification",
                clip_on=False, zorder=5)
    if labels is not None:
        ax.set_xticks(x, labels)
    ax.set_xlabel(_key_label(key))
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    nv = int(np.sum(failed))
    ax.set_title(f"{int(ok.sum())} of {len(rows)} points certified" + (f", {nv} failed verification" if nv else ""))
    fig.tight_layout()
    return fig


def fig_sweep_2d(result) -> Any:
    plt = _plt()
    k0, k1 = result.spec.keys[:2]
    v0 = list(result.spec.axes[0][1])
    v1 = list(result.spec.axes[1][1])
    col, lab, scale = _SWEEP_FIGURES[result.spec.figure]
    Z = np.full((len(v0), len(v1)), np.nan)
    status = np.empty((len(v0), len(v1)), dtype=object)
    for r in result.rows:  # grid order: the last axis varies fastest
        i, j = divmod(r["index"], len(v1))
        status[i, j] = r["status"]
        if r["status"] == "certified" and r.get(col) is not None:
            Z[i, j] = scale * r[col]
    x, xl = _axis_positions(v1)
    y, yl = _axis_positions(v0)
    fig, ax = plt.subplots(figsize=(7, 5))
    xi, yi = np.arange(len(v1)), np.arange(len(v0))
    finite = Z[np.isfinite(Z)]
    norm = None
    if finite.size and finite.min() > 0 and finite.max() / finite.min() > 20:  # bounds spanning decades
        from matplotlib.colors import LogNorm

        norm = LogNorm(vmin=finite.min(), vmax=finite.max())
    mesh = ax.pcolormesh(xi, yi, np.ma.masked_invalid(Z), shading="nearest", cmap="viridis", norm=norm)
    fig.colorbar(mesh, ax=ax, label=lab + (" (log scale)" if norm is not None else ""))
    if Z.size <= 150:  # the values themselves, readable on a small grid
        from matplotlib import patheffects

        outline = [patheffects.withStroke(linewidth=2, foreground="k")]
        for i in range(Z.shape[0]):
            for j in range(Z.shape[1]):
                if np.isfinite(Z[i, j]):
                    ax.text(j, i, _short(Z[i, j]), ha="center", va="center", fontsize=7, color="w",
                            path_effects=outline)
    ok = (status == "certified").astype(float)
    if 0 < ok.sum() < ok.size and min(ok.shape) > 1:
        ax.contour(xi, yi, ok, levels=[0.5], colors="k", linewidths=4)  # a white line on a black one:
        ax.contour(xi, yi, ok, levels=[0.5], colors="w", linewidths=1.5)  # visible on every colour
    for st, (marker, color) in _STATUS_MARK.items():
        jj, ii = np.nonzero((status == st).T)
        if jj.size:
            ax.plot(jj, ii, marker, color=color, ms=8, ls="none", label=st)
    ax.set_xticks(xi, xl if xl is not None else [f"{v:g}" for v in x], rotation=45 if len(v1) > 8 else 0)
    ax.set_yticks(yi, yl if yl is not None else [f"{v:g}" for v in y])
    ax.set_xlabel(_key_label(k1))
    ax.set_ylabel(_key_label(k0))
    if any(status[i, j] != "certified" for i in range(len(v0)) for j in range(len(v1))):
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, frameon=False)
    ax.set_title(f"{lab}; white line: boundary of the certified region")
    fig.tight_layout()
    return fig


def write_sweep_figure(result, outdir: str | Path, fmt: str = "png") -> Path | None:
    """sweep.<fmt>: 1-D (or zip) sweeps as curves against the first axis, 2-D grids as a heatmap;
    none for more axes."""
    import io

    from ..artifacts.files import atomic_write

    spec = result.spec
    if spec.mode == "grid" and len(spec.keys) == 2:
        fig = fig_sweep_2d(result)
    elif spec.mode == "zip" or len(spec.keys) == 1:
        fig = fig_sweep_1d(result)
    else:
        return None
    plt = _plt()
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=100, metadata={"Software": None} if fmt == "png" else None)
    plt.close(fig)
    path = Path(outdir) / f"sweep.{fmt}"
    atomic_write(path, buf.getvalue())
    return path


def _save_png(plt: Any, fig: Any, path: Path) -> Path:
    """Lay out, render to PNG and write atomically; the figure is closed."""
    from ..artifacts.files import atomic_write

    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write(path, buf.getvalue())
    return Path(path)


def identification_figure(ident: Any, path: Path) -> Path:
    """Histograms of the measured delays and of each slip estimate against the identified box, and
    the slip estimates against the commanded turn rate."""
    plt = _plt()
    names = ident.slip.names
    keys = list(ident.box)
    cols = 2 if len(names) <= 2 else 3
    fig, axes = plt.subplots(2, cols, figsize=(5 * cols, 7))
    axes = axes.ravel()
    ax = axes[0]
    ax.hist(ident.delays * 1000.0, bins=60, color="0.5")
    for x in ident.delay_range:
        ax.axvline(x * 1000.0, color="C3")
    ax.set_xlabel("delay applied - sent [ms]")
    ax.set_ylabel("commands")
    ax.set_title("delay (red: the identified range)")
    for i, (name, key) in enumerate(zip(names, keys)):
        axx = axes[1 + i]
        v = ident.slip.mu[:, i]
        v = v[np.isfinite(v)]
        flat = v.size == 0 or np.ptp(v) <= 1e-9 * max(1.0, float(np.max(np.abs(v))))  # one value: one bin
        axx.hist(v, bins=1 if flat else 80, color="0.5")
        for x in ident.box[key]:
            axx.axvline(x, color="C3")
        axx.set_xlabel(f"{name} per period [{'m' if name == 'x_icr' else '-'}]")
        axx.set_ylabel("periods")
        side = {"mu_r": "right track", "mu_l": "left track"}.get(name, name)
        axx.set_title(f"slip, {side} (red: the box)")
    ax = axes[1 + len(names)]
    for i, name in enumerate(names):
        if name in ("mu_r", "mu_l", "yaw"):
            ax.scatter(ident.slip.turn_rate, ident.slip.mu[:, i], s=3, label=name, alpha=0.4)
    ax.set_xlabel("commanded |omega| / |V| over the period [rad/m]")
    ax.set_ylabel("estimate [-]")
    ax.set_title("slip estimates against the turn rate")
    ax.legend(loc="best")
    return _save_png(plt, fig, path)


def validation_figure(res: dict[str, Any], waypoints: Any, path: Path) -> Path:
    """``validate``: the path with the physics robot's trajectories, and e_x, e_y, e_theta over time
    for every episode with the certified bounds as bands (grey: the turns, not certified)."""

    plt = _plt()
    v = res["validation"]
    t, E, Q, straight = res["t"], res["e"], res["q"], res["straight"]
    fig = plt.figure(figsize=(11, 8))
    gs = fig.add_gridspec(3, 2, width_ratios=[1.1, 1.0])
    ax = fig.add_subplot(gs[:, 0])
    wp = np.asarray(waypoints, dtype=float)
    ax.plot(wp[:, 0], wp[:, 1], "k--", lw=1, label="path")
    for n in range(Q.shape[0]):
        ax.plot(Q[n, :, 0], Q[n, :, 1], lw=0.8, label="episodes" if n == 0 else None)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("the robot along the path (errors: right)")
    ax.legend(loc="lower right", fontsize=8)
    names = (("e_x", 100.0, "cm"), ("e_y", 100.0, "cm"), ("e_theta", 1.0, "rad"))
    turns = ~np.all(straight, axis=0)
    for i, (nm, sc, unit) in enumerate(names):
        a = fig.add_subplot(gs[i, 1])
        for n in range(E.shape[0]):
            a.plot(t, E[n, :, i] * sc, lw=0.7)
        b = v["certified"].get(nm)
        if b is not None:
            a.axhspan(-b * sc, b * sc, color="C2", alpha=0.12, label=f"certified ±{b * sc:.3g} {unit}")
        a.fill_between(t, 0, 1, where=turns, color="0.85", transform=a.get_xaxis_transform(), label="after a waypoint or a perturbed start (not judged)")
        a.set_ylabel(f"{nm} [{unit}]")
        a.legend(loc="upper right", fontsize=7)
        if i == 2:
            a.set_xlabel("t [s]")
    fig.suptitle(f"validate: {v['episodes']} episodes, {v['engine']} — "
                 + ("passed" if v.get("passed") else "FAILED"), fontsize=11)
    return _save_png(plt, fig, path)


def lti_verification_figure(data: dict[str, Any], path: Path) -> Path:
    """A linear plant's verification: the frozen-delay spectral radius, and V along the worst run of
    each delay family against the certificate (the set's level 1, or alpha^k without a disturbance)."""
    plt = _plt()
    tr = data["traces"]
    has_v = bool(tr.get("V"))
    fig, axes = plt.subplots(1, 2 if has_v else 1, figsize=(11 if has_v else 6, 4))
    axes = np.atleast_1d(axes)
    ax = axes[0]
    ax.plot(tr["frozen"]["delay"], tr["frozen"]["spectral_radius"], color="tab:blue")
    ax.axhline(1.0, color="tab:red", lw=1, ls="--", label="instability")
    ax.set_xlabel("constant delay [s]")
    ax.set_ylabel("spectral radius of the exact loop")
    ax.set_title("Frozen delays")
    ax.legend(loc="best", fontsize=8)
    if has_v:
        ax = axes[1]
        for name, v in tr["V"].items():
            ax.plot(np.arange(len(v)), v, lw=1, label=name)
        k = np.arange(max(len(v) for v in tr["V"].values()))
        if tr.get("set"):
            ax.axhline(1.0, color="k", lw=1.5, label="certified set V = 1")
            ax.set_ylabel("V = xi' P xi (worst run per family)")
        else:
            ax.plot(k, tr["alpha"] ** k, color="k", lw=1.5, label="certified alpha^k")
            ax.set_yscale("log")
            ax.set_ylabel("V_k / V_0 (worst run per family)")
        ax.set_xlabel("period k")
        ax.set_title("From the set's boundary")
        ax.legend(loc="best", fontsize=7)
    return _save_png(plt, fig, path)
