"""YAML configuration -> validated, frozen :class:`Config` (pydantic v2, ``extra="forbid"``).

All quantities are SI: m, s, rad, rad/s.  Every error is raised as :class:`ConfigError` whose
message is one line beginning with the key path (``network.delay.max: ...``) or, for problems
with the file itself, with the file name.
"""

from __future__ import annotations

import math
import re
from importlib import resources
import json
from pathlib import Path
from collections.abc import Mapping
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .errors import ConfigError

__all__ = [
    "Config",
    "RobotConfig",
    "ReferenceConfig",
    "NetworkConfig",
    "SlipConfig",
    "SynthesisConfig",
    "VerificationConfig",
    "MAX_CONFIG_BYTES",
    "load_config",
    "parse_config",
    "default_config_text",
    "default_config",
    "config_schema",
    "config_with",
    "check_config_key",
]

MAX_CONFIG_BYTES = 1 << 20  # 1 MiB

_MODEL = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

Pos = Annotated[float, Field(gt=0)]
NonNeg = Annotated[float, Field(ge=0)]
RESERVED_NAMES = {"baselines": "regression baselines", "sweeps": "sweep tables"}  # results/<name>/ of a run
MAX_D_HI = 20  # longest delay, in sampling periods (the lifted state grows with it)
MAX_MOTION_PER_PERIOD = 2.0  # [m]: reference.speed * sampling_time above this is named a likely unit mistake
# [m]: a robot.gear_radius at or above MAX_GEAR_RADIUS, a robot.track_distance above MAX_TRACK_DISTANCE is no
# tracked robot's (a main battle tank's sprocket is ~0.35 m, its gauge ~3 m): named a likely unit mistake
MAX_GEAR_RADIUS = 1.0
MAX_TRACK_DISTANCE = 10.0
# what a unit hint may suggest instead: lengths [m] and a ratio track_distance / gear_radius of real robots
_TYPICAL_LENGTH = {"gear_radius": (0.005, 0.5), "track_distance": (0.05, 5.0)}
_TYPICAL_RATIO = (1.5, 30.0)
# old key path -> its place now: still read there (a file, an override), never written
RENAMED_KEYS = {"verification.path": "reference.path"}
# Tokens in validator messages: _SIBLING is replaced by the sibling key's full path; a message
# starting with _FIELD "name: ..." (from a model validator) is reported at that field's path.
_SIBLING = "@sibling:"
_FIELD = "@field:"


def _range_check(lo: float | None, hi: float, lo_name: str = "min") -> None:
    if lo is not None and hi < lo:
        raise ValueError(f"must be >= {_SIBLING}{lo_name} (got {hi:g} < {lo:g})")


class _Node(BaseModel):
    model_config = _MODEL


