"""The README's and the docs' code stays true: every ```python block of README.md and docs/ runs, and the
shell blocks a new user copies first — the README's "Your robot" and the first tutorial's quick start — run
command by command (without `make`), each in a scratch directory that sees the repo's configs/ and
committed baselines.  (tests/test_docs.py parses every other command line the pages show against the CLI,
and validates every YAML block, in `make test`.)"""

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
PAGES = {p.relative_to(ROOT): p.read_text(encoding="utf-8") for p in sorted((ROOT / "docs").rglob("*.md"))
         if "_build" not in p.parts}
TUTORIAL = PAGES[Path("docs/tutorials/your-robot.md")]
BLOCKS = [(str(where), lang, code) for where, text in [("README.md", README), *PAGES.items()]
          for lang, code in re.findall(r"^```(\w+)\n(.*?)^```", text, flags=re.S | re.M)]
PYTHON = [(where, code) for where, lang, code in BLOCKS if lang == "python"]


def _scratch(tmp_path: Path) -> Path:
    (tmp_path / "configs").symlink_to(ROOT / "configs")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "baselines").symlink_to(ROOT / "results" / "baselines")
    return tmp_path


def test_the_docs_have_the_documented_blocks() -> None:
    assert len(PYTHON) >= 4  # quick start (first tutorial), margins/sweeps, exports, runtime monitor
    assert "from robustsynth import load_config, build_model, synthesize, verify" in TUTORIAL


@pytest.mark.parametrize("where, code", PYTHON, ids=[f"{w}-python-{i}" for i, (w, _) in enumerate(PYTHON)])
def test_python_block_runs(where: str, code: str, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(_scratch(tmp_path))
    # as a script would run it (`python file.py`): a block guarded by `if __name__ == "__main__"` runs too
    exec(compile(code, where, "exec"), {"__name__": "__main__"})  # noqa: S102 - our own docs


def _run_shell_block(shell: str, cwd: Path) -> int:
    """Run a shell block's robustsynth lines (``make`` lines skipped, ``> file`` honoured); how many ran."""
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
    return ran


def test_quick_start_shell_block_runs(tmp_path: Path) -> None:
    quick = TUTORIAL[TUTORIAL.index("## Quick start"):]
    shell = re.search(r"```sh\n(.*?)```", quick, flags=re.S).group(1)
    cwd = _scratch(tmp_path)
    assert _run_shell_block(shell, cwd) == 4
    assert (cwd / "my.yaml").read_text().startswith("# robustsynth default scenario")  # default-config --name
    assert (cwd / "results" / "quick" / "report.md").exists()
    assert (cwd / "results" / "tracks-stability" / "verification.json").exists()  # verify --gains: beside the gain


def test_readme_your_robot_block_runs(tmp_path: Path) -> None:
    """The README's "Your robot": a scenario of one's own (the default, unedited), synthesized, verified
    and exported as C (about as long as the demo without its physics episodes)."""
    mine = README[README.index("## Your robot"):]
    shell = re.search(r"```sh\n(.*?)```", mine, flags=re.S).group(1)
    cwd = _scratch(tmp_path)
    assert _run_shell_block(shell, cwd) == 2
    out = cwd / "results" / "my-robot"
    assert (out / "report.md").exists() and (out / "gains.json").exists()
    assert (out / "export" / "rs_controller.c").exists()  # exported: the verdict passed


def test_docs_are_self_contained() -> None:
    """Every reference in the README, docs/ and docstrings points into the repository: no
    ../shared, no math.md or slip-aware.md a user does not have, and every relative link exists."""
    texts = {p: p.read_text(encoding="utf-8") for p in
             [ROOT / "README.md", *(ROOT / p for p in PAGES), *sorted((ROOT / "src").rglob("*.py")),
              *sorted((ROOT / "experiments").glob("*.*")), *sorted((ROOT / "benchmarks").glob("*.py"))]}
    for p, text in texts.items():
        for outside in ("../shared", "math.md", "slip-aware.md", "style.md"):
            assert outside not in text, f"{p.relative_to(ROOT)} refers to {outside}"
        if p.suffix == ".md":
            for link in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
                if "://" in link or link.startswith(("figures/", "results/")):
                    continue  # web pages; files a run writes
                assert (p.parent / link).exists(), f"{p.relative_to(ROOT)} links to missing {link}"
