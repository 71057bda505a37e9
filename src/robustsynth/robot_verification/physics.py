"""``robustsynth validate``: the deployed law on a physics-engine robot (MuJoCo), closing its loop
over the emulated network along the config's path (issue 25).

Nothing here is assumed about slip: it emerges from contact and friction
(:mod:`robustsynth.plants.physics`).  Each episode runs the deployed :class:`~robustsynth.law.Law`
at the sampling instants, sends its command through the network (the config's delays and losses,
in order, as in ``verify``), and the engine moves the robot through the period.  On straight
segments (after ``verification.transient`` seconds from each waypoint, and from a perturbed start)
the largest errors are compared with the certified bounds; the turns are reported beside them.
The episodes come back as robot logs (``identify``'s format); the pipeline estimates from them the
slip the engine showed and compares it with the config's box.

The robot in the engine is the config's (:func:`physics_config`): the sprocket radius is robot.gear_radius,
the tracks robot.track_distance apart, and the chassis as wide as the tracks imply unless ``physics:``
sets its size; every other ``physics:`` value is the config's or the feasibility study's default, and
the validation says which (``physics`` in validation.json: a robot with tracks 0.38 m apart had been
run silently on the default 0.5 m chassis, issue 50).
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..law import Law
from ..monitor import CAUSES
from ..plants.path import frame_error, path_of, pose_from_error

__all__ = ["validate_physics", "excite", "excitation_slip", "excitation_steps", "physics_config", "PERTURBATION",
           "CHASSIS_OVERHANG", "Injection", "INJECTIONS"]

PERTURBATION = (0.02, 0.02, 0.05)  # perturbed starts: uniform offsets up to this in e_x, e_y [m], e_theta [rad]
TORQUE_SATURATED = 0.999  # a period counts as torque-saturated when a track's peak reaches this share of the limit
# how far the chassis reaches beyond each track's centre line [m]: the study's robot, a 0.5 m wide chassis on
# tracks 0.45 m apart (the physics.chassis_size default); a config's chassis is robot.track_distance + 2 x this wide
CHASSIS_OVERHANG = 0.025


# what `validate --inject KIND` breaks, and its size when none is given (issue 54: the runtime monitor must flag it)
INJECTIONS = {
    "delay": ("the command sent at the period arrives SIZE s after tau_max", 0.07),
    "losses": ("network.dropouts.max_consecutive + SIZE commands in a row are lost from the period on", 1.0),
    "friction": ("the robot drives onto a mud patch: ground of friction SIZE (from physics.friction) that drags it back "
                 "with MUD_DRAG /s x its mass x its forward speed", 0.3),
    "patch": ("the robot drives onto ground of friction SIZE (from physics.friction) for PATCH_PERIODS periods, then "
              "back onto physics.friction; no drag (issue 55: slip that changes with the ground, which the box may "
              "or may not cover: the validation says)", 0.4),
    "push": ("a sideways push of SIZE times the robot's weight on its chassis (to its left) for one period", 3.0),
    "command": ("the command sent at the period asks a motor for SIZE times robot.max_motor_speed", 2.0),
}
MUD_DRAG = 8.0  # the mud patch's drag per unit of mass and forward speed [1/s] (more than friction 0.3 holds at V^D)
PATCH_PERIODS = 100  # how long the friction patch lasts [periods]


class Injection:
    """A violation of one assumption of the certificate, injected into every episode from period ``period`` on
    (:data:`INJECTIONS`: what each ``kind`` does, and its default ``size``): for showing the runtime monitor flag it
    on the physics robot.  The validation's verdict then speaks of a robot outside the certificate's assumptions."""

    def __init__(self, kind: str, period: int = 150, size: float | None = None, drag: float = MUD_DRAG) -> None:
        from ..errors import InputError

        if kind not in INJECTIONS:
            raise InputError(f"--inject: {kind!r} is not one of {', '.join(INJECTIONS)}")
        if period < 1:
            raise InputError(f"--inject-period: {period} must be 1 or more")
        self.kind, self.period, self.drag = kind, int(period), float(drag)  # drag: the mud's (0: friction alone)
        self.size = float(INJECTIONS[kind][1] if size is None else size)
        if not (self.size > 0.0 and math.isfinite(self.size)):
            raise InputError(f"--inject-size: {size!r} must be a positive number")

    def check(self, model: Any, engine: str) -> None:
        """InputError unless this injection can happen in ``engine``'s episodes of ``model``'s path."""
        from ..errors import InputError

        if engine != "physics" and self.kind in ("friction", "patch", "push"):
            raise InputError(f"--inject {self.kind}: only on the physics robot (--engine physics)")
        if self.period >= _steps(model):
            raise InputError(f"--inject-period: {self.period} is beyond the episode's {_steps(model)} periods")

    def describe(self) -> str:
        text = (INJECTIONS[self.kind][0].replace("SIZE", f"{self.size:g}").replace("MUD_DRAG", f"{self.drag:g}")
                .replace("PATCH_PERIODS", str(PATCH_PERIODS)))
        if self.kind == "friction" and self.drag == 0.0:
            text = f"the robot drives onto ground of friction {self.size:g} (from physics.friction), no drag"
        return f"{self.kind} from period {self.period}: {text}"

    def taus(self, model: Any, taus: np.ndarray) -> np.ndarray:
        """The episodes' packet delays (N, d_hi + steps) with a delay spike or a loss burst."""
        taus = np.array(taus, dtype=float)
        k = model.d_hi + self.period
        if self.kind == "delay":
            taus[:, k] = model.config.network.delay.max + self.size
        elif self.kind == "losses":
            n = model.config.network.dropouts.max_consecutive + int(math.ceil(self.size))
            taus[:, k:k + n] = np.inf
        return taus

    def command(self, model: Any, u: np.ndarray, k: int) -> np.ndarray:
        """The commands (N, 2) sent at period k: beyond the motor limit at the injection's period."""
        if self.kind != "command" or k != self.period:
            return u
        R, D = model.config.robot.gear_radius, model.config.robot.track_distance
        rho = self.size * (model.config.robot.max_motor_speed or 1e3)
        V = u[:, :1]
        return np.concatenate([V, (rho - V / R) * 2.0 * R / D], axis=1)  # the right track at rho

    def forces(self, robot: Any, q: np.ndarray, k: int, ground: float = 1.0) -> None:
        """The ground and the forces on the physics robot for period k (poses ``q``, (N, 3)); ``ground``: the friction
        it drives on outside a patch (physics.friction)."""
        if self.kind == "patch" and k in (self.period, self.period + PATCH_PERIODS):
            robot.set_friction(self.size if k == self.period else ground)
        elif self.kind == "friction" and k >= self.period:
            if k == self.period:
                robot.set_friction(self.size)
            v = robot.body_velocity()[:, 0]  # forward speed at the period's start (the drag held over the period)
            robot.push((-self.drag * robot.mass * v)[:, None] * np.stack([np.cos(q[:, 2]), np.sin(q[:, 2])], axis=1))
        elif self.kind == "push" and k in (self.period, self.period + 1):
            f = self.size * robot.mass * 9.81 if k == self.period else 0.0
            robot.push(f * np.stack([-np.sin(q[:, 2]), np.cos(q[:, 2])], axis=1))