def _length(v: Any) -> float | None:
    """A length as given (a finite positive number), else None (its field's validation names the problem)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    x = float(v)
    return x if math.isfinite(x) and x > 0 else None


def _implausible_length(key: str, v: float) -> bool:
    return v >= MAX_GEAR_RADIUS if key == "gear_radius" else v > MAX_TRACK_DISTANCE


def _length_unit_hint(key: str, lengths: dict[str, float]) -> str:
    """'; lengths are in metres: 7 looks like centimetres, did you mean 0.07 m?' for the implausible length
    ``key``: centimetres (/100) or else millimetres (/1000), whichever gives a typical tracked robot with the
    other length (scaled alike when it is implausible too: the same mistake); '' when neither does."""
    value = lengths[key]
    for k, unit in ((100.0, "centimetres"), (1000.0, "millimetres")):
        scaled = {n: v / k if n == key or _implausible_length(n, v) else v for n, v in lengths.items()}
        typical = all(_TYPICAL_LENGTH[n][0] <= scaled[n] <= _TYPICAL_LENGTH[n][1]
                      for n, v in lengths.items() if scaled[n] != v)
        if typical and len(scaled) == 2:
            typical = _TYPICAL_RATIO[0] <= scaled["track_distance"] / scaled["gear_radius"] <= _TYPICAL_RATIO[1]
        if typical:
            return f": {value:g} looks like {unit}, did you mean {value / k:g} m?"
    return ""


class RobotConfig(_Node):
    gear_radius: Annotated[float, Field(gt=0, lt=MAX_GEAR_RADIUS)] = Field(
        description="R: radius of the gears driving the tracks [m] (below 1 m: more is refused as a likely unit mistake)")
    track_distance: Annotated[float, Field(gt=0, le=MAX_TRACK_DISTANCE)] = Field(
        description="D: distance between the tracks [m] (at most 10 m: more is refused as a likely unit mistake)")
    max_motor_speed: Annotated[float, Field(gt=0, le=1e6)] | None = Field(
        default=None, description="rho_max: limit on |rho_r|, |rho_l| [rad/s]; null for none"
    )

    @model_validator(mode="before")
    @classmethod
    def _plausible_lengths(cls, data: Any) -> Any:
        """Lengths no tracked robot has (centimetres or millimetres written as metres: gear_radius 7): named
        with the likely unit, as times in milliseconds are (NetworkConfig._lifting_size, Config._plausible_motion)."""
        if not isinstance(data, Mapping):
            return data
        lengths = {k: x for k in ("gear_radius", "track_distance") if (x := _length(data.get(k))) is not None}
        for key, what, bound in (("gear_radius", "sprocket radius", f"below {MAX_GEAR_RADIUS:g} m"),
                                 ("track_distance", "distance between the tracks", f"at most {MAX_TRACK_DISTANCE:g} m")):
            if key in lengths and _implausible_length(key, lengths[key]):
                raise ValueError(f"{_FIELD}{key}: {lengths[key]:g} m is not a plausible {what} ({bound} for a tracked "
                                 f"robot; lengths are in metres{_length_unit_hint(key, lengths)})")
        return data


Coord = Annotated[float, Field(ge=-1e6, le=1e6)]
Waypoint = Annotated[tuple[Coord, Coord], Field(description="(x, y) [m]")]

_DEFAULT_PATH: tuple[tuple[float, float], ...] = ((0.0, 0.0), (6.0, 0.0), (10.0, 2.0), (16.0, 2.0))


class ReferenceConfig(_Node):
    speed: Annotated[float, Field(gt=0, le=100)] = Field(description="V^D: desired forward speed along each segment [m/s]")
    # the path the controller follows (export bakes it in) and verification simulates; verification.path is its
    # old place, still read (Config._path_moved)
    path: tuple[Waypoint, ...] = Field(default=_DEFAULT_PATH, max_length=1000, description="waypoints of the polyline [m]")
    turn_radius: Annotated[float, Field(gt=0, le=1e6)] | None = Field(
        default=None,
        description="round every corner of the path by an arc of this radius [m] and certify the turns: the "
        "certificate covers reference yaw rates up to speed / turn_radius (docs/theory.md §10); null: the "
        "reference jumps at the waypoints and the turns are not certified",
    )
    turn_ramp: Annotated[float, Field(gt=0, le=1e4)] | None = Field(
        default=None,
        description="with turn_radius: each turn eases in and out over this time [s] (its curvature ramps from 0 "
        "to 1/turn_radius, a clothoid easement), so the reference's yaw rate changes by at most speed / turn_radius "
        "x sampling_time / turn_ramp between periods, which the certificate covers instead of steps of the whole "
        "yaw rate; null: arcs that start at once",
    )

    @field_validator("path", mode="before")
    @classmethod
    def _lists_to_tuples(cls, v: Any) -> Any:
        # YAML gives lists; strict mode takes tuples only.
        if isinstance(v, list):
            return tuple(tuple(p) if isinstance(p, list) else p for p in v)
        return v

    @field_validator("path")
    @classmethod
    def _path_ok(cls, v: tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
        if len(v) < 2:
            raise ValueError("needs at least 2 waypoints")
        for i in range(1, len(v)):
            if math.hypot(v[i][0] - v[i - 1][0], v[i][1] - v[i - 1][1]) <= 1e-9:
                raise ValueError(f"waypoints {i - 1} and {i} coincide")
        return v


class DelayRange(_Node):
    min: Annotated[float, Field(ge=0, le=1e4)] = Field(description="tau_min [s]")
    max: Annotated[float, Field(ge=0, le=1e4)] = Field(description="tau_max [s]")

    @field_validator("max")
    @classmethod
    def _ordered(cls, v: float, info: Any) -> float:
        _range_check(info.data.get("min"), v)
        return v


class Dropouts(_Node):
    max_consecutive: Annotated[int, Field(ge=0, le=MAX_D_HI)] = Field(
        default=0,
        description="largest number of consecutive commands the network may lose (0: none); the actuator "
        "holds the last command it received, order is preserved",
    )


class NetworkConfig(_Node):
    sampling_time: Annotated[float, Field(ge=1e-6, le=100)] = Field(description="Ts: sensor sampling period [s]")
    delay: DelayRange = Field(description="bounds of the total delay tau = tau_SC + tau_CA + tau_C [s]")
    dropouts: Dropouts = Field(default_factory=Dropouts, description="packet loss on the command link")

    @model_validator(mode="after")
    def _lifting_size(self) -> "NetworkConfig":
        m = self.dropouts.max_consecutive
        if m and (self.delay.max + m * self.sampling_time) / self.sampling_time > MAX_D_HI + 1e-9:
            raise ValueError(
                f"{_FIELD}dropouts.max_consecutive: {m} lost commands after a delay of up to {self.delay.max:g} s "
                f"reach {self.delay.max + m * self.sampling_time:g} s = delay.max + max_consecutive * sampling_time; "
                f"the lifting supports up to {MAX_D_HI} * network.sampling_time = {MAX_D_HI * self.sampling_time:g} s "
                f"(max_consecutive <= {int(MAX_D_HI - math.ceil(self.delay.max / self.sampling_time - 1e-9))} here)"
            )
        ratio = self.delay.max / self.sampling_time
        if ratio > MAX_D_HI + 1e-9:
            hint = ""
            if self.delay.max >= 1.0 and self.delay.max / 1000.0 <= MAX_D_HI * self.sampling_time:
                hint = (f"; times are in seconds: {self.delay.max:g} looks like milliseconds"
                        f" (did you mean {self.delay.max / 1000.0:g} s?)")
            raise ValueError(
                f"{_FIELD}delay.max: must be <= {MAX_D_HI} * network.sampling_time (got {self.delay.max:g} s ="
                f" {ratio:.4g} periods; the lifted state would have {3 + 2 * math.ceil(ratio - 1e-9)} entries){hint}"
            )
        return self


class SlipRange(_Node):
    min: Annotated[float, Field(gt=0, le=10)] = Field(description="smallest slip coefficient mu (dimensionless, > 0)")
    max: Annotated[float, Field(gt=0, le=10)] = Field(description="largest slip coefficient mu (dimensionless, > 0)")

    @field_validator("max")
    @classmethod
    def _ordered(cls, v: float, info: Any) -> float:
        _range_check(info.data.get("min"), v)
        return v


class OffsetRange(_Node):
    min: Annotated[float, Field(ge=-1, le=1)] = Field(description="smallest longitudinal ICR offset x_icr [m]")
    max: Annotated[float, Field(ge=-1, le=1)] = Field(description="largest longitudinal ICR offset x_icr [m]")

    @field_validator("max")
    @classmethod
    def _ordered(cls, v: float, info: Any) -> float:
        _range_check(info.data.get("min"), v)
        return v


class SlipConfig(_Node):
    model: Literal["tracks", "icr"] = Field(
        default="tracks",
        description="tracks: one traction factor per track (the paper's); icr: also a yaw factor (the robot turns "
        "at yaw x the tracks' yaw rate) and the longitudinal offset of the instantaneous centre of rotation (it "
        "slides sideways at v_y = -x_icr omega); docs/theory.md §12",
    )
    right: SlipRange = Field(description="range of mu_r (right track)")
    left: SlipRange = Field(description="range of mu_l (left track)")
    yaw: SlipRange | None = Field(default=None, description="slip.model icr: range of the yaw factor (dimensionless)")
    icr_offset: OffsetRange | None = Field(default=None, description="slip.model icr: range of x_icr [m]")
    max_rate: Annotated[float, Field(gt=0, le=1e4)] | None = Field(
        default=None,
        description="largest |d mu / dt| of either track [1/s]; null: slip may jump anywhere in its range every period",
    )

    @model_validator(mode="after")
    def _icr_parameters(self) -> "SlipConfig":
        extra = [k for k in ("yaw", "icr_offset") if getattr(self, k) is not None]
        if self.model == "tracks" and extra:
            raise ValueError(f"{_FIELD}{extra[0]}: only with slip.model: icr (slip.model is tracks)")
        if self.model == "icr":
            missing = [k for k in ("yaw", "icr_offset") if getattr(self, k) is None]
            if missing:
                raise ValueError(f"{_FIELD}{missing[0]}: required with slip.model: icr (a range {{min, max}})")
        return self


class ErrorWeights(_Node):
    e_x: Annotated[float, Field(ge=0, le=1e6)] = Field(default=0.01, description="weight on e_x [1/m]")
    e_y: Annotated[float, Field(ge=0, le=1e6)] = Field(default=1.0, description="weight on e_y [1/m]")
    e_theta: Annotated[float, Field(ge=0, le=1e6)] = Field(default=0.01, description="weight on e_theta [1/rad]")

    @model_validator(mode="after")
    def _not_all_zero(self) -> "ErrorWeights":
        if self.e_x == 0 and self.e_y == 0 and self.e_theta == 0:
            raise ValueError("at least one weight must be > 0")
        return self


class SynthesisConfig(_Node):
    model: Literal["slip-aware", "paper"] = Field(
        default="slip-aware",
        description="slip-aware: exact in slip (it multiplies the command), the certificate the robot obeys; "
        "paper: the seed paper's linearization at mu = 1 (reproduction and comparison)",
    )
    objective: Literal["ultimate-bound", "stability", "hinf"] = Field(
        default="ultimate-bound", description="what the LMIs optimize (docs/theory/concepts.md, Synthesis)"
    )
    lyapunov: Literal["common", "slip-dependent", "delay-dependent", "path-dependent"] = Field(
        default="common", description="one Lyapunov matrix, one per slip corner, one per slip corner and "
        "delay vertex, or one per slip corner and the delay vertices of two periods (slip-aware model; "
        "delay- and path-dependent need polytopic delays)"
    )
    integral_action: bool = Field(
        default=False, description="integrator states int_e_x, int_e_y appended to the lifted state (zero steady error)"
    )
    delay_description: Literal["auto", "polytopic", "polytopic-product", "in-order-common", "norm-bounded",
                               "lossy-polytopic"] = Field(
        default="auto",
        description="slip-aware model: delay instants by the vertices of a triangle covering each instant's curve, the "
        "combinations of them in-order delivery needs (polytopic: at most 9 (n-1) n / 2 for n uncertain instants, the "
        "product where no two instants share a range), every combination (polytopic-product: 3^n), or the in-order ones "
        "with every triangle on the instants' common range (in-order-common: (n+1)(n+2)/2, covering more delays than "
        "configured, looser), by the "
        "norm-bounded embedding with multipliers, by the vertices of the instants a lossy link can really produce "
        "(lossy-polytopic; needs network.delay.max <= network.sampling_time), or auto (lossy-polytopic on a lossy "
        "link with delay.max <= Ts, else polytopic for one uncertain instant, else norm-bounded)",
    )
    kinematics: Literal["linearized", "nonlinear"] = Field(
        default="linearized",
        description="linearized: the certificate is for the linearization at the slip-compensated point "
        "(docs/theory.md §2); nonlinear: it also covers the kinematic terms the linearization drops, over the "
        "exact arcs of each period, for headings within synthesis.heading_bound, and with a common Lyapunov matrix "
        "on delay vertices slip that changes at any time within a period (docs/theory.md §9)",
    )
    heading_bound: Literal["auto"] | Annotated[float, Field(gt=0, le=1.0)] = Field(
        default="auto",
        description="nonlinear kinematics: the bound on |e_theta(t)| within every period that the certificate "
        "assumes and proves on its own set [rad]; auto searches for the one with the smallest weighted bound",
    )
    symmetry: Literal["auto", "off"] = Field(
        default="auto",
        description="auto: when the slip box is the same for both tracks, use the robot's left/right mirror "
        "symmetry (a mirror-invariant certificate, the same optimum, about half the LMIs; docs/theory.md §6h); "
        "off: pose every vertex condition (for comparison)",
    )
    multiplier: Literal["structured", "full"] = Field(
        default="structured", description="S-procedure multiplier for Delta: one per block or one scalar"
    )
    solver: Literal["clarabel", "scs"] = Field(default="clarabel", description="first solver tried")
    weights: ErrorWeights = Field(default_factory=ErrorWeights, description="weights on the error states")
    motor_limits: bool = Field(
        default=True, description="enforce robot.max_motor_speed on the invariant ellipsoid (when set)"
    )
    alpha_points: Annotated[int, Field(ge=3, le=200)] = Field(
        default=15, description="grid points of the line search over alpha (then refined)"
    )
    bisection_tol: Annotated[float, Field(gt=0, lt=0.1)] = Field(
        default=1e-3, description="tolerance on the decay rate r in the bisection"
    )
    margin: Annotated[float, Field(gt=0, lt=1e-2)] = Field(
        default=1e-7, description="LMIs are solved as M <= -margin*I (scaled units)"
    )

    @field_validator("symmetry", mode="before")
    @classmethod
    def _yaml_off(cls, v: Any) -> Any:
        """YAML 1.1 reads a bare ``off`` as false (the docs write ``symmetry: off``): take it as 'off'."""
        if v is False:
            return "off"
        if v is True:
            raise ValueError("write auto or off (YAML reads a bare on / yes / true as a boolean)")
        return v

    @model_validator(mode="after")
    def _consistent(self) -> "SynthesisConfig":
        if self.lyapunov != "common" and self.model == "paper":
            raise ValueError(f"{_FIELD}lyapunov: {self.lyapunov} needs synthesis.model: slip-aware (the paper's model has no slip corners)")
        if self.lyapunov != "common" and self.objective == "hinf":
            raise ValueError(f"{_FIELD}lyapunov: {self.lyapunov} is available for ultimate-bound and stability, not hinf")
        if self.lyapunov in ("delay-dependent", "path-dependent") and self.delay_description == "norm-bounded":
            raise ValueError(f"{_FIELD}lyapunov: {self.lyapunov} needs delay vertices (delay_description polytopic, "
                             "lossy-polytopic or auto), not norm-bounded")
        if self.kinematics == "nonlinear":
            if self.model != "slip-aware":
                raise ValueError(f"{_FIELD}kinematics: nonlinear needs synthesis.model: slip-aware")
            if self.objective != "ultimate-bound":
                raise ValueError(f"{_FIELD}kinematics: nonlinear is available for objective ultimate-bound "
                                 f"(an invariant set), not {self.objective}")
            if self.delay_description == "norm-bounded":
                raise ValueError(f"{_FIELD}kinematics: nonlinear needs delay vertices (delay_description "
                                 "polytopic, lossy-polytopic or auto), not norm-bounded")
        elif self.heading_bound != "auto":  # it would be ignored: say so rather than certify something else
            raise ValueError(f"{_FIELD}heading_bound: {self.heading_bound:g} rad is for synthesis.kinematics: nonlinear "
                             "(a linearized certificate assumes no heading bound); set kinematics: nonlinear or remove it")
        return self


class SynthesisSection(_Node):
    """A ``synthesis`` section alone: validating settings inside it names every problem by its
    ``synthesis.<key>`` path (``synthesize()``'s overrides)."""

    synthesis: SynthesisConfig


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


class _Named(_Node):
    """A scenario's name: its default output directory results/<name>/."""

    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]*$")] = Field(
        description="scenario name; default output directory results/<name>/"
    )

    @field_validator("name")
    @classmethod
    def _name_not_reserved(cls, v: str) -> str:
        if v in RESERVED_NAMES:
            raise ValueError(f"{v!r} is reserved (results/{v}/ holds the committed {RESERVED_NAMES[v]}); choose another name")
        return v


