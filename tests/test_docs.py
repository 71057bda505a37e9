"""The documentation site (docs/): it builds offline with warnings as errors, its generated reference covers
every CLI command and option (compared with click), every configuration key (compared with the pydantic
JSON schema, not with the generator's own walk) and every public name, and every command line the pages
show parses against the CLI; every YAML block is a valid config or fragment of one."""

from __future__ import annotations

import html
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import click
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)
BUILD_TIMEOUT_S = 120  # the target is <= 60 s on a 2-core machine (about 10 s measured); this catches a runaway

pytestmark = pytest.mark.docs


def sphinx_build(out: Path) -> subprocess.CompletedProcess:
    """``make docs``'s command into ``out`` (a fresh environment: every page read, every warning seen)."""
    return subprocess.run([sys.executable, "-m", "sphinx", "-E", "-W", "--keep-going", "-n", "-q", "-b", "html",
                           str(DOCS), str(out)], capture_output=True, text=True, timeout=BUILD_TIMEOUT_S,
                          env={**os.environ, "PYTHONWARNINGS": "ignore"})


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    t0 = time.perf_counter()
    r = sphinx_build(out)
    took = time.perf_counter() - t0
    assert r.returncode == 0, f"make docs failed ({took:.0f} s):\n{r.stdout}\n{r.stderr}"
    assert "WARNING" not in r.stderr and "ERROR" not in r.stderr, r.stderr
    return out


def _ids(page: Path) -> set[str]:
    return set(re.findall(r'\bid="([^"]+)"', page.read_text(encoding="utf-8")))


def test_the_site_builds_without_warnings(site: Path) -> None:
    for page in ("index", "tutorials/your-robot", "reference/cli", "reference/config", "reference/api", "theory"):
        assert (site / f"{page}.html").exists(), page
    # MathJax is served by the site itself (no network when a page is read)
    index = (site / "index.html").read_text(encoding="utf-8")
    assert re.search(r'<script[^>]+src="_static/mathjax/tex-chtml\.js', index), "MathJax not loaded from _static"
    assert (site / "_static" / "mathjax" / "tex-chtml.js").exists()
    assert "://" not in "".join(re.findall(r'<script[^>]+src="([^"]+)"', index)), "a script from the network"


# ------------------------------------------------------------------ the config keys, against the JSON schema

def _schema_keys(schema: dict[str, Any]) -> set[str]:
    """Every dotted key path of a pydantic JSON schema (objects through $ref, anyOf/allOf and null)."""
    defs = schema.get("$defs", {})

    def resolve(node: dict[str, Any]) -> list[dict[str, Any]]:
        if "$ref" in node:
            return resolve(defs[node["$ref"].rsplit("/", 1)[1]])
        out = [node]
        for key in ("anyOf", "allOf", "oneOf"):
            for sub in node.get(key, []):
                out += resolve(sub)
        return out

    keys: set[str] = set()

    def walk(node: dict[str, Any], prefix: str) -> None:
        for part in resolve(node):
            for name, sub in part.get("properties", {}).items():
                keys.add(prefix + name)
                walk(sub, prefix + name + ".")

    walk(schema, "")
    return keys


@pytest.mark.parametrize("plant, model", [("tracked-robot", "config"), ("lti", "lticonfig")])
def test_every_config_key_is_in_the_reference(site: Path, plant: str, model: str) -> None:
    from docutils.nodes import make_id

    from robustsynth.config import config_schema

    keys = _schema_keys(config_schema(plant))
    assert len(keys) > (60 if plant == "tracked-robot" else 20)  # the walk reaches the nested sections
    page = site / "reference" / "config.html"
    ids, text = _ids(page), html.unescape(re.sub(r"<[^>]+>", "", page.read_text(encoding="utf-8")))
    want = {make_id(f"cfg-{model}-{k}"): k for k in keys}
    missing = sorted(k for i, k in want.items() if i not in ids or k not in text)
    assert not missing, f"config keys missing from the reference: {missing}"
    stale = sorted(i for i in ids if i.startswith(f"cfg-{model}-") and i not in want)
    assert not stale, f"reference rows that are no key of the schema: {stale}"



def test_the_objective_rows_list_the_registrys_objectives(site: Path) -> None:
    """synthesis.objective is validated against the objectives' registry, not a Literal: its row still lists the
    values (docs/_ext/configref.py reads them from the field's ``Registered``), for each plant kind."""
    from robustsynth.objectives import names

    text = html.unescape(re.sub(r"<[^>]+>", "", (site / "reference" / "config.html").read_text(encoding="utf-8")))
    for values in (names("tracked-robot"), ("auto",) + names("lti")):
        assert " | ".join(values) in text, values

# ------------------------------------------------------------------ the CLI, against click