def physics_config(config: Any) -> tuple[Any, dict[str, Any]]:
    """The config whose ``physics:`` the engine's robot is built from, and the record of what it used.

    What the robot section implies is derived: the wheels' radius is robot.gear_radius (the sprocket), the
    tracks lie robot.track_distance apart and the chassis is robot.track_distance + 2 CHASSIS_OVERHANG wide
    (length and height the defaults) unless ``physics.chassis_size`` is set; a value the config sets is kept.
    The record (validation.json's ``physics``): every parameter's value, where it came from ("config",
    "default" or the robot key it follows) and a one-line ``summary``."""
    from ..config import PhysicsConfig

    p = config.physics
    given = set(p.model_fields_set)
    R, D, rho = config.robot.gear_radius, config.robot.track_distance, config.robot.max_motor_speed
    source = {k: ("config" if k in given else "default") for k in PhysicsConfig.model_fields}
    size = [float(v) for v in p.chassis_size]
    if "chassis_size" not in given:
        size[1] = round(float(D) + 2.0 * CHASSIS_OVERHANG, 12)
        source["chassis_size"] = (f"width from robot.track_distance: {float(D):g} m + 2 x {CHASSIS_OVERHANG:g} m; "
                                  "length, height: default")
        config = config.model_copy(update={"physics": p.model_copy(update={"chassis_size": size})})
    p = config.physics
    params = {k: (list(v) if isinstance(v, (list, tuple)) else v) for k, v in p.model_dump(mode="json").items()}
    params.update(sprocket_radius=float(R), track_spacing=float(D), max_motor_speed=rho)
    source.update(sprocket_radius="robot.gear_radius", track_spacing="robot.track_distance",
                  max_motor_speed="robot.max_motor_speed")

    def said(key: str, text: str) -> str:
        src = source[key]
        return f"{text} ({'physics: in the config' if src == 'config' else src})"

    L, W, H = size
    summary = ", ".join([
        said("chassis_mass", f"chassis {p.chassis_mass:g} kg"),
        said("chassis_size", f"{L:g} x {W:g} x {H:g} m"),
        said("track_spacing", f"tracks {D:g} m apart"),
        said("sprocket_radius", f"sprocket radius {R:g} m"),
        said("wheels_per_track", f"{p.wheels_per_track} wheels per track") + " " + said("wheel_span", f"over {p.wheel_span:g} m"),
        said("friction", f"friction {p.friction:g}"),
        said("track_torque", f"{p.track_torque:g} N m per track"),
        said("payload_mass", f"payload {p.payload_mass:g} kg {p.payload_x:+g} m ahead" if p.payload_mass else "no payload"),
        said("timestep", f"time step {p.timestep:g} s"),
    ])
    record = {"parameters": params, "source": source, "summary": summary,
              "derived": [k for k, v in source.items() if v not in ("config", "default")]}
    return config, record


