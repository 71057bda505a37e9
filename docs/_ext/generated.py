"""What the docs' own directives share: parse the lines they generate into the page."""

from __future__ import annotations

from typing import Any

from docutils import nodes
from docutils.statemachine import StringList


def parsed(directive: Any, lines: list[str], source: str, rst: bool = False) -> list[nodes.Node]:
    """The nodes of ``lines`` (Markdown, or with ``rst`` reStructuredText: MyST parses a directive's content as
    Markdown, so reST goes in an eval-rst block), parsed in ``directive``'s place; ``source`` names where they
    came from in messages."""
    if rst:
        lines = ["```{eval-rst}", *lines, "```"]
    node = nodes.section()
    node.document = directive.state.document
    directive.state.nested_parse(StringList(lines, source=source), directive.content_offset, node)
    return node.children
