"""Dotted key paths (``network.delay.max``): checked against the models, and applied to a mapping or a config
as overrides validated like a file."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ValidationError

from ..errors import ConfigError
from ._base import _node_class
from .lti import LtiConfig
from .messages import _format_validation_error
from .tracked_robot import Config

# old key path -> its place now: still read there (a file, an override), never written
RENAMED_KEYS = {"verification.path": "reference.path"}


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
