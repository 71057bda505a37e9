"""A tracked robot in a physics engine (MuJoCo): slip that *emerges* from contact and friction.

The only module that imports MuJoCo (the ``physics`` extra).  The robot is built from the config
(``robot:`` for R, D and the motor limit, ``physics:`` for the rest): a box chassis, an optional
payload, and per track a row of spheres of radius R at y = -D/2 (right) and +D/2 (left), each on a
hinge driven by a velocity servo; every wheel of a track gets the same motor-speed command.
Contacts use the settings of a feasibility study that made skid turns steady (soft impedance near
zero penetration, ``solimp 0.5 0.95 0.01``, ``solref 0.05 1``; elliptic cone, ``implicitfast``).

:class:`PhysicsRobot` moves N independent robots through sampling periods with the same interface
as :class:`~robustsynth.plants.kinematic.KinematicRobot`: the commands in flight ``U[:, j]`` act on
``[s~_j, s~_{j-1})`` of the period (in-order delivery), as motor speeds ``J^-1 u_hat`` clipped to
``+-rho_max``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..model.kinematics import J_inverse

__all__ = ["PhysicsRobot", "mjcf", "available"]


def available() -> str:
    """'' when MuJoCo can be imported, else why not."""
    try:
        import mujoco  # noqa: F401
    except ImportError as exc:  # pragma: no cover - the extra is installed by make test
        return f"MuJoCo is not installed ({exc}): pip install 'robustsynth[physics]'"
    return ""


def mjcf(config: Any) -> str:
    """The MJCF model of the config's robot (``robot:`` and ``physics:``)."""
    R = config.robot.gear_radius
    D = config.robot.track_distance
    p = config.physics
    rho_max = config.robot.max_motor_speed or 1e3
    L, W, H = p.chassis_size
    z0 = R + p.clearance + H / 2.0  # chassis centre above ground, wheel centres at height R
    mu = p.friction
    contact = 'condim="3" solimp="0.5 0.95 0.01" solref="0.05 1"'
    torque = p.track_torque / p.wheels_per_track
    xs = np.linspace(-p.wheel_span / 2.0, p.wheel_span / 2.0, p.wheels_per_track)
    bodies, acts = [], []
    for side, y in (("r", -D / 2.0), ("l", D / 2.0)):
        for i, x in enumerate(xs):
            name = f"{side}{i}"
            bodies.append(
                f'<body name="w{name}" pos="{x:.6g} {y:.6g} {R - z0:.6g}">'
                f'<joint name="j{name}" type="hinge" axis="0 1 0" armature="{p.wheel_armature:g}" damping="0"/>'
                f'<geom type="sphere" size="{R:g}" mass="{p.wheel_mass:g}" contype="1" conaffinity="2" '
                f'friction="{mu:g} 0.005 0" {contact}/></body>')
            acts.append(f'<velocity name="a{name}" joint="j{name}" kv="{p.servo_gain:g}" forcelimited="true" '
                        f'forcerange="{-torque:g} {torque:g}" ctrllimited="true" ctrlrange="{-rho_max:g} {rho_max:g}"/>')
    payload = ""
    if p.payload_mass > 0:
        payload = (f'<geom type="box" size="0.1 0.1 0.05" pos="{p.payload_x:g} 0 {H / 2 + 0.05:g}" '
                   f'mass="{p.payload_mass:g}" contype="0" conaffinity="0"/>')
    return f"""<mujoco model="tracked">
  <option timestep="{p.timestep:g}" integrator="implicitfast" cone="elliptic"/>
  <worldbody>
    <geom name="floor" type="plane" size="500 500 0.1" contype="2" conaffinity="1" friction="{mu:g} 0.005 0" {contact}/>
    <body name="chassis" pos="0 0 {z0:.6g}">
      <freejoint/>
      <geom type="box" size="{L / 2:g} {W / 2:g} {H / 2:g}" mass="{p.chassis_mass:g}" contype="0" conaffinity="0"/>
      {payload}
      {"".join(bodies)}
    </body>
  </worldbody>
  <actuator>{"".join(acts)}</actuator>
</mujoco>"""


def _yaw(quat: np.ndarray) -> float:
    w, x, y, z = quat
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


