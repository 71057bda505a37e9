"""YAML configuration -> validated, frozen :class:`Config` (pydantic v2, ``extra="forbid"``).

All quantities are SI: m, s, rad, rad/s.  Every error is raised as :class:`ConfigError` whose
message is one line beginning with the key path (``network.delay.max: ...``) or, for problems
with the file itself, with the file name.

The package, one module per concern (each imports only those above it in this list):

- ``_base``: the strict, frozen node class, the message tokens, the lifting's size limit, the scenario name
- ``network``: the ``network:`` section, the same for every plant
- ``robot``, ``slip``, ``synthesis``, ``verification``: the tracked robot's sections
- ``tracked_robot``: the tracked robot's whole config, :class:`Config`, and its checks across sections
- ``lti``: a linear plant's whole config, :class:`LtiConfig` (``plant: kind: lti``)
- ``messages``: a pydantic ValidationError as one line of key paths and problems
- ``roots``: which root model a document is; the JSON schema; plain data
- ``overrides``: dotted key paths, checked and applied
- ``loading``: YAML (strict), files, mappings, the embedded default
"""

from __future__ import annotations

from ..errors import ConfigError
from ._base import _FIELD, _MODEL, _SIBLING, MAX_D_HI, RESERVED_NAMES, NonNeg, Pos, _Named, _node_class, _Node, _range_check
from .network import DelayRange, Dropouts, NetworkConfig
from .robot import (MAX_GEAR_RADIUS, MAX_TRACK_DISTANCE, _DEFAULT_PATH, _TYPICAL_LENGTH, _TYPICAL_RATIO, Coord,
                    ReferenceConfig, RobotConfig, Waypoint, _implausible_length, _length, _length_unit_hint)
from .slip import OffsetRange, SlipConfig, SlipRange
from .synthesis import ErrorWeights, SynthesisConfig, SynthesisSection
from .verification import InitialOffset, LossChannel, MonitorConfig, NoiseConfig, PhysicsConfig, VerificationConfig
from .tracked_robot import MAX_MOTION_PER_PERIOD, Config
from .lti import (ROBOT_ONLY_SECTIONS, ROBOT_ONLY_SYNTHESIS, ControllerConfig, LtiConfig, LtiDisturbance,
                  LtiMarginConfig, LtiOutputs, LtiPlantConfig, LtiSynthesisConfig, LtiSynthesisSection, _matrix)
from .messages import _fields_at, _format_validation_error, _loc, _one_problem, _union_parts
from .roots import _validate, config_schema, config_to_dict, is_lti, plant_kind_of, refuse_lti
from .overrides import RENAMED_KEYS, _new_key, check_config_key, config_with, mapping_with
from .loading import (MAX_CONFIG_BYTES, _StrictLoader, config_from_dict, default_config, default_config_text,
                      load_config, named_default_config_text, parse_config, read_config_text)

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
