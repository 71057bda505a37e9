"""Sphinx extension: the configuration keys, generated from the pydantic v2 models of robustsynth.config.

``{config-reference} robustsynth.config.Config`` (a MyST directive) walks the model's fields, recursing into
nested sections, and writes one table per top-level section: the dotted key path, its type, its unit (the
``[...]`` of the field's description), its default, its range (the field's constraints) and its meaning (the
description).  Nothing here is kept by hand: a key added to the schema appears, a key removed disappears, and
tests/test_docs.py checks every key of the JSON schema against the built page.
"""

from __future__ import annotations

import enum
import importlib
import re
import types
import typing
from typing import Any

import annotated_types as at
from docutils import nodes
from generated import parsed
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined
from sphinx.util.docutils import SphinxDirective

from robustsynth.config._base import _node_class  # the model a field annotation holds

UNIT = re.compile(r"\[([^\]]+)\]")
THEORY = re.compile(r"docs/theory\.md (§\s?(\d+)[a-z]?)")


def _constraints(meta: list[Any]) -> list[str]:
    out = []
    for m in meta:
        if isinstance(m, FieldInfo):  # Annotated[float, Field(gt=0)] inside a union: its own constraints
            out += _constraints(list(m.metadata))
            continue
        for cls, sym in ((at.Gt, ">"), (at.Ge, "≥"), (at.Lt, "<"), (at.Le, "≤")):
            if isinstance(m, cls):
                out.append(f"{sym} {getattr(m, next(iter(cls.__dataclass_fields__)))!r}")
        if isinstance(m, at.MinLen):
            out.append(f"length ≥ {m.min_length}")
        if isinstance(m, at.MaxLen):
            out.append(f"length ≤ {m.max_length}")
        if getattr(m, "pattern", None):
            out.append(f"matches ``{m.pattern}``")
    return out


def _type(annotation: Any, ranges: list[str]) -> str:
    """A short reading of an annotation; the constraints met on the way are appended to ``ranges``."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        ranges.extend(_constraints(list(args[1:])))
        return _type(args[0], ranges)
    if origin is typing.Literal:
        return " | ".join(f"``{a}``" if not isinstance(a, str) else f"``{a}``" for a in args)
    if origin in (typing.Union, types.UnionType):
        return " | ".join(_type(a, ranges) for a in args)
    if origin in (list, tuple):
        if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
            return f"list of {_type(args[0], ranges)}"
        if origin is tuple:
            return "(" + ", ".join(_type(a, ranges) for a in args) + ")"
        return f"list of {_type(args[0], ranges) if args else 'any'}"
    if annotation is type(None):
        return "null"
    if annotation is Any:
        return "any"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "section"
    if isinstance(annotation, type) and issubclass(annotation, enum.Enum):
        return " | ".join(f"``{e.value}``" for e in annotation)
    return getattr(annotation, "__name__", str(annotation))


def _default(field: FieldInfo) -> str:
    if field.default_factory is not None:
        value = field.default_factory()
        return "(section)" if isinstance(value, BaseModel) else f"``{value!r}``"
    if field.default is PydanticUndefined:
        return "**required**"
    if isinstance(field.default, tuple) and len(field.default) > 4:
        return f"{len(field.default)} entries (see ``default-config``)"
    return f"``{field.default!r}``" if field.default is not None else "``null``"


def _cell(text: str) -> str:
    return text.replace("\n", " ").replace("|", "\\|") if text else "—"


def config_keys(model: type[BaseModel], prefix: str = "") -> list[dict[str, str]]:
    """Every key of ``model``, depth first: path, type, unit, default, range, description."""
    rows = []
    for name, field in model.model_fields.items():
        path = f"{prefix}{name}"
        ranges = _constraints(field.metadata)
        registered = [m for m in field.metadata if callable(getattr(m, "choices", None))]  # config._base.Registered
        kind = (" | ".join(f"``{a}``" for a in registered[0].choices()) if registered
                else _type(field.annotation, ranges))
        sub = _node_class(field.annotation)
        desc = field.description or ((sub.__doc__ or "").strip().split("\n\n")[0] if sub else "")
        unit = UNIT.search(field.description or "")
        rows.append({"key": path, "type": kind, "unit": unit.group(1) if unit else "",
                     "default": _default(field), "range": ", ".join(dict.fromkeys(ranges)),
                     "description": " ".join(desc.split())})
        if sub is not None:
            rows += config_keys(sub, path + ".")
    return rows


def _describe(text: str) -> str:
    """A description as reST: backquoted code stays code, theory references link to the theory pages."""
    text = re.sub(r"(?<!`)`([^`]+)`(?!`)", r"``\1``", text)
    text = re.sub(r"(?<![\w`])\*(?!\s)", r"\\*", text)
    return THEORY.sub(lambda m: f":ref:`docs/theory.md {m.group(1)} <theory-{m.group(2)}>`", text)


class ConfigReference(SphinxDirective):
    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        module, _, name = self.arguments[0].rpartition(".")
        model = getattr(importlib.import_module(module), name)
        rows = config_keys(model)
        lines: list[str] = []
        tops = [r for r in rows if "." not in r["key"]]
        for top in tops:
            section = [r for r in rows if r["key"] == top["key"] or r["key"].startswith(top["key"] + ".")]
            lines += [f".. rubric:: ``{top['key']}``", ""]
            if top["description"]:
                lines += [_describe(_cell(top["description"])), ""]
            lines += [
                      ".. list-table::", "   :header-rows: 1", "   :widths: 22 14 8 12 14 30",
                      "   :class: config-keys", "",
                      "   * - key", "     - type", "     - unit", "     - default", "     - range", "     - meaning"]
            for r in section:
                lines += [f"   * - .. _cfg-{model.__name__.lower()}-{r['key']}:", "",
                          f"       ``{r['key']}``",
                          f"     - {_cell(r['type'])}", f"     - {_cell(r['unit'])}", f"     - {_cell(r['default'])}",
                          f"     - {_cell(r['range'])}", f"     - {_describe(_cell(r['description']))}"]
            lines.append("")
        return parsed(self, lines, "robustsynth.config", rst=True)


def setup(app: Any) -> dict[str, Any]:
    app.add_directive("config-reference", ConfigReference)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
