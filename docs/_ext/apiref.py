"""Sphinx extension: the Python API reference, generated from ``robustsynth._EXPORTS`` (the public names).

``{api-reference}`` writes one autodoc entry per public name, from the module that defines it, in the
order of robustsynth's table of contents: a name added to the public API is documented (and its
docstring built with warnings as errors) without touching the docs.
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any

from docutils import nodes
from generated import parsed
from sphinx.util.docutils import SphinxDirective


def public_api() -> list[tuple[str, str, Any]]:
    import robustsynth

    return [(name, module, getattr(importlib.import_module(module), name))
            for name, module in robustsynth._EXPORTS.items()]


def _is_pydantic(cls: type) -> bool:
    return any(base.__module__.startswith("pydantic") for base in cls.__mro__[1:])


class ApiReference(SphinxDirective):
    def run(self) -> list[nodes.Node]:
        lines: list[str] = []
        for name, module, obj in public_api():
            kind = "autoclass" if inspect.isclass(obj) else "autofunction"
            lines += [f".. {kind}:: {module}.{name}"]
            if kind == "autoclass" and _is_pydantic(obj):
                lines += ["", "   Its keys are in the :doc:`configuration reference </reference/config>`."]
            elif kind == "autoclass":
                lines += ["   :members:", "   :inherited-members:"]
            lines += [""]
        return parsed(self, lines, "robustsynth._EXPORTS", rst=True)


def setup(app: Any) -> dict[str, Any]:
    app.add_directive("api-reference", ApiReference)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
