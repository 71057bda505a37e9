"""The tracked robot's ``slip:`` section: the traction factors' ranges (and the icr model's yaw factor and offset)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from ._base import _FIELD, _Node, _Range


class SlipRange(_Range):
    min: Annotated[float, Field(gt=0, le=10)] = Field(description="smallest slip coefficient mu (dimensionless, > 0)")
    max: Annotated[float, Field(gt=0, le=10)] = Field(description="largest slip coefficient mu (dimensionless, > 0)")


class OffsetRange(_Range):
    min: Annotated[float, Field(ge=-1, le=1)] = Field(description="smallest longitudinal ICR offset x_icr [m]")
    max: Annotated[float, Field(ge=-1, le=1)] = Field(description="largest longitudinal ICR offset x_icr [m]")


class SlipCompensation(_Node):
    """The slip-compensated law (docs/theory.md §18): each track's command divided by the runtime monitor's estimate
    of its traction (:meth:`robustsynth.monitor.Monitor.slip_estimate`, §17), so that the certificate covers only
    the ratio mu / mu_hat, not the whole box."""

    error: Annotated[float, Field(gt=0, le=1)] | Literal["auto"] = Field(
        default="auto",
        description="e: the largest |mu_i(t) - mu_hat_i| while a command computed from the estimate acts, which the "
        "certificate assumes and the monitor checks each period (half-width + lag <= e); auto: 1.5 x the estimate's "
        "a-priori bound at action on a straight segment (monitor.slip_estimate_bound; docs/theory.md §17, §18)",
    )


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
    compensation: SlipCompensation | None = Field(
        default=None,
        description="divide each track's command by the estimated traction (slip.model tracks, slip.max_rate "
        "needed); the certificate is then conditional on the estimate's error (docs/theory.md §18); null: none",
    )

    @model_validator(mode="after")
    def _icr_parameters(self) -> "SlipConfig":
        extra = [k for k in ("yaw", "icr_offset") if getattr(self, k) is not None]
        if self.model == "tracks" and extra:
            raise ValueError(f"{_FIELD}{extra[0]}: only with slip.model: icr (slip.model is tracks)")
        if self.compensation is not None:
            if self.model != "tracks":
                raise ValueError(f"{_FIELD}compensation: needs slip.model tracks (the icr model's yaw factor hides "
                                 "the traction difference from the estimate; docs/theory.md §17)")
            if self.max_rate is None:
                raise ValueError(f"{_FIELD}compensation: needs slip.max_rate (without a rate bound the estimate is "
                                 "the box; docs/theory.md §17)")
            e = self.compensation.error
            if e != "auto" and e >= min(self.right.min, self.left.min):
                raise ValueError(f"{_FIELD}compensation.error: {e:g} must be below the smallest traction "
                                 f"{min(self.right.min, self.left.min):g} (the ratio mu / mu_hat must stay positive)")
        if self.model == "icr":
            missing = [k for k in ("yaw", "icr_offset") if getattr(self, k) is None]
            if missing:
                raise ValueError(f"{_FIELD}{missing[0]}: required with slip.model: icr (a range {{min, max}})")
        return self
