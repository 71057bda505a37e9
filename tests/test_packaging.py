"""The lock (constraints.txt) and pyproject.toml agree: every dependency and extra the package
declares is pinned to one exact version that its declared range admits, so `make test` installs a
combination pyproject allows, and nothing the suite needs is left to the newest release."""

from __future__ import annotations

import re
import tomllib
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;#]+)$")


def _lock() -> dict[str, Version]:
    pins: dict[str, Version] = {}
    for n, raw in enumerate((ROOT / "constraints.txt").read_text().splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        m = PIN.match(line)
        assert m, f"constraints.txt:{n}: not 'name==version': {raw!r}"
        name = canonicalize_name(m.group(1))
        assert name not in pins, f"constraints.txt:{n}: {name} pinned twice"
        pins[name] = Version(m.group(2))
    return pins


def _declared() -> list[Requirement]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = [Requirement(r) for r in project["dependencies"]]
    for extra in project["optional-dependencies"].values():
        reqs += [Requirement(r) for r in extra]
    build = tomllib.loads((ROOT / "pyproject.toml").read_text())["build-system"]["requires"]
    return reqs + [Requirement(r) for r in build if not r.startswith("wheel")]


def test_every_declared_requirement_is_pinned_within_its_range() -> None:
    pins = _lock()
    for req in _declared():
        name = canonicalize_name(req.name)
        assert name in pins, f"{req} is not in constraints.txt"
        assert req.specifier.contains(pins[name], prereleases=True), f"constraints.txt pins {name}=={pins[name]}, outside {req}"
        for extra in req.extras:  # dask[distributed]: what the extra pulls in is pinned too
            for dep in _extra_requirements(req.name, extra):
                assert canonicalize_name(dep.name) in pins, f"{req} needs {dep}, not in constraints.txt"


def _extra_requirements(dist: str, extra: str) -> list[Requirement]:
    """The requirements an installed distribution adds for one of its extras (from its metadata)."""
    out = []
    for raw in metadata.requires(dist) or []:
        r = Requirement(raw)
        if r.marker is not None and "extra" in str(r.marker) and r.marker.evaluate({"extra": extra}):
            out.append(r)
    return out


def test_the_installer_is_pinned_and_the_makefile_installs_through_the_lock() -> None:
    assert "pip" in _lock()
    make = (ROOT / "Makefile").read_text()
    assert "PIP_CONSTRAINT=$(CURDIR)/$(LOCK)" in make and "LOCK   := constraints.txt" in make
    # every install of the project's venv goes through the lock; only test-latest's venv is unpinned
    for line in make.splitlines():
        if "pip install" in line:
            assert line.lstrip().startswith("$(LOCKED)") or "$(LATEST)" in line, line
