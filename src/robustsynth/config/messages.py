"""A pydantic ValidationError as one line of problems, each beginning with its key path (``network.delay.max:
must be ...``): the tokens of :mod:`._base` resolved, near-miss keys named ("did you mean"), a union's branches
merged."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ValidationError

from ._base import _FIELD, _SIBLING, _Node, _node_class
from .tracked_robot import Config


def _loc(loc: tuple[Any, ...]) -> str:
    parts: list[str] = []
    for p in loc:
        if isinstance(p, int):
            parts.append(f"[{p}]")
        else:
            parts.append(("." if parts else "") + str(p))
    return "".join(parts) or "<root>"


def _fields_at(root: "type[BaseModel] | None", loc: tuple[Any, ...]) -> list[str]:
    """The keys of the section at ``loc`` of the config model ``root`` (the robot's ``Config`` when None; empty when
    ``loc`` is not a section)."""
    node: type[BaseModel] | None = root if root is not None else Config
    for part in loc:
        if node is None or not isinstance(part, str) or part not in node.model_fields:
            return []
        node = _node_class(node.model_fields[part].annotation)
    return list(node.model_fields) if node is not None else []


def _union_parts(root: "type[BaseModel] | None", loc: tuple[Any, ...]) -> set[int]:
    """The positions in a pydantic error location that name a branch of a union-typed key
    (``literal['auto']``, ``constrained-int``), found by walking the location through the fields of
    ``root``: a key the user typed is never taken for one, whatever its spelling."""
    import types
    import typing

    node, out = root, set()
    for i, part in enumerate(loc):
        if node is None or not isinstance(part, str) or part not in node.model_fields:
            break
        ann = node.model_fields[part].annotation
        union = typing.get_origin(ann) in (typing.Union, types.UnionType)
        if union and sum(a is not type(None) for a in typing.get_args(ann)) >= 2:
            if i + 1 < len(loc) and isinstance(loc[i + 1], str):
                out.add(i + 1)
            break
        node = _node_class(ann)
    return out


def _one_problem(e: dict[str, Any]) -> tuple[str, str]:
    """(key path, message) of one pydantic error."""
    loc = tuple(e["loc"])
    path = _loc(loc)
    msg = str(e["msg"])
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    if msg.startswith(_FIELD):
        field, _, msg = msg[len(_FIELD) :].partition(": ")
        path = f"{path}.{field}" if loc else field
    if _SIBLING in msg:
        parent = _loc(loc[:-1])
        msg = msg.replace(_SIBLING, f"{parent}." if loc[:-1] else "")
    if e["type"] == "extra_forbidden":
        msg = "unknown key"
    elif e["type"] == "missing":
        msg = "required key is missing"
    elif e["type"] in {"float_type", "int_type", "string_type", "bool_type", "model_type", "tuple_type"}:
        msg += f" (got {type(e.get('input')).__name__})"
    elif e["type"] in {"greater_than", "greater_than_equal", "less_than", "less_than_equal", "too_short", "too_long"}:
        msg += f" (got {e.get('input')!r})"
    return path, msg


def _model_named(title: str) -> type[BaseModel] | None:
    """The config model a ValidationError's title names (every model of the config is a ``_Node``), else None."""
    todo: list[type[BaseModel]] = [_Node]
    found: dict[str, type[BaseModel]] = {}
    while todo:
        cls = todo.pop()
        found.setdefault(cls.__name__, cls)
        todo += cls.__subclasses__()
    return found.get(title)


def _format_validation_error(err: ValidationError) -> str:
    """Every problem, on one line: ``key.path: problem; other.key: problem``.  An unknown key that
    is a near-miss of a key of its section gets "did you mean"; a required key it stands for is not
    reported missing a second time."""
    import difflib

    errors = err.errors(include_url=False)
    explained: set[tuple[Any, ...]] = set()
    problems: list[tuple[str, str, bool]] = []
    root = _model_named(err.title)
    for e in errors:
        loc = tuple(e["loc"])
        tags = _union_parts(root, loc)
        path, msg = _one_problem(dict(e, loc=tuple(p for i, p in enumerate(loc) if i not in tags)))
        if e["type"] == "extra_forbidden" and loc and isinstance(loc[-1], str):
            close = difflib.get_close_matches(loc[-1], _fields_at(root, loc[:-1]), n=1, cutoff=0.6)
            if close:
                target = loc[:-1] + (close[0],)
                msg += f" (did you mean {_loc(target)}?)"
                explained.add(target)
        problems.append((path, msg, bool(tags)))
    out: list[str] = []
    merged: dict[str, int] = {}  # a union's branches: one line, "should be A or B"
    for (path, msg, branch), e in zip(problems, errors):
        if e["type"] == "missing" and tuple(e["loc"]) in explained:
            continue
        if branch:
            alt = msg[len("Input should be "):] if msg.startswith("Input should be ") else msg
            if path in merged:
                out[merged[path]] += f" or {alt}"
                continue
            merged[path] = len(out)
            out.append(f"{path}: should be {alt}")
            continue
        out.append(f"{path}: {msg}")
    return "; ".join(out)
