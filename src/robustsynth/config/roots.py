"""The two root models: which one a document (or object) is, and what comes out of one (its JSON schema, its plain
data)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..errors import ConfigError, InputError
from .lti import LtiConfig
from .tracked_robot import Config


def refuse_lti(obj: Any, where: str) -> None:
    """InputError when ``obj`` (a config, or a model made from one) is a linear plant's: the robot's
    calls have no meaning for it, and would fail on a missing section."""
    if isinstance(obj, LtiConfig) or isinstance(getattr(obj, "config", None), LtiConfig):
        raise InputError(f"{where}: the config is a linear plant's (plant: kind: lti): its plant is "
                         "robustsynth.LinearPlant.from_config(config), which robustsynth.synthesize, robustsynth.verify "
                         "and robustsynth.margin take (the CLI picks it)")


def is_lti(data: Any) -> bool:
    """Whether a config document (or object) describes a linear plant (``plant: kind: lti``)."""
    if isinstance(data, LtiConfig):
        return True
    plant = data.get("plant") if isinstance(data, Mapping) else None
    return isinstance(plant, Mapping) and plant.get("kind") == "lti"


def plant_kind_of(config: Any) -> str:
    """The plant kind a config describes, as its plant names itself (``plant_kind``): "lti" for ``plant: kind:
    lti``, else "tracked-robot"."""
    return "lti" if is_lti(config) else "tracked-robot"


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


def config_schema(plant: str = "tracked-robot") -> dict[str, Any]:
    """JSON Schema of the configuration (``plant='lti'``: of a linear plant's, ``plant: kind: lti``)."""
    return (LtiConfig if plant == "lti" else Config).model_json_schema()


def config_to_dict(cfg: Config) -> dict[str, Any]:
    """Resolved configuration as plain JSON-able data (tuples as lists)."""
    return cfg.model_dump(mode="json")