class Config(_Named):
    """A whole scenario: one robot, its network, its slip, and how to design and verify."""

    robot: RobotConfig
    reference: ReferenceConfig
    network: NetworkConfig
    slip: SlipConfig
    synthesis: SynthesisConfig = Field(default_factory=SynthesisConfig)
    verification: VerificationConfig = Field(default_factory=VerificationConfig)
    physics: PhysicsConfig = Field(default_factory=PhysicsConfig)
    monitor: MonitorConfig = Field(default_factory=MonitorConfig)

    @model_validator(mode="before")
    @classmethod
    def _path_moved(cls, data: Any) -> Any:
        """verification.path, the path's old place (files and stored configs written before it moved to the
        reference, which export bakes into the controller): read as reference.path; both given: refused."""
        if not isinstance(data, Mapping):
            return data
        ver = data.get("verification")
        if not isinstance(ver, Mapping) or "path" not in ver:
            return data
        ref = data.get("reference")
        if isinstance(ref, Mapping) and "path" in ref:
            raise ValueError(f"{_FIELD}verification.path: reference.path is given too: give the path once, as "
                             "reference.path (verification.path is its old place)")
        out = dict(data)
        out["verification"] = {k: v for k, v in ver.items() if k != "path"}
        if isinstance(ref, Mapping):  # else reference's own problem is named
            out["reference"] = {**ref, "path": ver["path"]}
        return out

    @model_validator(mode="after")
    def _plausible_motion(self) -> "Config":
        step = self.reference.speed * self.network.sampling_time
        if step > MAX_MOTION_PER_PERIOD:
            Ts = self.network.sampling_time
            hint = (f"; times are in seconds: {Ts:g} looks like milliseconds (did you mean {Ts / 1000.0:g} s?)"
                    if Ts >= 1.0 else "")
            raise ValueError(
                f"{_FIELD}network.sampling_time: {Ts:g} s at reference.speed {self.reference.speed:g} m/s moves the "
                f"robot {step:.3g} m per sampling period (more than {MAX_MOTION_PER_PERIOD:g} m: implausible for "
                f"feedback on a tracking error){hint}")
        return self

    @model_validator(mode="after")
    def _turns_need(self) -> "Config":
        """reference.turn_radius: a certificate the turning vertices exist for (model/arcs.py), and a path
        whose corners the arcs round (law.PathTable)."""
        r = self.reference.turn_radius
        if r is None:
            if self.reference.turn_ramp is not None:
                raise ValueError(f"{_FIELD}reference.turn_ramp: only with reference.turn_radius (it eases the turns in)")
            return self
        syn = self.synthesis
        for bad, why in ((syn.model == "paper", "synthesis.model: slip-aware"),
                         (syn.delay_description == "norm-bounded", "delay vertices (synthesis.delay_description: auto, "
                          "polytopic or lossy-polytopic)"),
                         (syn.objective == "hinf", "synthesis.objective ultimate-bound or stability")):
            if bad:
                raise ValueError(f"{_FIELD}reference.turn_radius: the turning certificate needs {why}")
        per_period = self.reference.speed / r * self.network.sampling_time
        if per_period > math.pi / 2:  # the arc factors' ranges (model/arcs.arc_ranges) need w_bar Ts <= pi/2
            raise ValueError(f"{_FIELD}reference.turn_radius: {r:g} m turns the reference by {per_period:.3g} rad per "
                             f"sampling period at reference.speed {self.reference.speed:g} m/s, more than pi/2: the turning "
                             f"certificate needs a radius of at least "
                             f"{math.ceil(self.reference.speed * self.network.sampling_time / (math.pi / 2) * 1e4) / 1e4:g} m")
        from .law import PathTable

        try:
            PathTable([list(p) for p in self.reference.path], self.reference.speed, r, self.network.sampling_time,
                      self.reference.turn_ramp)
        except ValueError as exc:
            raise ValueError(f"{_FIELD}reference.path: with reference.turn_radius {r:g} m, {exc}") from None
        return self

    @model_validator(mode="after")
    def _icr_needs(self) -> "Config":
        if self.slip.model != "icr":
            return self
        syn = self.synthesis
        if syn.model == "paper":
            raise ValueError(f"{_FIELD}slip.model: icr needs synthesis.model: slip-aware (the paper's model has no "
                             "yaw factor or lateral slip)")
        if syn.delay_description == "norm-bounded":
            raise ValueError(f"{_FIELD}slip.model: icr needs delay vertices (synthesis.delay_description: auto, "
                             "polytopic or lossy-polytopic)")
        return self