def test_every_cli_command_and_option_is_in_the_reference(site: Path) -> None:
    from robustsynth.cli import main

    ids = _ids(site / "reference" / "cli.html")
    ctx = click.Context(main, info_name="robustsynth")
    assert len(main.commands) >= 13
    missing = []
    for prog, cmd in [("robustsynth", main), *((f"robustsynth-{n}", c) for n, c in main.commands.items())]:
        if cmd is not main and prog not in ids:
            missing.append(prog)
        help_opt = cmd.get_help_option(ctx)
        for p in cmd.params:
            if p is help_opt or getattr(p, "hidden", False):
                continue
            if isinstance(p, click.Argument):
                want = [f"cmdoption-{prog}-arg-{p.human_readable_name}"]
            else:
                want = [f"cmdoption-{prog}-{o.lstrip('-')}" for o in (*p.opts, *p.secondary_opts)]
            missing += [w for w in want if w not in ids]
    assert not missing, f"CLI commands/options missing from the reference: {missing}"


def test_every_public_name_is_in_the_api_reference(site: Path) -> None:
    import robustsynth

    ids = _ids(site / "reference" / "api.html")
    missing = [f"{m}.{n}" for n, m in robustsynth._EXPORTS.items() if f"{m}.{n}" not in ids]
    assert not missing, f"public names missing from the API reference: {missing}"



def test_the_examples_gallery_shows_every_committed_config_and_its_result(site: Path) -> None:
    """docs/examples.md's gallery is generated from configs/ and results/baselines/: every config, its command, and
    what its baseline says (the default's certified |e_y| as its summary.json states it; a failed verdict as failed)."""
    import html
    import json

    page = html.unescape(re.sub(r"<[^>]+>", "", (site / "examples.html").read_text(encoding="utf-8")))
    for cfg in sorted((ROOT / "configs").glob("*.yaml")):
        assert f"robustsynth run configs/{cfg.name}" in page, cfg.name
        assert f"Committed result (results/baselines/{cfg.stem}/)" in page, cfg.stem
    default = json.loads((ROOT / "results" / "baselines" / "default" / "summary.json").read_text())
    assert f"|e_y| ≤ {100 * default['certified']['ultimate_bound']['e_y']:.2f} cm" in page
    tracks = json.loads((ROOT / "results" / "baselines" / "tracks-box" / "summary.json").read_text())
    assert not tracks["verification_passed"] and "linearization only" in page and "verification FAILED" in page


# ------------------------------------------------------------------ code blocks of README and docs

def _blocks(langs: tuple[str, ...]) -> list[tuple[str, str]]:
    out = []
    for p in [ROOT / "README.md", *PAGES]:
        for lang, code in re.findall(r"^\s*```(\w+)\n(.*?)^\s*```", p.read_text(encoding="utf-8"), flags=re.S | re.M):
            if lang in langs:
                out.append((str(p.relative_to(ROOT)), code))
    return out


def _command_lines(code: str) -> list[str]:
    """The robustsynth command lines of a shell block (comments, prompts, continuations, pipes, redirects)."""
    lines, joined = [], ""
    for raw in code.splitlines():
        line = raw.strip()
        if line.startswith("$ "):
            line = line[2:]
        joined += line.rstrip("\\") + " "
        if line.endswith("\\"):
            continue
        cmd, joined = joined.split(" #", 1)[0].strip(), ""
        cmd = re.split(r"\s[|>]\s?|\s>", cmd + " ", maxsplit=1)[0].strip()
        first = cmd.split(" ", 1)[0]
        if first in ("robustsynth", ".venv/bin/robustsynth"):
            lines.append(cmd)
    return lines


SHELL = [(where, cmd) for where, code in _blocks(("sh", "bash", "console")) for cmd in _command_lines(code)]


def test_the_docs_show_command_lines() -> None:
    assert len(SHELL) >= 25  # every page's commands are collected (a parsing slip would drop them): 29 today


@pytest.mark.parametrize("where, line", SHELL, ids=[f"{w}:{i}" for i, (w, _) in enumerate(SHELL)])
def test_every_command_line_shown_parses(where: str, line: str) -> None:
    """Each `robustsynth ...` line of a shell block names a real command and real options (click parses it
    without running it; files need not exist)."""
    from robustsynth.cli import main

    args = shlex.split(line)[1:]
    ctx = click.Context(main, info_name="robustsynth")
    while args and args[0] in ("-q", "--quiet", "-v", "--verbose"):  # the group's own options
        args = args[1:]
    assert args, f"{where}: no command in {line!r}"
    cmd = main.get_command(ctx, args[0])
    assert cmd is not None, f"{where}: no command {args[0]!r} in {line!r}"
    known = {o for p in cmd.get_params(ctx) if isinstance(p, click.Option) for o in (*p.opts, *p.secondary_opts)}
    for token in args[1:]:
        if token.startswith("-") and not re.fullmatch(r"-[\d.]+(e-?\d+)?", token):
            assert token.split("=", 1)[0] in known, f"{where}: {args[0]} has no option {token} ({line!r})"
    # and click reads it: choices, counts and arguments (files need not exist: no callbacks run)
    try:
        cmd.make_context(args[0], list(args[1:]), parent=ctx, resilient_parsing=True)
    except click.UsageError as e:
        pytest.fail(f"{where}: {line!r}: {e.format_message()}")