class _KinematicEngine:
    """The kinematic robot (exact arcs, the config's slip model) behind the physics robot's interface,
    for ``validate --engine kinematic``: each episode has one slip drawn uniformly from the config's box."""

    def __init__(self, model: Any, mu: np.ndarray) -> None:
        """``mu`` (N, n_p): one slip per episode; (N, steps, n_p): one per period."""
        from ..plants.kinematic import KinematicRobot

        self.robot = KinematicRobot.of(model)
        self.mu = np.asarray(mu, dtype=float)
        self.k = 0
        self.q = np.zeros((self.mu.shape[0], 3))

    def reset(self, q0: np.ndarray, speed: float) -> None:
        self.q = np.array(q0, dtype=float)

    def pose(self) -> np.ndarray:
        return self.q.copy()

    def period(self, U: np.ndarray, S: np.ndarray) -> np.ndarray:
        mu = self.mu if self.mu.ndim == 2 else self.mu[:, self.k]
        self.q = self.robot.period(self.q, U, S, mu)
        self.k += 1
        return np.zeros((self.q.shape[0], 2))  # no torques in this model


ENGINES = ("physics", "kinematic")


def _run_episodes(model: Any, gains: dict[str, Any], first: int, count: int, seed: int,
                  progress: Callable[[int, int], None] | None = None, engine: str = "physics",
                  inject: Injection | None = None) -> dict[str, np.ndarray]:
    """Episodes ``first .. first + count - 1`` in one process: each has its own random stream
    (``seed``, index), so the results do not depend on how episodes are split over workers.
    Episode 0 starts on the path; the others from offsets up to PERTURBATION."""
    from ..plants.physics import PhysicsRobot
    from ..scenarios import random_delays

    cfg = model.config
    K = np.asarray(gains["K"], dtype=float)
    V, Ts, d_hi = model.V, model.Ts, model.d_hi
    path = path_of(cfg)
    steps = _steps(model)
    N = count
    plant = model  # the robot driven: for a compensated law its true slip box, not the certificate's ratio box
    if model.compensation is not None:
        from .compensated import true_robot

        plant = true_robot(model.user_config)
    offsets = np.zeros((N, 3))
    taus, mus = [], []
    for i in range(N):
        rng = np.random.default_rng([seed, first + i])
        if first + i > 0:
            offsets[i] = rng.uniform(-1.0, 1.0, 3) * np.array(PERTURBATION)
        taus.append(random_delays(model, rng, 1, steps)[0])
        mus.append([rng.uniform(lo, hi) for lo, hi in plant.slip_ranges])  # every slip parameter (icr: 4)
    taus = np.array(taus)  # (N, d_hi + steps): the d_hi packets before t_0 first
    if inject is not None:
        taus = inject.taus(model, taus)
    q0 = pose_from_error(path, offsets)
    robot = PhysicsRobot(physics_config(cfg)[0], N) if engine == "physics" else _KinematicEngine(plant, np.array(mus))
    loop = _estimator_loop(model, gains, taus, steps)
    robot.reset(q0, V)
    S = model.s_tilde(taus)  # (N, steps, d_hi)
    law = Law(K.tolist(), Ts, bool(model.n_z), path.table)
    law.reset(past=[np.zeros(N) for _ in range(2 * d_hi)], z=[np.zeros(N) for _ in range(model.n_z)])
    uD = np.array([V, 0.0])
    U = np.tile(uD, (N, d_hi + 1, 1))
    J_inv = np.asarray(model.J_inv)
    limit = cfg.physics.track_torque
    E = np.zeros((N, steps, 3))
    Q = np.zeros((N, steps, 3))
    RHO = np.zeros((N, steps, 2))
    sat = np.zeros((N, steps), dtype=bool)
    XI = np.zeros((N, steps, model.n_s))
    for k in range(steps):
        t = k * Ts
        q = robot.pose()
        Q[:, k] = q
        seg = path.segment(t)
        E[:, k] = frame_error(path, seg, q, t)
        dv, dw = law.correction(t, q[:, 0], q[:, 1], q[:, 2])
        u = uD + np.stack([np.asarray(dv, dtype=float) * np.ones(N), np.asarray(dw, dtype=float) * np.ones(N)], axis=1)
        u = u + law.feedforward(t) * model.turn_feedforward  # the turning feedforward, as the simulator sends it
        if loop is not None:  # the slip-compensated law: the monitor's estimate divides each track's command
            XI[:, k] = np.stack(law.xi, axis=1)
            u = loop.command(k, t, q, XI[:, k], u)
        if inject is not None:
            u = inject.command(model, u, k)
            inject.forces(robot, q, k, cfg.physics.friction)
        # J^-1 u row by row (not a matmul, whose summation order may depend on how many episodes a worker has)
        RHO[:, k] = u[:, :1] * J_inv[:, 0] + u[:, 1:] * J_inv[:, 1]
        U = np.concatenate([u[:, None], U[:, :-1]], axis=1)
        peak = robot.period(U, S[:, k])
        sat[:, k] = np.any(peak >= TORQUE_SATURATED * limit, axis=1)
        if progress is not None:
            progress(k + 1, steps)
    out = {"offsets": offsets, "taus": taus, "E": E, "Q": Q, "RHO": RHO, "sat": sat}
    if loop is not None:
        out.update(XI=XI, holds=loop.holds, mu_hat=loop.mu_hat, margin=loop.margin, status=loop.status)
    return out