# --------------------------------------------------------------------------- any linear plant


def _matrix(v: Any, what: str) -> list[list[float]]:
    """A nested list of finite numbers (ints allowed) with rows of one length."""
    if not isinstance(v, (list, tuple)) or not v or not all(isinstance(r, (list, tuple)) and r for r in v):
        raise ValueError(f"{what}: must be a non-empty list of non-empty rows (a matrix)")
    rows = []
    for i, r in enumerate(v):
        row = []
        for j, x in enumerate(r):
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
                raise ValueError(f"{what}[{i}][{j}]: must be a finite number (got {x!r})")
            row.append(float(x))
        rows.append(row)
    if len({len(r) for r in rows}) != 1:
        raise ValueError(f"{what}: rows of different lengths {[len(r) for r in rows]}")
    return rows


class LtiDisturbance(_Node):
    """``x' = A x + B u + E w`` with ``||w(t)||_2 <= bound`` at every instant (any shape in time)."""

    E: Any = Field(description="n x q disturbance input matrix, a list of rows")
    bound: Annotated[float, Field(ge=1e-9, le=1e9)] = Field(description="bound on ||w(t)||_2 at every t (in w's "
                                                             "units; rescale E for smaller ones)")

    @field_validator("E")
    @classmethod
    def _E(cls, v: Any) -> list[list[float]]:
        E = _matrix(v, "E")
        if not any(x != 0.0 for row in E for x in row):
            raise ValueError("E: is zero (no disturbance enters: leave out plant.disturbance)")
        return E


