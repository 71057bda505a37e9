"""YAML -> a validated config: the strict loader (no aliases, no duplicate keys, YAML 1.2 floats), files, mappings,
and the embedded default (package data), with its name or dotted-path overrides."""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from ..errors import ConfigError
from .lti import LtiConfig
from .messages import _format_validation_error
from .overrides import mapping_with
from .roots import _validate
from .tracked_robot import Config

MAX_CONFIG_BYTES = 1 << 20  # 1 MiB


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
        text = _utf8(text, source)
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
    return parse_config(read_config_text(path), str(Path(path)))


def read_config_text(path: str | Path, what: str = "config file") -> str:
    """The text of a YAML file of at most MAX_CONFIG_BYTES (a config, a sweep): ConfigError naming the file
    when it is a directory (not a ``what``), unreadable, larger, or not UTF-8."""
    p = Path(path)
    try:
        if p.is_dir():
            raise ConfigError(f"{p}: is a directory, not a {what}")
        with p.open("rb") as fh:  # regular files, and pipes such as <(...) or /dev/stdin
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except ConfigError:
        raise
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(f"{p}: file is larger than 1 MiB")
    return _utf8(raw, str(p))


def _utf8(raw: bytes, source: str) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{source}: not valid UTF-8 (byte {exc.start})") from None
