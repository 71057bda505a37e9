"""The README's code stays true: every ```python block runs, and the quick start's shell block
runs command by command (without `make demo`), each in a scratch directory that sees the repo's
configs/ and committed baselines."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # make test-all / CI (`make test` runs the rest in minutes)

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
BLOCKS = re.findall(r"```(\w+)\n(.*?)```", README, flags=re.S)
PYTHON = [code for lang, code in BLOCKS if lang == "python"]


def _scratch(tmp_path: Path) -> Path:
    (tmp_path / "configs").symlink_to(ROOT / "configs")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "baselines").symlink_to(ROOT / "results" / "baselines")
    return tmp_path


def test_readme_has_the_documented_blocks() -> None:
    assert len(PYTHON) >= 3  # quick start, margins/sweeps, runtime
    assert any("from robustsynth import load_config, build_model, synthesize, verify" in c for c in PYTHON)


@pytest.mark.parametrize("code", PYTHON, ids=[f"python-{i}" for i in range(len(PYTHON))])
def test_python_block_runs(code: str, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(_scratch(tmp_path))
    # as a script would run it (`python file.py`): a block guarded by `if __name__ == "__main__"` runs too
    exec(compile(code, "README.md", "exec"), {"__name__": "__main__"})  # noqa: S102 - our own README


def test_quick_start_shell_block_runs(tmp_path: Path) -> None:
    quick = README[README.index("## Quick start"):]
    shell = re.search(r"```sh\n(.*?)```", quick, flags=re.S).group(1)
    cwd = _scratch(tmp_path)
    ran = 0
    for line in shell.splitlines():
        cmd = line.split("#", 1)[0].strip()
        if not cmd or cmd.startswith("make "):
            continue
        out = None
        if ">" in cmd:
            cmd, target = (part.strip() for part in cmd.split(">", 1))
            out = cwd / target
        argv = shlex.split(cmd)
        assert argv[0] == ".venv/bin/robustsynth", line
        r = subprocess.run([sys.executable, "-m", "robustsynth", *argv[1:]], cwd=cwd, capture_output=True, text=True,
                           env={**os.environ, "PYTHONWARNINGS": "ignore"})
        assert r.returncode == 0, f"{line}\n{r.stdout}\n{r.stderr}"
        if out is not None:
            out.write_text(r.stdout)
        ran += 1
    assert ran == 4
    assert (cwd / "my.yaml").read_text().startswith("# robustsynth default scenario")  # default-config --name
    assert (cwd / "results" / "quick" / "report.md").exists()
    assert (cwd / "results" / "tracks-stability" / "verification.json").exists()  # verify --gains: beside the gain


def test_docs_are_self_contained() -> None:
    """Every reference in the README, docs/ and docstrings points into the repository: no
    ../shared, no math.md or slip-aware.md a user does not have, and every relative link exists."""
    texts = {p: p.read_text(encoding="utf-8") for p in
             [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "src").rglob("*.py")),
              *sorted((ROOT / "experiments").glob("*.*")), *sorted((ROOT / "benchmarks").glob("*.py"))]}
    for p, text in texts.items():
        for outside in ("../shared", "math.md", "slip-aware.md", "style.md"):
            assert outside not in text, f"{p.relative_to(ROOT)} refers to {outside}"
        if p.suffix == ".md":
            for link in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
                if "://" in link or link.startswith(("figures/", "results/")):
                    continue  # web pages; files a run writes
                assert (p.parent / link).exists(), f"{p.relative_to(ROOT)} links to missing {link}"