class LtiOutputs(_Node):
    """The outputs ``y = C x`` whose bounds the certificate states (default: every state)."""

    C: Any = Field(description="p x n output matrix, a list of rows (one row per bounded output)")
    names: list[str] | None = Field(default=None, description="the outputs' names (default y1, y2, ...)")
    units: list[str] | None = Field(default=None, description="the outputs' units (default '-')")
    scale: list[Annotated[float, Field(gt=0, le=1e9)]] | None = Field(
        default=None, description="the synthesis minimizes the largest bound / scale (default 1 each)")

    @field_validator("C")
    @classmethod
    def _C(cls, v: Any) -> list[list[float]]:
        C = _matrix(v, "C")
        for i, row in enumerate(C):
            if not any(x != 0.0 for x in row):
                raise ValueError(f"C[{i}]: is zero (an output that is always 0 needs no bound)")
        return C

    @model_validator(mode="after")
    def _lengths(self) -> "LtiOutputs":
        p = len(self.C)
        for key in ("names", "units", "scale"):
            v = getattr(self, key)
            if v is not None and len(v) != p:
                raise ValueError(f"{_FIELD}{key}: {len(v)} entries for the {p} rows of C")
        return self


class LtiPlantConfig(_Node):
    """``x' = A x + B u (+ E w)`` (continuous time): from A and B here, or from a .mat / .npz file holding them."""

    kind: Literal["lti"] = Field(description="lti: any linear plant (tracked-robot: the default, without this section)")
    A: Any = Field(default=None, description="n x n state matrix (continuous time), a list of rows")
    B: Any = Field(default=None, description="n x m input matrix, a list of rows")
    file: str | None = Field(default=None, description="a .mat or .npz file with arrays A and B (instead of A, B here)")
    states: list[str] | None = Field(default=None, description="the states' names (default x1, x2, ...)")
    units: list[str] | None = Field(default=None, description="the states' units (default '-')")
    disturbance: LtiDisturbance | None = Field(default=None, description="a bounded disturbance input (the "
                                               "ultimate bound of synthesize)")
    input_limits: list[Annotated[float, Field(gt=0, le=1e9)]] | None = Field(
        default=None, description="|u_i| <= input_limits[i] on the certified set (one per input)")
    outputs: LtiOutputs | None = Field(default=None, description="the outputs the certificate bounds (default: "
                                       "every state)")

    @model_validator(mode="after")
    def _shapes(self) -> "LtiPlantConfig":
        if self.file is not None and (self.A is not None or self.B is not None):
            raise ValueError(f"{_FIELD}{'A' if self.A is not None else 'B'}: give A and B, or file (not both)")
        if self.file is None and (self.A is None or self.B is None):
            missing = " and ".join(k for k, v in (("A", self.A), ("B", self.B)) if v is None)
            raise ValueError(f"{_FIELD}{missing.split(' ')[0]}: required key is missing (give A and B, or file: "
                             f"missing {missing})")
        if self.file is not None:
            return self
        try:
            A = _matrix(self.A, "A")
            B = _matrix(self.B, "B")
        except ValueError as exc:
            raise ValueError(f"{_FIELD}{exc}") from None
        n = len(A)
        if len(A[0]) != n:
            raise ValueError(f"{_FIELD}A: must be square (got {n} x {len(A[0])})")
        if len(B) != n:
            raise ValueError(f"{_FIELD}B: must have n = {n} rows like A (got {len(B)})")
        for key, names in (("states", self.states), ("units", self.units)):
            if names is not None and len(names) != n:
                raise ValueError(f"{_FIELD}{key}: {len(names)} names for {n} states")
        if self.disturbance is not None and len(self.disturbance.E) != n:
            raise ValueError(f"{_FIELD}disturbance.E: must have n = {n} rows like A (got {len(self.disturbance.E)})")
        if self.outputs is not None and len(self.outputs.C[0]) != n:
            raise ValueError(f"{_FIELD}outputs.C: must have n = {n} columns like A (got {len(self.outputs.C[0])})")
        if self.input_limits is not None and len(self.input_limits) != len(B[0]):
            raise ValueError(f"{_FIELD}input_limits: {len(self.input_limits)} limits for the {len(B[0])} inputs of B")
        return self


class ControllerConfig(_Node):
    gain: Any = Field(description="K of u_k = K x_k (m x n), or of the lifted state [x; u_{k-1}; ...] (m x (n + d m))")

    @field_validator("gain")
    @classmethod
    def _gain(cls, v: Any) -> list[list[float]]:
        return _matrix(v, "K")


class LtiMarginConfig(_Node):
    pieces: Annotated[int, Field(ge=1, le=64)] = Field(default=6, description="pieces per switching instant's range "
                                                       "in the guaranteed over-approximation")
    tolerance: Annotated[float, Field(gt=0, le=1)] = Field(default=1e-3, description="bisection tolerance of a margin [s]")
    delay_far: Annotated[float, Field(gt=0, le=100)] | None = Field(default=None, description="largest delay searched "
                                                                    "[s] (default 4 sampling periods)")


ROBOT_ONLY_SECTIONS = ("robot", "reference", "slip", "verification", "physics")
ROBOT_ONLY_SYNTHESIS = ("model", "lyapunov", "integral_action", "delay_description", "kinematics", "heading_bound",
                        "symmetry", "multiplier", "weights", "motor_limits", "bisection_tol", "margin")


