"""Sphinx configuration of robustsynth's documentation (make docs: offline, warnings as errors)."""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import robustsynth  # noqa: E402

project = "robustsynth"
author = "robustsynth developers"
copyright = "robustsynth developers"  # noqa: A001
version = release = robustsynth.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx_click",
    "sphinx-mathjax-offline",  # MathJax 3 copied into _static/mathjax: the math renders without a network
    "configref",
    "apiref",
    "baselines",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "sample-log.csv"]
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 4
suppress_warnings = []

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented"
autodoc_typehints_format = "short"
autodoc_default_options = {"undoc-members": False}
napoleon_numpy_docstring = True
napoleon_google_docstring = False
nitpicky = True
# names from third-party packages and typing internals the API's signatures mention: no inventories offline
nitpick_ignore_regex = [
    ("py:.*", r"(numpy|np|pydantic|click|pathlib|collections|typing|os|cvxpy|control|dask|distributed|concurrent)\b.*"),
    ("py:.*", r"(Any|Path|Mapping|Sequence|Iterable|Callable|NDArray|ArrayLike|Literal|Self)"),
]
# internal helpers that public docstrings name (documented in their modules, not part of the public API)
nitpick_ignore = [
    ("py:func", "vertices.icr_constant"),
    ("py:func", "slip.turn_feedforward"),
    ("py:attr", "arcs.Turns.merged"),
    ("py:func", "auto_threads"),
    ("py:func", "delay_margin"),
    ("py:func", "robustsynth.certificate.lti.recheck_lti"),
    ("py:func", "robustsynth.certificate.lti.check_lti_certificate"),
    ("py:func", "robustsynth.certificate.lti.lti_within"),
    ("py:mod", "nonlinear"),
    # numpydoc's words for duck types in a Parameters section
    ("py:class", "callable"),
    ("py:class", "sequence"),
]

html_theme = "furo"
html_title = f"robustsynth {release}"
html_static_path: list[str] = []
html_show_sourcelink = False


def _escape_bars(app, ctx, lines):
    """click help texts write |e_y| (a magnitude); in reST |name| is a substitution: escape a bar that opens one."""
    import re

    for i, line in enumerate(lines):
        if "``" not in line:
            lines[i] = re.sub(r"(?<!\\)\|(?=\S)", r"\\|", line)


def _napoleon_except_properties(app, what, name, obj, options, lines):
    """napoleon, except on properties and attributes: it reads their first line as ``type: description``, and
    these docstrings are prose ("Slip input in normalized box coordinates: B_d W ...")."""
    from sphinx.ext.napoleon import _process_docstring

    if what not in ("attribute", "property"):
        _process_docstring(app, what, name, obj, options, lines)


def _class_signatures(app, what, name, obj, options, signature, return_annotation):
    """A pydantic model's signature is its fields with their FieldInfo defaults: its keys are in the config
    reference instead.  A dataclass's is its fields with their annotations as strings (``from __future__ import
    annotations``), which are no references: its field names only."""
    import dataclasses

    if what == "class" and any(b.__module__.startswith("pydantic") for b in getattr(obj, "__mro__", ())[1:]):
        return "", None
    if what in ("class", "exception") and dataclasses.is_dataclass(obj):
        return "(" + ", ".join(f.name for f in dataclasses.fields(obj) if f.init) + ")", None
    return None


def _escape_substitutions(app, what, name, obj, options, lines):
    """Docstrings write magnitudes as |w_i|; in reST |name| is a substitution reference: escape the bar."""
    import re

    for i, line in enumerate(lines):
        if "``" not in line:
            lines[i] = re.sub(r"(?<![\\|])\|(?=[^\s|])", r"\\|", line)


def setup(app):
    app.connect("autodoc-process-signature", _class_signatures)
    app.connect("autodoc-process-docstring", _escape_substitutions, priority=450)
    from sphinx.ext.napoleon import _process_docstring

    for listener in list(app.events.listeners["autodoc-process-docstring"]):
        if listener.handler is _process_docstring:
            app.disconnect(listener.id)
    app.connect("autodoc-process-docstring", _napoleon_except_properties)
    app.connect("sphinx-click-process-description", _escape_bars)
    app.connect("sphinx-click-process-epilog", _escape_bars)
    app.connect("sphinx-click-process-options", _escape_bars)
