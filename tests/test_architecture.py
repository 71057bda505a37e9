"""The house's layers (docs/architecture.md): every module of robustsynth imports only from its own
floor or below, and no modules import each other in a circle.  Every import counts, also those
inside functions (the lazy ones keep `robustsynth --help` fast, but they are dependencies all the
same).  A new module must be given a floor here, so that its place is a decision."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PKG = "robustsynth"

# bottom -> top; a name covers the module and everything under it (longest match wins)
LAYERS: list[tuple[str, ...]] = [
    ("robustsynth", "robustsynth.errors", "robustsynth.forked", "robustsynth.law", "robustsynth.monitor",
     "robustsynth.objectives", "robustsynth.results", "robustsynth.verified"),  # the face, errors, work in a forked
    # child, the pure law and its monitor, the objectives' descriptors, verified arithmetic
    ("robustsynth.config",),
    ("robustsynth.core",),  # what every plant shares: the network and its delay / loss sequences
    ("robustsynth.model",),
    ("robustsynth.certificate",),  # the numpy re-check of LMI certificates: the proof checker
    ("robustsynth.artifacts",),  # output files, the gains file's format
    ("robustsynth.runtime",),  # the controller on the robot, its exports
    ("robustsynth.plants",),  # what the controller acts on
    ("robustsynth.scenarios",),  # what the world may do: slip, delays, losses, starts
    ("robustsynth.synthesis",),  # LMIs (the only user of cvxpy)
    ("robustsynth.verification",),  # the judges, plant-generic: the certificate's re-check, the lifted model, verdicts
    ("robustsynth.robot_verification",),  # the tracked robot's own judges: closed loop on its path, probe, physics
    ("robustsynth.report", "robustsynth.interop"),
    ("robustsynth.comparison", "robustsynth.margins", "robustsynth.sweeps", "robustsynth.identification",
     "robustsynth.identification_icr"),
    ("robustsynth.pipeline", "robustsynth.regression"),
    ("robustsynth.commands",),  # each command's job per plant kind (the CLI's one library call)
    ("robustsynth.cli", "robustsynth.__main__"),
]


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path) -> set[str]:
    """The robustsynth modules ``path`` imports (absolute names; `from X import y` counts y as a
    module when X.y is one)."""
    mod = _module_name(path)
    package = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == PKG}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != PKG:
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                out.add(sub if sub in MODULES else target)
    return out - {mod}


MODULES = {_module_name(p): p for p in sorted((SRC / PKG).rglob("*.py"))}


def _floor(mod: str) -> int:
    best, floor = -1, None
    for i, names in enumerate(LAYERS):
        for n in names:
            if (mod == n or mod.startswith(n + ".")) and len(n) > best:
                best, floor = len(n), i
    assert floor is not None, f"{mod}: no floor in tests/test_architecture.py LAYERS (give it one)"
    return floor


GRAPH = {m: _imports(p) for m, p in MODULES.items()}


def test_every_module_has_a_floor() -> None:
    for m in MODULES:
        _floor(m)


@pytest.mark.parametrize("mod", sorted(MODULES))
def test_imports_run_down_the_floors(mod: str) -> None:
    up = [f"{t} (floor {_floor(t)})" for t in sorted(GRAPH[mod]) if t in MODULES and _floor(t) > _floor(mod)]
    assert not up, f"{mod} (floor {_floor(mod)}) imports from above: {', '.join(up)}"


def _circle(graph: dict[str, set[str]]) -> list[str] | None:
    """A circle of the graph (depth-first search: a back edge closes one), or None."""
    state: dict[str, int] = {}  # 1 on the stack, 2 done
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        stack.append(m)
        for t in sorted(graph[m]):
            if t not in graph:
                continue
            if state.get(t) == 1:
                return stack[stack.index(t):] + [t]
            if t not in state and (found := visit(t)):
                return found
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (found := visit(m)):
            return found
    return None


def test_no_import_circles() -> None:
    found = _circle(GRAPH)
    assert found is None, "import circle: " + " -> ".join(found)


def test_the_checker_sees_upward_imports_and_circles(tmp_path, monkeypatch) -> None:
    """The rules can fail: a synthetic module of the runtime importing the synthesis (inside a
    function) is found importing from above, and modules that import each other are a circle."""
    fake = tmp_path / "src" / PKG / "runtime" / "fake.py"
    fake.parent.mkdir(parents=True)
    fake.write_text("def f():\n    from ..synthesis import synthesize\n    from .. import law\n")
    monkeypatch.setattr(__import__(__name__, fromlist=["SRC"]), "SRC", tmp_path / "src")
    found = _imports(fake)
    assert {"robustsynth.synthesis", "robustsynth.law"} <= found
    assert _floor("robustsynth.synthesis") > _floor("robustsynth.runtime.fake")
    assert _circle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _circle({"a": {"b"}, "b": set()}) is None


# -------------------------------------------------------------------------- plant-generic rooms (issue 52)

GENERIC_ROOMS = ("robustsynth.synthesis", "robustsynth.certificate", "robustsynth.verification")
CONCRETE_PLANTS = ("robustsynth.model", "robustsynth.plants")  # the tracked robot's model, the plants
# (the tracked robot's own judges, which do, are the room above: robustsynth.robot_verification)


def _concrete_imports(path: Path) -> list[str]:
    return sorted(i for i in _imports(path) if i.startswith(CONCRETE_PLANTS))


def test_generic_rooms_import_no_concrete_plant() -> None:
    found = {m: _concrete_imports(p) for m, p in MODULES.items() if m.startswith(GENERIC_ROOMS) and _concrete_imports(p)}
    assert not found, f"take the plant through robustsynth.core.plant.Plant instead: {found}"


def test_the_checker_sees_a_generic_room_import_a_plant(tmp_path, monkeypatch) -> None:
    """The rule can fail: a synthetic module of the verification room that imports the robot's model (inside a
    function) is found importing a concrete plant."""
    fake = tmp_path / "src" / PKG / "verification" / "fake.py"
    fake.parent.mkdir(parents=True)
    fake.write_text("def f():\n    from ..model import build_model\n    from ..core.plant import Plant\n")
    monkeypatch.setattr(__import__(__name__, fromlist=["SRC"]), "SRC", tmp_path / "src")
    assert _concrete_imports(fake) == ["robustsynth.model"]


# -------------------------------------------------------------------------- sizes (issue 52)

MAX_MODULE_LINES = 800  # a module past this mixes concerns: split it by concern
MAX_FUNCTION_LINES = 120  # a function past this is several steps: name them
MAX_CLI_LINES = 500  # the CLI is options -> one library call -> a printed summary


def _too_long_functions(path: Path) -> list[str]:
    functions = [n for n in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
                 if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
    return [f"{_module_name(path)}.{n.name} ({n.end_lineno - n.lineno + 1} lines)" for n in functions
            if n.end_lineno - n.lineno + 1 > MAX_FUNCTION_LINES]


def test_no_module_function_or_cli_past_its_size() -> None:
    paths = sorted((SRC / PKG).rglob("*.py"))
    long_modules = [f"{_module_name(p)} ({n} lines)" for p in paths
                    if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES]
    long_functions = [f for p in paths for f in _too_long_functions(p)]
    cli = len((SRC / PKG / "cli" / "__init__.py").read_text(encoding="utf-8").splitlines())
    assert not long_modules, f"modules over {MAX_MODULE_LINES} lines: {long_modules}"
    assert not long_functions, f"functions over {MAX_FUNCTION_LINES} lines: {long_functions}"
    assert cli <= MAX_CLI_LINES, f"the CLI's commands module has {cli} lines (at most {MAX_CLI_LINES})"


def test_the_size_rule_sees_a_long_function(tmp_path, monkeypatch) -> None:
    """The rule can fail: a synthetic module with a function one line past the limit is found."""
    fake = tmp_path / "src" / PKG / "fake.py"
    fake.parent.mkdir(parents=True)
    monkeypatch.setattr(__import__(__name__, fromlist=["SRC"]), "SRC", tmp_path / "src")
    fake.write_text("def f():\n" + "    x = 1\n" * MAX_FUNCTION_LINES)
    assert _too_long_functions(fake) == [f"{PKG}.fake.f ({MAX_FUNCTION_LINES + 1} lines)"]
