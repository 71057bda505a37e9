"""The ``network:`` section, the same for every plant: the sampling period, the delay's bounds, the losses."""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import Field, model_validator

from ._base import _FIELD, MAX_D_HI, _Node, _Range


class DelayRange(_Range):
    min: Annotated[float, Field(ge=0, le=1e4)] = Field(description="tau_min [s]")
    max: Annotated[float, Field(ge=0, le=1e4)] = Field(description="tau_max [s]")


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
