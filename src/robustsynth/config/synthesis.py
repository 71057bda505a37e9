"""The tracked robot's ``synthesis:`` section: the model, objective, Lyapunov structure and delay description of
the LMIs, and which combinations of them exist."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from ..objectives import listed, objective
from ._base import _FIELD, RobotObjective, _Node


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
    objective: RobotObjective = Field(
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
        if self.lyapunov != "common" and objective(self.objective).common_lyapunov_only:
            raise ValueError(f"{_FIELD}lyapunov: {self.lyapunov} is available for "
                             f"{listed(lambda o: not o.common_lyapunov_only, conj='and')}, not {self.objective}")
        if self.lyapunov in ("delay-dependent", "path-dependent") and self.delay_description == "norm-bounded":
            raise ValueError(f"{_FIELD}lyapunov: {self.lyapunov} needs delay vertices (delay_description polytopic, "
                             "lossy-polytopic or auto), not norm-bounded")
        if self.kinematics == "nonlinear":
            if self.model != "slip-aware":
                raise ValueError(f"{_FIELD}kinematics: nonlinear needs synthesis.model: slip-aware")
            if not objective(self.objective).nonlinear_kinematics:
                raise ValueError(f"{_FIELD}kinematics: nonlinear is available for objective "
                                 f"{listed(lambda o: o.nonlinear_kinematics)} (an invariant set), not {self.objective}")
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
