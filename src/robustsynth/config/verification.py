"""How the tracked robot's design is judged after synthesis: the ``verification:`` section (Monte Carlo, lifted
model, adversary, the simulated lossy channel), ``physics:`` (the MuJoCo robot of ``validate``) and ``monitor:``
(the runtime monitor beside the deployed law)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field

from ._base import _Node


class InitialOffset(_Node):
    """Offset added to the steady state of each run's initial slip (zero: start inside the certified set)."""

    x: Annotated[float, Field(ge=-100, le=100)] = Field(default=0.0, description="initial e_x [m]")
    y: Annotated[float, Field(ge=-100, le=100)] = Field(default=0.0, description="initial e_y [m]")
    theta: Annotated[float, Field(ge=-math.pi, le=math.pi)] = Field(default=0.0, description="initial e_theta [rad]")


class NoiseConfig(_Node):
    position: Annotated[float, Field(ge=0, le=10)] = Field(default=0.0, description="std of position measurement noise [m]")
    heading: Annotated[float, Field(ge=0, le=math.pi)] = Field(default=0.0, description="std of heading measurement noise [rad]")


class LossChannel(_Node):
    """Gilbert-Elliott (bursty) loss channel of the simulator: a good state that delivers and a bad
    state that loses; stationary loss probability and mean burst length set its two transition
    probabilities."""

    probability: Annotated[float, Field(ge=0, lt=1)] = Field(
        default=0.2, description="long-run fraction of commands lost (used only when network.dropouts.max_consecutive > 0)"
    )
    mean_burst: Annotated[float, Field(ge=1, le=1e4)] = Field(default=2.0, description="mean length of a loss burst [packets]")
    exceed_cap: bool = Field(
        default=False,
        description="also run bursts longer than network.dropouts.max_consecutive (outside the model): reported "
        "apart, not part of the verdict",
    )


class VerificationConfig(_Node):
    runs: Annotated[int, Field(ge=1, le=100_000)] = Field(default=200, description="Monte Carlo runs")
    seed: Annotated[int, Field(ge=0, le=2**32 - 1)] = Field(default=0, description="random seed")
    initial_offset: InitialOffset = Field(default_factory=InitialOffset, description="initial pose error")
    noise: NoiseConfig = Field(default_factory=NoiseConfig, description="measurement noise")
    transient: Annotated[float, Field(ge=0, le=1e4)] = Field(
        default=5.0,
        description="for a gain without a certificate: time excluded from the maxima after a waypoint (and after an "
        "initial offset) [s]; with a certificate the exclusion ends when the robot re-enters the certified set",
    )
    frozen_grid: Annotated[int, Field(ge=2, le=100_000)] = Field(
        default=201, description="delay grid points per uncertain instant for the frozen-delay check"
    )
    lifted_runs: Annotated[int, Field(ge=1, le=100_000)] = Field(
        default=200, description="runs of the lifted linear model per delay pattern"
    )
    lifted_steps: Annotated[int, Field(ge=1, le=100_000)] = Field(
        default=200, description="steps of each lifted-model run"
    )
    motor_saturation: bool = Field(
        default=True,
        description="clip the motor speeds to +-robot.max_motor_speed at the actuator, as real motors do "
        "(false: an ideal actuator, for comparison only)",
    )
    nonlinear_slack: Annotated[float, Field(ge=1, le=1)] = Field(
        default=1.0,
        description="fixed at 1: the nonlinear robot is judged against the certified bounds themselves "
        "(a relaxed verdict would not be a certificate; kept so that old configs still read)",
    )
    adversarial_runs: Annotated[int, Field(ge=0, le=10_000)] = Field(
        default=20, description="width of the adversarial slip/delay search on the nonlinear robot: the histories it "
        "keeps each period for each of its objectives (V, |e_x|, |e_y|, |e_theta|, |rho|); 0: skip"
    )
    adversarial_steps: Annotated[int, Field(ge=1, le=100_000)] = Field(
        default=300, description="periods of the adversarial search (a straight segment)"
    )
    dropouts: LossChannel = Field(default_factory=LossChannel, description="the simulated lossy channel")


