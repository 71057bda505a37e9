"""The tracked robot's ``robot:`` and ``reference:`` sections: its geometry (with the checks that name a length
written in the wrong unit) and the path it follows."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import Field, field_validator, model_validator

from ._base import _FIELD, _Node

# [m]: a robot.gear_radius at or above MAX_GEAR_RADIUS, a robot.track_distance above MAX_TRACK_DISTANCE is no
# tracked robot's (a main battle tank's sprocket is ~0.35 m, its gauge ~3 m): named a likely unit mistake
MAX_GEAR_RADIUS = 1.0
MAX_TRACK_DISTANCE = 10.0
# what a unit hint may suggest instead: lengths [m] and a ratio track_distance / gear_radius of real robots
_TYPICAL_LENGTH = {"gear_radius": (0.005, 0.5), "track_distance": (0.05, 5.0)}
_TYPICAL_RATIO = (1.5, 30.0)


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