def _compensated_samples(model: Any, gains: dict[str, Any], comp: dict[str, np.ndarray], straight: np.ndarray
                         ) -> tuple[np.ndarray, dict[str, Any]]:
    """The samples a compensated law's certificate speaks of (docs/theory.md §18), as ``verify`` judges them: sample
    k + 1 where the state at t_k was in the set and the condition held for the commands of periods k - d_hi .. k
    (the turns included: the certificate covers them).  Returns that mask (N, steps) and the record: how often the
    condition held, the median estimate, the samples judged, those that left the set and the episodes that did not
    end in the set under the condition (the set attracts: one that does not come back fails, as in verify)."""
    from ..certificate import lyapunov_of
    from .compensated import covered_steps

    level = (gains.get("certificate") or {}).get("ellipsoid_level")
    holds = comp["holds"]
    v = lyapunov_of(model, gains["certificate"]).V_max(comp["XI"]) / float(level)  # the largest over its matrices
    covered = covered_steps(holds, model.d_hi)
    judged = np.zeros_like(straight)
    judged[:, 1:] = covered[:, :-1] & (v[:, :-1] <= 1.0)
    mu = comp["mu_hat"][holds]
    rec = {"condition_held_share": float(holds.mean()), "samples_judged": int(judged.sum()),
           "samples_judged_outside_the_set": int(np.sum(judged & (v > 1.0 + 1e-9))),
           # an episode that leaves its set (or the condition) must come back: judged and inside at its end
           "episodes_not_back_at_the_end": int(np.sum(~(judged[:, -1] & (v[:, -1] <= 1.0)))),
           "max_V_over_level_judged": float(np.max(np.where(judged, v, 0.0))),
           "max_V_over_level_all": float(np.max(v)),
           "estimate_median": [float(np.median(mu[:, 0])), float(np.median(mu[:, 1]))] if mu.size else None,
           "estimate_range": [[float(mu[:, i].min()), float(mu[:, i].max())] for i in range(2)] if mu.size else None,
           "monitor_alarm_periods": {name: int(np.sum((comp["status"] & bit) != 0)) for name, bit in CAUSES}}
    return judged, rec