class LtiSynthesisConfig(_Node):
    """``robustsynth synthesize`` on a linear plant: a gain u_k = K xi_k on the lifted state (docs/theory.md §15)."""

    objective: Literal["auto", "stability", "ultimate-bound", "hinf"] = Field(
        default="auto", description="stability: robust decay (with input_limits: the largest ball of states at rest "
        "from which the inputs stay within them); ultimate-bound: the smallest invariant set under the disturbance "
        "(needs plant.disturbance); hinf: the smallest l2 gain from the disturbance to the outputs (needs "
        "plant.disturbance; input limits are not enforced); auto: ultimate-bound with a disturbance, else stability")
    decay: Annotated[float, Field(gt=0, le=1)] = Field(
        default=0.98, description="sqrt(V) shrinks at least by this factor per period (disturbance-free)")
    pieces: Annotated[int, Field(ge=1, le=64)] = Field(default=2, description="pieces per switching instant's range "
                                                       "in the guaranteed over-approximation")
    alpha_points: Annotated[int, Field(ge=2, le=60)] = Field(default=6, description="grid points of the line "
                                                             "search over V's contraction alpha (ultimate-bound)")
    threads: Annotated[int, Field(ge=1, le=64)] | Literal["auto"] = Field(
        default="auto", description="solves of the alpha line search run at once, one thread each (auto: the CPUs "
        "this process may use, at most 4); the search visits the same alphas either way, so the gain is the same")
    solver: Literal["clarabel", "scs"] = Field(default="clarabel", description="first solver tried")


class LtiConfig(_Named):
    """A linear plant closed over the network: a given gain's margins (``robustsynth margin``), or a gain
    of its own (``robustsynth synthesize``)."""

    plant: LtiPlantConfig
    controller: ControllerConfig | None = Field(default=None, description="the gain whose margins `margin` "
                                                "computes (or pass --gains)")
    network: NetworkConfig
    margin: LtiMarginConfig = Field(default_factory=LtiMarginConfig)
    synthesis: LtiSynthesisConfig = Field(default_factory=LtiSynthesisConfig)

    @model_validator(mode="before")
    @classmethod
    def _robot_only(cls, data: Any) -> Any:
        """The tracked robot's sections and features, asked for on a linear plant: said so by name."""
        if not isinstance(data, Mapping):
            return data
        for key in ROBOT_ONLY_SECTIONS:
            if key in data:
                raise ValueError(f"{_FIELD}{key}: a section of the tracked robot's config; not part of a linear "
                                 "plant's (plant: kind: lti)")
        syn = data.get("synthesis")
        if isinstance(syn, Mapping):
            for key in ROBOT_ONLY_SYNTHESIS:
                if key in syn:
                    raise ValueError(f"{_FIELD}synthesis.{key}: the tracked robot's; not available for a linear plant "
                                     "(plant: kind: lti)")
        return data

    @property
    def objective(self) -> str:
        """The synthesis objective that ``auto`` stands for."""
        obj = self.synthesis.objective
        if obj == "auto":
            return "ultimate-bound" if self.plant.disturbance is not None else "stability"
        return obj

    @model_validator(mode="after")
    def _needs(self) -> "LtiConfig":
        if self.synthesis.objective in ("ultimate-bound", "hinf") and self.plant.disturbance is None:
            raise ValueError(f"{_FIELD}synthesis.objective: {self.synthesis.objective} needs plant.disturbance (E and "
                             "its bound)")
        return self

    @model_validator(mode="after")
    def _far(self) -> "LtiConfig":
        far, net = self.margin.delay_far, self.network
        # (that it reaches beyond network.delay.max is checked where the margin runs: a sweep over delay.max
        # with one delay_far would otherwise refuse points that never compute a margin)
        if far is not None and not net.delay.min < far <= MAX_D_HI * net.sampling_time:
            raise ValueError(f"{_FIELD}margin.delay_far: must lie in (network.delay.min, {MAX_D_HI} * "
                             f"network.sampling_time] = ({net.delay.min:g}, {MAX_D_HI * net.sampling_time:g}] (got {far:g})")
        return self



