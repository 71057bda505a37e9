"""A linear plant's whole config (:class:`LtiConfig`, ``plant: kind: lti``): the plant's matrices, a given gain,
the margin's and the synthesis' settings, and the tracked robot's keys refused by name."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from ..objectives import objective
from ._base import _FIELD, MAX_D_HI, LinearObjective, _Named, _Node
from .network import NetworkConfig


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

    objective: LinearObjective = Field(
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


class LtiSynthesisSection(_Node):
    """A linear plant's ``synthesis`` section alone (``synthesize()``'s overrides, named by ``synthesis.<key>``)."""

    synthesis: LtiSynthesisConfig


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
        obj = self.synthesis.objective
        if obj != "auto" and objective(obj).needs_disturbance and self.plant.disturbance is None:
            raise ValueError(f"{_FIELD}synthesis.objective: {obj} needs plant.disturbance (E and "
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