def _estimator_loop(model: Any, gains: dict[str, Any], taus: np.ndarray, steps: int) -> Any:
    """For a slip-compensated law (docs/theory.md §18), the per-episode monitors and compensators of the deployed
    controller (:class:`~robustsynth.robot_verification.simulate.EstimatorLoop`); None otherwise."""
    if model.compensation is None:
        return None
    from ..artifacts.gains import controller_description
    from .simulate import EstimatorLoop, applied_times

    return EstimatorLoop(controller_description(gains, model.user_config), applied_times(model, taus, steps))


def _steps(model: Any) -> int:
    """Sampling instants along the config's path (its duration at V^D, rounded up)."""
    return int(math.ceil(path_of(model.config).duration / model.Ts))


def _chunk(args: tuple) -> dict[str, np.ndarray]:
    model, gains, first, count, seed, engine, inject = args
    return _run_episodes(model, gains, first, count, seed, None, engine, inject)


def validate_physics(model: Any, gains: dict[str, Any], episodes: int = 4, seed: int = 0,
                     progress: Callable[[int, int], None] | None = None, workers: int = 1,
                     engine: str = "physics", inject: Injection | None = None) -> dict[str, Any]:
    """Run ``episodes`` closed-loop episodes on the physics robot (``workers`` processes: the
    episodes split between them, the same results); returns the validation mapping (per episode and
    overall maxima against the certified figures, the verdict) and the logs.  ``inject``: a violation of one of
    the certificate's assumptions in every episode (:class:`Injection`; the validation records it)."""
    from ..artifacts.logs import RobotLog

    cfg = model.config
    Ts, d_hi = model.Ts, model.d_hi
    path = path_of(cfg)
    steps = _steps(model)
    N = episodes
    workers = max(1, min(int(workers), N))
    if engine not in ENGINES:
        from ..errors import InputError

        raise InputError(f"--engine: {engine!r} is not one of {', '.join(ENGINES)}")
    if inject is not None:
        inject.check(model, engine)
    if workers == 1:
        parts = [_run_episodes(model, gains, 0, N, seed, progress, engine, inject)]
    else:
        from concurrent.futures import ProcessPoolExecutor

        bounds = np.linspace(0, N, workers + 1).astype(int)
        jobs = [(model, gains, int(a), int(b - a), seed, engine, inject) for a, b in zip(bounds[:-1], bounds[1:])]
        with ProcessPoolExecutor(max_workers=workers) as pool:
            parts = list(pool.map(_chunk, jobs))
    offsets, taus, E, Q, RHO, sat = (np.concatenate([p[k] for p in parts]) for k in ("offsets", "taus", "E", "Q", "RHO", "sat"))
    comp = None if model.compensation is None else {
        k: np.concatenate([p[k] for p in parts]) for k in ("XI", "holds", "mu_hat", "margin", "status")}
    rho_max = cfg.robot.max_motor_speed
    # straight segments: from `transient` after each waypoint (and after a perturbed start) on
    tk = np.arange(steps) * Ts
    straight = np.ones((N, steps), dtype=bool)
    tr = cfg.verification.transient
    for ts in path.table.t_start[1:]:
        straight[:, (tk >= ts) & (tk < ts + tr)] = False
    cert = gains.get("certified") or {}
    # a certificate that covers the path's turns (model/arcs.py) claims its bounds for all t through them: every
    # instant is judged, against the bounds for all t (the sampled ones where it states none)
    through_turns = bool(path.turning and cert.get("turns"))
    if path.turning and not through_turns:  # straight where no command in flight carries a turning feedforward
        w = np.array([path.feedforward(t) for t in tk])
        turning = np.convolve(w != 0.0, np.ones(d_hi + 2), mode="full")[:steps] > 0
        straight[:, turning] = False
    straight[1:, tk < tr] = False
    comp_rec = None
    if comp is not None:  # the compensated law's claims: the samples in the set under the condition (theory §18)
        straight, comp_rec = _compensated_samples(model, gains, comp, straight)
    ub = dict(cert.get("ultimate_bound") or {})
    if through_turns:
        for k, v in (cert.get("ultimate_bound_between_samples") or {}).items():
            if v is not None and k in ub:
                ub[k] = max(float(ub[k]), float(v))
    names = ("e_x", "e_y", "e_theta")
    per_episode = []
    for n in range(N):
        m = straight[n]
        ep = {"start_offset": offsets[n].tolist(),
              "straight_max": {nm: float(np.max(np.abs(E[n, m, i]), initial=0.0)) for i, nm in enumerate(names)},
              "turn_max": {nm: float(np.max(np.abs(E[n, ~m, i]), initial=0.0)) for i, nm in enumerate(names)},
              "max_motor_speed_commanded": float(np.max(np.abs(RHO[n]))),
              "torque_saturated_s": float(np.sum(sat[n]) * Ts)}
        ep["passed"] = all(ep["straight_max"][nm] <= ub[nm] for nm in names if nm in ub)
        per_episode.append(ep)
    overall = {nm: max(ep["straight_max"][nm] for ep in per_episode) for nm in names}
    turns = {nm: max(ep["turn_max"][nm] for ep in per_episode) for nm in names}
    out = {
        "engine": "physics (MuJoCo)" if engine == "physics" else "kinematic (exact arcs, one slip per episode from the box)", "episodes": N, "seed": seed, "steps": steps, "duration_s": steps * Ts,
        # the physics robot's parameters and where each came from (the kinematic engine has none)
        "physics": physics_config(cfg)[1] if engine == "physics" else None,
        "straight_rule": (f"every instant, through the turns the certificate covers (after a perturbed start from {tr:g} s on), "
                          "against the bounds for all t" if through_turns else
                          "between the arcs, where no command in flight turns (and after a perturbed start, from "
                          f"{tr:g} s on)" if path.turning else
                          f"from {tr:g} s after each waypoint (and after a perturbed start) on"),
        "through_turns": through_turns,
        "certified": {nm: ub.get(nm) for nm in names},
        "straight_max": overall,
        "ratio_to_certified": {nm: (overall[nm] / ub[nm] if ub.get(nm) else None) for nm in names},
        "turn_max": turns,
        "max_motor_speed_commanded": max(ep["max_motor_speed_commanded"] for ep in per_episode),
        "max_motor_speed": rho_max,
        "torque_saturated_s": max(ep["torque_saturated_s"] for ep in per_episode),
        "per_episode": per_episode,
        "injected": None if inject is None else inject.describe(),
        "compensated": comp_rec,
    }
    logs = []
    for n in range(N):
        # the instant each command was delivered: t_k + tau_k (lost: NaN)
        tau = taus[n, d_hi : d_hi + steps]
        applied = np.where(np.isfinite(tau), tk + tau, np.nan)
        est = None if comp is None else np.concatenate([comp["mu_hat"][n], comp["holds"][n][:, None].astype(float)], axis=1)
        logs.append(RobotLog(f"episode_{n:03d}.csv", tk.copy(), Q[n, :, 0], Q[n, :, 1], Q[n, :, 2],
                             np.arange(steps, dtype=float), RHO[n, :, 0], RHO[n, :, 1], tk.copy(), applied, est))
    out["passed"] = bool(all(ep["passed"] for ep in per_episode))
    if comp_rec is not None:  # and the set kept wherever the compensated law's condition held, in some samples at least
        out["passed"] = (out["passed"] and comp_rec["samples_judged_outside_the_set"] == 0
                         and comp_rec["episodes_not_back_at_the_end"] == 0)
    # the runtime monitor over the episodes (recorded, not in the verdict): an alarm inside the certificate's
    # assumptions is its false alarm, or slip the box does not hold
    from ..runtime.replay import monitor_summary

    out["monitor"] = monitor_summary(logs, gains, model.user_config)
    return {"validation": out, "logs": logs, "straight": straight, "t": tk, "e": E, "q": Q}


