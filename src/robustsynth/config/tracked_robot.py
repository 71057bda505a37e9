"""The tracked robot's whole config (:class:`Config`, ``plant: kind: tracked-robot``, the default): its sections,
and the checks that span several of them (the path's old place, a plausible motion per period, what turns and the
icr slip model need)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from pydantic import Field, model_validator

from ..objectives import listed, objective
from ._base import _FIELD, _Named
from .network import NetworkConfig
from .robot import ReferenceConfig, RobotConfig
from .slip import SlipConfig
from .synthesis import SynthesisConfig
from .verification import MonitorConfig, PhysicsConfig, VerificationConfig

MAX_MOTION_PER_PERIOD = 2.0  # [m]: reference.speed * sampling_time above this is named a likely unit mistake


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
                         (objective(syn.objective).turns is not None,
                          f"synthesis.objective {listed(lambda o: o.turns is None)}")):
            if bad:
                raise ValueError(f"{_FIELD}reference.turn_radius: the turning certificate needs {why}")
        per_period = self.reference.speed / r * self.network.sampling_time
        if per_period > math.pi / 2:  # the arc factors' ranges (model/arcs.arc_ranges) need w_bar Ts <= pi/2
            raise ValueError(f"{_FIELD}reference.turn_radius: {r:g} m turns the reference by {per_period:.3g} rad per "
                             f"sampling period at reference.speed {self.reference.speed:g} m/s, more than pi/2: the turning "
                             f"certificate needs a radius of at least "
                             f"{math.ceil(self.reference.speed * self.network.sampling_time / (math.pi / 2) * 1e4) / 1e4:g} m")
        from ..law import PathTable

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
