"""What every config model shares: the strict, frozen node class, the tokens validators' messages carry
(resolved into key paths by :mod:`.messages`), the lifting's size limit, and the scenario's name."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, field_validator
from pydantic_core import PydanticCustomError

from ..objectives import choices_text, names

_MODEL = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

Pos = Annotated[float, Field(gt=0)]
NonNeg = Annotated[float, Field(ge=0)]
RESERVED_NAMES = {"baselines": "regression baselines", "sweeps": "sweep tables"}  # results/<name>/ of a run
MAX_D_HI = 20  # longest delay, in sampling periods (the lifted state grows with it)
# Tokens in validator messages: _SIBLING is replaced by the sibling key's full path; a message
# starting with _FIELD "name: ..." (from a model validator) is reported at that field's path.
_SIBLING = "@sibling:"
_FIELD = "@field:"


@dataclass(frozen=True)
class Registered:
    """A field's values: the objectives registered for ``plant`` (:mod:`robustsynth.objectives`), read when a
    config is validated (an objective registered later is accepted), after the ``extra`` ones."""

    plant: str
    extra: tuple[str, ...] = ()

    def choices(self) -> tuple[str, ...]:
        return self.extra + names(self.plant)

    def __call__(self, value: Any) -> Any:
        """Before the type's validation: any value that is not one of the choices (a string or not) is refused as
        a Literal refuses it, naming them."""
        allowed = self.choices()
        if not isinstance(value, str) or value not in allowed:
            raise PydanticCustomError("literal_error", "Input should be {expected}", {"expected": choices_text(allowed)})
        return value

    def __get_pydantic_json_schema__(self, core_schema: Any, handler: Any) -> dict[str, Any]:
        """The schema's ``enum``: the choices when the schema is made (a Literal's schema has them too)."""
        return dict(handler(core_schema), enum=list(self.choices()))


_ROBOT_OBJECTIVES = Registered("tracked-robot")
_LINEAR_OBJECTIVES = Registered("lti", ("auto",))
RobotObjective = Annotated[str, BeforeValidator(_ROBOT_OBJECTIVES), _ROBOT_OBJECTIVES]
LinearObjective = Annotated[str, BeforeValidator(_LINEAR_OBJECTIVES), _LINEAR_OBJECTIVES]


def _range_check(lo: float | None, hi: float, lo_name: str = "min") -> None:
    if lo is not None and hi < lo:
        raise ValueError(f"must be >= {_SIBLING}{lo_name} (got {hi:g} < {lo:g})")


class _Node(BaseModel):
    model_config = _MODEL


class _Range(_Node):
    # a range {min, max} (its subclasses declare both, with their bounds): a max below the min is refused

    @field_validator("max", check_fields=False)
    @classmethod
    def _ordered(cls, v: float, info: Any) -> float:
        _range_check(info.data.get("min"), v)
        return v


class _Named(_Node):
    """A scenario's name: its default output directory results/<name>/."""

    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9][A-Za-z0-9._-]*$")] = Field(
        description="scenario name; default output directory results/<name>/"
    )

    @field_validator("name")
    @classmethod
    def _name_not_reserved(cls, v: str) -> str:
        if v in RESERVED_NAMES:
            raise ValueError(f"{v!r} is reserved (results/{v}/ holds the committed {RESERVED_NAMES[v]}); choose another name")
        return v


def _node_class(annotation: Any) -> type[BaseModel] | None:
    """The BaseModel class of a field annotation (through Annotated / Optional), else None."""
    import typing

    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        cls = _node_class(arg)
        if cls is not None:
            return cls
    return None