EXCITATION_TURNS = (0.0, 0.25, -0.25, 0.5, -0.5, 1.0, -1.0, 2.0, -2.0)  # omega / V [rad/m] of the excitation's stretches
EXCITATION_SPEEDS = (0.6, 1.0, 1.4)  # forward speed of a stretch / V^D
EXCITATION_HOLD = 3.0  # seconds per stretch


def excite(model: Any, episodes: int = 4, seed: int = 0, engine: str = "physics") -> list:
    """Open-loop excitation of the robot for ``identify``: each episode drives stretches of
    EXCITATION_HOLD seconds at every turn rate of EXCITATION_TURNS and speed of EXCITATION_SPEEDS
    (shuffled per episode), the commands sent through the emulated network (the config's delays and
    losses).  Commands beyond the motor limit are scaled down to it.  Returns the episodes as robot
    logs, the poses with the config's ``verification.noise``.

    ``engine='kinematic'``: the model's own robot (exact arcs, the config's slip model), its slip
    following the simulator's profiles per period (constant, random walk, steps, corners, cycled over
    the episodes): logs with a known truth.  :func:`excitation_slip` gives that slip."""
    from ..artifacts.logs import RobotLog
    from ..errors import InputError
    from ..scenarios import random_delays

    if engine not in ENGINES:
        raise InputError(f"--engine: {engine!r} is not one of {', '.join(ENGINES)}")

    cfg = model.config
    V, Ts, d_hi = model.V, model.Ts, model.d_hi
    rng = np.random.default_rng(seed)
    J_inv = np.asarray(model.J_inv)
    rho_max = cfg.robot.max_motor_speed
    combos = [(s * V, s * V * w) for w in EXCITATION_TURNS for s in EXCITATION_SPEEDS]
    hold = max(1, int(round(EXCITATION_HOLD / Ts)))
    steps = hold * len(combos)
    cmd = np.zeros((episodes, steps, 2))
    for n in range(episodes):
        for i, c in enumerate(rng.permutation(len(combos))):
            cmd[n, i * hold : (i + 1) * hold] = combos[c]
    if rho_max is not None:  # scale a command down to the motor limit
        peak = np.max(np.abs(cmd @ J_inv.T), axis=-1, keepdims=True)
        cmd = cmd * np.minimum(1.0, rho_max / np.maximum(peak, 1e-12))
    if engine == "physics":
        from ..plants.physics import PhysicsRobot

        robot = PhysicsRobot(physics_config(cfg)[0], episodes)
    else:
        robot = _KinematicEngine(model, excitation_slip(model, episodes, steps, seed))
    robot.reset(np.zeros((episodes, 3)), V)
    taus = random_delays(model, rng, episodes, steps)
    S = model.s_tilde(taus)
    U = np.tile(np.array([V, 0.0]), (episodes, d_hi + 1, 1))
    Q = np.zeros((episodes, steps, 3))
    for k in range(steps):
        Q[:, k] = robot.pose()
        U = np.concatenate([cmd[:, k][:, None], U[:, :-1]], axis=1)
        robot.period(U, S[:, k])
    tk = np.arange(steps) * Ts
    rho = cmd @ J_inv.T
    nz = cfg.verification.noise
    Q = Q + rng.normal(size=Q.shape) * np.array([nz.position, nz.position, nz.heading])
    logs = []
    for n in range(episodes):
        tau = taus[n, d_hi : d_hi + steps]
        logs.append(RobotLog(f"excite_{n:03d}.csv", tk.copy(), Q[n, :, 0], Q[n, :, 1], Q[n, :, 2],
                             np.arange(steps, dtype=float), rho[n, :, 0], rho[n, :, 1], tk.copy(),
                             np.where(np.isfinite(tau), tk + tau, np.nan)))
    return logs


def excitation_steps(model: Any) -> int:
    """Sampling periods of one excitation episode."""
    return max(1, int(round(EXCITATION_HOLD / model.Ts))) * len(EXCITATION_TURNS) * len(EXCITATION_SPEEDS)


def excitation_slip(model: Any, episodes: int, steps: int, seed: int) -> np.ndarray:
    """The kinematic excitation's slip (episodes, steps, n_p): the simulator's profiles in the config's box."""
    from ..scenarios import SLIP_PROFILES, slip_profiles

    lo = np.array([r[0] for r in model.slip_ranges])
    hi = np.array([r[1] for r in model.slip_ranges])
    kinds = [SLIP_PROFILES[n % len(SLIP_PROFILES)] for n in range(episodes)]
    return slip_profiles(np.random.default_rng([seed, 1]), kinds, steps, lo, hi, model.Ts, model.config.slip.max_rate)