class PhysicsConfig(_Node):
    """The physics-engine robot of ``robustsynth validate`` (MuJoCo; R, D and the motor limit come from
    ``robot:``).  The defaults reproduce the feasibility study's robot (shared docs/physics.md)."""

    chassis_mass: Annotated[float, Field(gt=0, le=1e4)] = Field(default=20.0, description="chassis mass [kg]")
    chassis_size: Annotated[list[Annotated[float, Field(gt=0, le=100)]], Field(min_length=3, max_length=3)] = Field(
        default=[0.6, 0.5, 0.15], description="chassis box length, width, height [m]")
    clearance: Annotated[float, Field(ge=0, le=10)] = Field(
        default=0.065, description="gap between the chassis' bottom and the ground [m]")
    payload_mass: Annotated[float, Field(ge=0, le=1e4)] = Field(default=0.0, description="payload mass [kg] (0: none)")
    payload_x: Annotated[float, Field(ge=-10, le=10)] = Field(
        default=0.0, description="payload position ahead of the chassis centre [m]")
    friction: Annotated[float, Field(gt=0, le=10)] = Field(default=1.0, description="ground sliding friction [-]")
    wheels_per_track: Annotated[int, Field(ge=2, le=40)] = Field(default=6, description="contact wheels per track")
    wheel_span: Annotated[float, Field(gt=0, le=100)] = Field(
        default=0.5, description="distance between a track's first and last contact wheel [m]")
    wheel_mass: Annotated[float, Field(gt=0, le=1e3)] = Field(default=0.2, description="mass of one contact wheel [kg]")
    wheel_armature: Annotated[float, Field(ge=0, le=100)] = Field(default=0.02, description="rotor inertia per wheel [kg m^2]")
    track_torque: Annotated[float, Field(gt=0, le=1e5)] = Field(default=20.0, description="torque limit per track [N m]")
    servo_gain: Annotated[float, Field(gt=0, le=1e5)] = Field(
        default=10.0, description="velocity servo gain per wheel [N m s/rad]")
    timestep: Annotated[float, Field(gt=0, le=0.01)] = Field(default=0.002, description="physics time step [s]")


class MonitorConfig(_Node):
    """The runtime monitor beside the deployed law (``robustsynth.monitor``, docs/theory.md §16): its fallback and
    what it tolerates.  The pose noise it allows for is ``verification.noise`` times ``noise_sigmas``."""

    fallback: Literal["stop", "hold", "slow"] = Field(
        default="stop", description="what the controller sends once the monitor's alarms persist: stop (0, 0), hold "
        "(the last command before the alarms), slow (the law's command times slow_factor); engaged until reset")
    persistence: Annotated[int, Field(ge=1, le=1000)] = Field(
        default=2, description="periods in a row with an alarm before the fallback engages")
    slow_factor: Annotated[float, Field(gt=0, le=1)] = Field(
        default=0.5, description="fallback slow: the fraction of the law's command sent")
    window: Annotated[int, Field(ge=1, le=1000)] = Field(
        default=10, description="periods of pose increments the slip check sums (more: less noise, slower to see)")
    noise_sigmas: Annotated[float, Field(ge=0, le=100)] = Field(
        default=6.0, description="the pose noise bound the thresholds carry, in standard deviations of verification.noise")
    clock_tol: Annotated[float, Field(ge=0, le=1)] = Field(
        default=1e-3, description="timestamps' tolerance [s]: a delay within it of [tau_min, tau_max] is admissible")
    model_tol: Annotated[float, Field(ge=0, le=1)] = Field(
        default=0.02, description="the slip check's relative allowance for what its body-frame increments leave "
        "out (the commands' order within a period, the arcs' curvature)")