@dataclass
class PhysicsRobot:
    """N tracked robots in MuJoCo (one model, N data), stepped period by period."""

    config: Any
    runs: int

    def __post_init__(self) -> None:
        import mujoco

        self._mj = mujoco
        self.model = mujoco.MjModel.from_xml_string(mjcf(self.config))
        self.data = [mujoco.MjData(self.model) for _ in range(self.runs)]
        self.Ts = self.config.network.sampling_time
        self.dt = self.model.opt.timestep
        self.substeps = max(1, int(round(self.Ts / self.dt)))
        self.J_inv = J_inverse(self.config.robot.gear_radius, self.config.robot.track_distance)
        self.rho_max = self.config.robot.max_motor_speed
        self.n_w = self.config.physics.wheels_per_track
        self.z0 = float(self.model.body("chassis").pos[2])

    def reset(self, q0: np.ndarray, speed: float) -> None:
        """Every robot at pose q0[n] = (x, y, theta), moving straight at ``speed`` (wheels rolling)."""
        R = self.config.robot.gear_radius
        for d, q in zip(self.data, np.asarray(q0, dtype=float)):
            self._mj.mj_resetData(self.model, d)
            d.qpos[0:3] = [q[0], q[1], self.z0]
            d.qpos[3:7] = [math.cos(q[2] / 2.0), 0.0, 0.0, math.sin(q[2] / 2.0)]
            d.qvel[0:2] = [speed * math.cos(q[2]), speed * math.sin(q[2])]
            d.qvel[6:] = speed / R
            d.ctrl[:] = speed / R
            self._mj.mj_forward(self.model, d)
        self._theta = np.asarray(q0, dtype=float)[:, 2].copy()

    def pose(self) -> np.ndarray:
        """(N, 3): x, y, yaw of each chassis; the yaw continuous since :meth:`reset` (unwrapped
        against the previous call's, so called at least once per half turn)."""
        q = np.array([[d.qpos[0], d.qpos[1], _yaw(d.qpos[3:7])] for d in self.data])
        q[:, 2] = self._theta + (q[:, 2] - self._theta + math.pi) % (2 * math.pi) - math.pi
        self._theta = q[:, 2].copy()
        return q

    def body_velocity(self) -> np.ndarray:
        """(N, 3): forward and lateral velocity in the body frame [m/s] and yaw rate [rad/s].  With the
        yaw rate omega, the instantaneous centre of rotation lies ``x_ICR = -v_lat / omega`` ahead of
        the chassis centre (the skid-steer ICR description)."""
        out = []
        for d in self.data:
            th = _yaw(d.qpos[3:7])
            vx, vy = float(d.qvel[0]), float(d.qvel[1])
            out.append([math.cos(th) * vx + math.sin(th) * vy, -math.sin(th) * vx + math.cos(th) * vy, float(d.qvel[5])])
        return np.array(out)

    def motor_torques(self) -> np.ndarray:
        """(N, 2): the summed actuator torque per track (right, left) [N m]."""
        n = self.n_w
        return np.array([[float(np.sum(d.actuator_force[:n])), float(np.sum(d.actuator_force[n:]))] for d in self.data])

    def set_friction(self, mu: float) -> None:
        """Every robot drives onto ground of sliding friction ``mu`` from now on (a patch: the ground's and the
        wheels' friction, as MuJoCo takes the larger of a contact's two)."""
        self.model.geom_friction[:, 0] = float(mu)

    def push(self, force: np.ndarray) -> None:
        """A horizontal force ``force[n] = (f_x, f_y)`` [N] in the world frame on each chassis from now on, until the
        next call (zeros: none) — a push, or a drag."""
        body = self.model.body("chassis").id
        for d, f in zip(self.data, np.broadcast_to(np.asarray(force, dtype=float), (self.runs, 2))):
            d.xfrc_applied[body, :] = 0.0
            d.xfrc_applied[body, :2] = f

    @property
    def mass(self) -> float:
        """The robot's whole mass [kg] (chassis, payload, wheels)."""
        return float(np.sum(self.model.body_mass))

    def period(self, U: np.ndarray, S: np.ndarray) -> np.ndarray:
        """One sampling period: ``U[n, j]`` (commands u_hat in flight, newest first) acts on
        ``[S[n, j], S[n, j-1])`` (S[n, -1] = Ts, the end 0); returns the largest |torque| per track
        the servos used (N, 2).  Motor speeds J^-1 u_hat clipped to +-rho_max."""
        d_hi = S.shape[1]
        rho = np.einsum("ij,njk->nki", self.J_inv, np.moveaxis(np.asarray(U, dtype=float), 1, 2))  # (N, d_hi+1, 2)
        if self.rho_max is not None:
            rho = np.clip(rho, -self.rho_max, self.rho_max)
        peak = np.zeros((self.runs, 2))
        n = self.n_w
        for i in range(self.substeps):
            tau = (i + 0.5) * self.dt
            for r, d in enumerate(self.data):
                j = next((j for j in range(d_hi) if S[r, j] <= tau), d_hi)  # the newest command in force
                d.ctrl[:n] = rho[r, j, 0]
                d.ctrl[n:] = rho[r, j, 1]
                self._mj.mj_step(self.model, d)
                f = d.actuator_force
                peak[r] = np.maximum(peak[r], [abs(float(np.sum(f[:n]))), abs(float(np.sum(f[n:])))])
        return peak