# --------------------------------------------------------------------------- loading


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that refuses aliases (alias bombs) and duplicate keys."""

    def compose_node(self, parent: Any, index: Any) -> Any:  # noqa: D401
        if self.check_event(yaml.AliasEvent):
            mark = self.peek_event().start_mark
            raise ConfigError(f"line {mark.line + 1}: YAML aliases are not allowed")
        return super().compose_node(parent, index)

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                dup = key in seen
            except TypeError:
                dup = False
            if dup:
                raise ConfigError(f"line {key_node.start_mark.line + 1}: duplicate key {key!r}")
            try:
                seen.add(key)
            except TypeError:
                pass
        return super().construct_mapping(node, deep=deep)

# YAML 1.1 reads 1e6 or 2E-3 (no dot) as strings; a config means numbers (YAML 1.2's rule).  The
# resolver lists are copied first: adding to SafeLoader's own would change every yaml user's.
_StrictLoader.yaml_implicit_resolvers = {k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_StrictLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+.0123456789"))


def _loc(loc: tuple[Any, ...]) -> str:
    parts: list[str] = []
    for p in loc:
        if isinstance(p, int):
            parts.append(f"[{p}]")
        else:
            parts.append(("." if parts else "") + str(p))
    return "".join(parts) or "<root>"


def _fields_at(loc: tuple[Any, ...]) -> list[str]:
    """The keys of the config section at ``loc`` (empty when ``loc`` is not a section)."""
    node: type[BaseModel] | None = Config
    for part in loc:
        if node is None or not isinstance(part, str) or part not in node.model_fields:
            return []
        node = _node_class(node.model_fields[part].annotation)
    return list(node.model_fields) if node is not None else []


def _union_parts(root: "type[BaseModel] | None", loc: tuple[Any, ...]) -> set[int]:
    """The positions in a pydantic error location that name a branch of a union-typed key
    (``literal['auto']``, ``constrained-int``), found by walking the location through the fields of
    ``root``: a key the user typed is never taken for one, whatever its spelling."""
    import types
    import typing

    node, out = root, set()
    for i, part in enumerate(loc):
        if node is None or not isinstance(part, str) or part not in node.model_fields:
            break
        ann = node.model_fields[part].annotation
        union = typing.get_origin(ann) in (typing.Union, types.UnionType)
        if union and sum(a is not type(None) for a in typing.get_args(ann)) >= 2:
            if i + 1 < len(loc) and isinstance(loc[i + 1], str):
                out.add(i + 1)
            break
        node = _node_class(ann)
    return out


def _one_problem(e: dict[str, Any]) -> tuple[str, str]:
    """(key path, message) of one pydantic error."""
    loc = tuple(e["loc"])
    path = _loc(loc)
    msg = str(e["msg"])
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    if msg.startswith(_FIELD):
        field, _, msg = msg[len(_FIELD) :].partition(": ")
        path = f"{path}.{field}" if loc else field
    if _SIBLING in msg:
        parent = _loc(loc[:-1])
        msg = msg.replace(_SIBLING, f"{parent}." if loc[:-1] else "")
    if e["type"] == "extra_forbidden":
        msg = "unknown key"
    elif e["type"] == "missing":
        msg = "required key is missing"
    elif e["type"] in {"float_type", "int_type", "string_type", "bool_type", "model_type", "tuple_type"}:
        msg += f" (got {type(e.get('input')).__name__})"
    elif e["type"] in {"greater_than", "greater_than_equal", "less_than", "less_than_equal", "too_short", "too_long"}:
        msg += f" (got {e.get('input')!r})"
    return path, msg


def _format_validation_error(err: ValidationError) -> str:
    """Every problem, on one line: ``key.path: problem; other.key: problem``.  An unknown key that
    is a near-miss of a key of its section gets "did you mean"; a required key it stands for is not
    reported missing a second time."""
    import difflib

    errors = err.errors(include_url=False)
    explained: set[tuple[Any, ...]] = set()
    problems: list[tuple[str, str, bool]] = []
    root = globals().get(err.title)
    root = root if isinstance(root, type) and issubclass(root, BaseModel) else None
    for e in errors:
        loc = tuple(e["loc"])
        tags = _union_parts(root, loc)
        path, msg = _one_problem(dict(e, loc=tuple(p for i, p in enumerate(loc) if i not in tags)))
        if e["type"] == "extra_forbidden" and loc and isinstance(loc[-1], str):
            close = difflib.get_close_matches(loc[-1], _fields_at(loc[:-1]), n=1, cutoff=0.6)
            if close:
                target = loc[:-1] + (close[0],)
                msg += f" (did you mean {_loc(target)}?)"
                explained.add(target)
        problems.append((path, msg, bool(tags)))
    out: list[str] = []
    merged: dict[str, int] = {}  # a union's branches: one line, "should be A or B"
    for (path, msg, branch), e in zip(problems, errors):
        if e["type"] == "missing" and tuple(e["loc"]) in explained:
            continue
        if branch:
            alt = msg[len("Input should be "):] if msg.startswith("Input should be ") else msg
            if path in merged:
                out[merged[path]] += f" or {alt}"
                continue
            merged[path] = len(out)
            out.append(f"{path}: should be {alt}")
            continue
        out.append(f"{path}: {msg}")
    return "; ".join(out)


def refuse_lti(obj: Any, where: str) -> None:
    """InputError when ``obj`` (a config, or a model made from one) is a linear plant's: the robot's
    calls have no meaning for it, and would fail on a missing section."""
    from .errors import InputError

    if isinstance(obj, LtiConfig) or isinstance(getattr(obj, "config", None), LtiConfig):
        raise InputError(f"{where}: the config is a linear plant's (plant: kind: lti): use robustsynth.lti_plant, "
                         "synthesize_lti, verify_lti and lti_margins (or the CLI, which picks them)")


def is_lti(data: Any) -> bool:
    """Whether a config document (or object) describes a linear plant (``plant: kind: lti``)."""
    if isinstance(data, LtiConfig):
        return True
    plant = data.get("plant") if isinstance(data, Mapping) else None
    return isinstance(plant, Mapping) and plant.get("kind") == "lti"


def _validate(data: dict[str, Any]) -> "Config | LtiConfig":
    if is_lti(data):
        return LtiConfig.model_validate(data)
    plant = data.get("plant")
    if plant is not None:  # the tracked robot needs no plant section; its kind may be named
        if not isinstance(plant, Mapping):  # 'plant: lti' reads as a kind, but is no section
            raise ConfigError(f"plant: must be a mapping (got {plant!r}): plant: {{kind: lti, A: ..., B: ...}} for a linear "
                              "plant, or no plant section for the tracked robot")
        if dict(plant) != {"kind": "tracked-robot"}:
            raise ConfigError(f"plant.kind: must be tracked-robot (the default: no plant section) or lti "
                              f"(got {plant.get('kind')!r})")
        data = {k: v for k, v in data.items() if k != "plant"}
    return Config.model_validate(data)


def parse_config(text: str | bytes, source: str = "<config>") -> Config:
    """Parse and validate a YAML document (``text``) into a :class:`Config`.

    Parameters
    ----------
    text : str or bytes
        The YAML document.
    source : str
        The name errors give the document (a file path).

    Returns
    -------
    Config
        The validated, frozen configuration.

    Raises
    ------
    ConfigError
        One line naming the key path and the problem.
    """
    if isinstance(text, bytes):
        if len(text) > MAX_CONFIG_BYTES:
            raise ConfigError(f"{source}: file is larger than 1 MiB ({len(text)} bytes)")
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ConfigError(f"{source}: not valid UTF-8 (byte {exc.start})") from None
    if len(text) > MAX_CONFIG_BYTES:
        raise ConfigError(f"{source}: file is larger than 1 MiB")
    try:
        data = yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - _StrictLoader is a SafeLoader
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(f"{source}: {where}invalid YAML: {problem}") from None
    except RecursionError:
        raise ConfigError(f"{source}: YAML nesting is too deep") from None
    if data is None:
        raise ConfigError(f"{source}: the document is empty (expected the sections robot:, reference:, network:, "
                          "slip:, ...; `robustsynth default-config` prints a complete one)")
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: the document must be a mapping (got {type(data).__name__})")
    try:
        return _validate(data)
    except ValidationError as exc:
        raise ConfigError(_format_validation_error(exc)) from None
    except RecursionError:
        raise ConfigError(f"{source}: YAML nesting is too deep") from None


def config_from_dict(data: dict[str, Any]) -> "Config | LtiConfig":
    """Validate a mapping (as a YAML file would give) into a config; ConfigError names the key."""
    try:
        return _validate(data)
    except ValidationError as exc:
        raise ConfigError(_format_validation_error(exc)) from None


def default_config_text() -> str:
    """The embedded default configuration (package data)."""
    return resources.files("robustsynth").joinpath("data/default.yaml").read_text(encoding="utf-8")


def named_default_config_text(name: str) -> str:
    """The embedded default with ``name: NAME`` (validated like a file; comments kept)."""
    text = default_config_text()
    lines = text.splitlines(keepends=True)
    idx = [i for i, ln in enumerate(lines) if ln.startswith("name:")]
    if len(idx) != 1:  # the package data always has one top-level name line
        raise ConfigError("<default config>: no single top-level name line to replace")
    lines[idx[0]] = f"name: {json.dumps(name)}\n"
    out = "".join(lines)
    try:
        parse_config(out, "--name")
    except ConfigError as exc:
        raise ConfigError(str(exc).replace("name:", "--name:", 1) if str(exc).startswith("name:") else str(exc)) from None
    return out


def default_config(**overrides: Any) -> Config:
    """The embedded default with dotted-path overrides, validated like a file:
    ``default_config(**{"network.delay.max": 0.2, "robot.max_motor_speed": None})``.

    Parameters
    ----------
    **overrides : Any
        Dotted key paths and their values (``"network.delay.max"``, ...).

    Returns
    -------
    Config
        The embedded default with those values, validated.

    Raises
    ------
    ConfigError
        An unknown key or an invalid value, named.
    """
    return mapping_with(yaml.safe_load(default_config_text()), **overrides)


def mapping_with(data: dict[str, Any], **overrides: Any) -> Config:
    """A config mapping with dotted-path overrides (the mapping is changed), validated like a file."""
    for path, value in overrides.items():
        path = _new_key(data, path)
        node = data
        keys = path.split(".")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        node[keys[-1]] = value
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(_format_validation_error(exc)) from None


def _new_key(data: dict[str, Any], path: str) -> str:
    """The key path an override ``path`` sets now (RENAMED_KEYS), with the value at the renamed key's old
    place in ``data`` removed: the override replaces it."""
    path = RENAMED_KEYS.get(path, path)
    for old, new in RENAMED_KEYS.items():
        if new == path:
            *parents, leaf = old.split(".")
            node: Any = data
            for k in parents:
                node = node.get(k) if isinstance(node, dict) else None
            if isinstance(node, dict):
                node.pop(leaf, None)
    return path


def _node_class(annotation: Any) -> type[BaseModel] | None:
    """The BaseModel class of a field annotation (through Annotated / Optional), else None."""
    import typing

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        cls = _node_class(arg)
        if cls is not None:
            return cls
    return None


def check_config_key(path: str, root: "type[BaseModel] | None" = None) -> None:
    """ConfigError naming ``path`` unless it is a dotted path to a leaf of the configuration
    (``network.delay.max``; of ``root``, default the robot's Config), with the keys that exist there."""
    node: type[BaseModel] = root or Config
    if node is Config:
        path = RENAMED_KEYS.get(path, path)  # an old key path is read at its place now
    parts = path.split(".")
    for i, part in enumerate(parts):
        fields = node.model_fields
        if part not in fields:
            where = ".".join(parts[:i]) or "the top level"
            import difflib

            close = difflib.get_close_matches(part, list(fields), n=1)
            hint = f" (did you mean {'.'.join(parts[:i] + close + parts[i + 1:])}?)" if close else f"; keys at {where}: {', '.join(fields)}"
            raise ConfigError(f"{path}: no such config key{hint}")
        sub = _node_class(fields[part].annotation)
        if i < len(parts) - 1 and sub is None:
            raise ConfigError(f"{path}: {'.'.join(parts[: i + 1])} is a value, not a section")
        if i == len(parts) - 1 and sub is not None:
            raise ConfigError(f"{path}: is a section; name one of its keys ({', '.join(sub.model_fields)})")
        if sub is not None:
            node = sub


def config_with(config: "Config | LtiConfig", overrides: dict[str, Any]) -> "Config | LtiConfig":
    """``config`` with dotted-path ``overrides`` applied and validated like a file (ConfigError with
    the key path on a bad value or an unknown key)."""
    data = config.model_dump(mode="python")
    for path, value in overrides.items():
        check_config_key(path, type(config))
        if isinstance(config, Config):
            path = _new_key(data, path)
        node = data
        keys = path.split(".")
        for k in keys[:-1]:
            if node.get(k) is None:
                node[k] = {}
            node = node[k]
        node[keys[-1]] = value
    try:
        return type(config).model_validate(data)
    except ValidationError as exc:
        raise ConfigError(_format_validation_error(exc)) from None


def load_config(path: str | Path | Mapping[str, Any] | None = None) -> Config:
    """Load a configuration file (or validate a mapping with the same rules and messages); ``None``
    gives the embedded default.  To change single values of the default: ``default_config(**{"network.
    delay.max": 0.09})``; of a loaded config: ``cfg.model_copy(update=...)`` per section, or dump,
    edit and reload (``load_config(config_to_dict(cfg) | {...})``).

    Parameters
    ----------
    path : str, Path, Mapping or None
        A YAML file, or a mapping validated with the same rules; ``None``: the embedded default.

    Returns
    -------
    Config
        The validated, frozen configuration (a ``LtiConfig`` for ``plant: kind: lti``).

    Raises
    ------
    ConfigError
        One line naming the key path and the problem (the CLI's exit 2).
    """
    if path is None:
        return parse_config(default_config_text(), "<default config>")
    if isinstance(path, Mapping):
        try:
            return _validate(dict(path))
        except ValidationError as exc:
            raise ConfigError(_format_validation_error(exc)) from None
    p = Path(path)
    try:
        if p.is_dir():
            raise ConfigError(f"{p}: is a directory, not a config file")
        with p.open("rb") as fh:  # regular files, and pipes such as <(...) or /dev/stdin
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except ConfigError:
        raise
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(f"{p}: file is larger than 1 MiB")
    return parse_config(raw, str(p))


def config_schema(plant: str = "tracked-robot") -> dict[str, Any]:
    """JSON Schema of the configuration (``plant='lti'``: of a linear plant's, ``plant: kind: lti``)."""
    return (LtiConfig if plant == "lti" else Config).model_json_schema()


def config_to_dict(cfg: Config) -> dict[str, Any]:
    """Resolved configuration as plain JSON-able data (tuples as lists)."""
    return cfg.model_dump(mode="json")