YAML = _blocks(("yaml",))


@pytest.mark.parametrize("where, code", YAML, ids=[f"{w}:{i}" for i, (w, _) in enumerate(YAML)])
def test_every_yaml_block_is_a_valid_config_or_fragment(where: str, code: str) -> None:
    """A YAML block that names a committed file (``# configs/...yaml`` on its first line) is that file's
    content, and the file loads (a config, or a sweep spec); any other block is a whole config (it has a
    name) or a fragment of one that validates merged into the embedded default (a linear plant's: into
    configs/dc-motor.yaml)."""
    from robustsynth.config import config_from_dict, default_config_text, load_config

    data = yaml.safe_load(code)
    named = re.match(r"#\s*(configs/\S+\.yaml)", code.strip())
    if named:
        path = ROOT / named.group(1)
        assert yaml.safe_load(path.read_text()) == data, f"{where}: the block is not {named.group(1)}"
        if "axes" in data:
            from robustsynth.sweeps import load_sweep

            load_sweep(path)
        else:
            load_config(path)
        return
    if "name" not in data:
        lti = "plant" in data or "controller" in data
        base = yaml.safe_load((ROOT / "configs" / "dc-motor.yaml").read_text() if lti else default_config_text())

        def merge(a: dict, b: dict) -> dict:
            return {**a, **{k: merge(a[k], v) if isinstance(v, dict) and isinstance(a.get(k), dict) else v
                            for k, v in b.items()}}

        data = merge(base, data)
    config_from_dict(data)  # raises ConfigError naming the key


# ------------------------------------------------------------------ the README: short, and the two commands first

def test_the_readme_is_short_and_begins_with_the_two_commands() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.encode("utf-8")) <= 10 * 1024, f"README.md is {len(readme.encode()) / 1024:.1f} KB"
    first = re.match(r"# robustsynth\n\n```sh\n(.*?)```", readme, flags=re.S)
    assert first, "README.md must begin with its title and the shell block of `make demo` and `make test`"
    assert [line.split("#")[0].strip() for line in first.group(1).splitlines()] == ["make demo", "make test"]
    for link in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme):
        assert "://" in link or (ROOT / link).exists(), f"README.md links to missing {link}"


# ------------------------------------------------------------------ as a reader sees it: headless chromium

def test_the_site_in_a_headless_browser(site: Path) -> None:
    """The index and the first tutorial in Debian's chromium (make docs-check): images load, MathJax (from
    the site itself) renders the math, no console error, no request leaves the machine.  .ci/run installs
    chromium, so CI runs this."""
    sys.path.insert(0, str(DOCS / "_tools"))
    try:
        import browser_check
    finally:
        sys.path.pop(0)
    chromium = browser_check.find_chromium()
    if chromium is None:
        pytest.skip("chromium is not installed (apt-get install chromium; .ci/run installs it)")
    for page in browser_check.PAGES:
        found, problems = browser_check.check_page(chromium, site / page)
        assert not problems, f"{page}: {problems}"
        assert found["images"] and found["math"] > 0, (page, found)


def test_every_public_function_documents_its_parameters_and_return() -> None:
    """numpydoc sections on the public API: a Parameters entry for every parameter of the signature, and
    a Returns section (the API reference renders them)."""
    import importlib
    import inspect

    import robustsynth

    problems = []
    for name, module in robustsynth._EXPORTS.items():
        obj = getattr(importlib.import_module(module), name)
        if inspect.isclass(obj):
            continue
        doc = inspect.getdoc(obj) or ""
        params = re.search(r"^Parameters\n-+\n(.*?)(?=^\w+\n-+\n|\Z)", doc, flags=re.S | re.M)
        documented = set()
        for line in (params.group(1) if params else "").splitlines():
            head = re.match(r"^(\*{0,2}\w+(?:, \*{0,2}\w+)*)(?: :|$)", line)
            if head:
                documented |= {n.strip().lstrip("*") for n in head.group(1).split(",")}
        wanted = {p for p in inspect.signature(obj).parameters}
        if wanted - documented:
            problems.append(f"{module}.{name}: parameters not documented: {sorted(wanted - documented)}")
        if not re.search(r"^Returns\n-+\n", doc, flags=re.M):
            problems.append(f"{module}.{name}: no Returns section")
    assert not problems, "\n".join(problems)
