"""The README's and the docs' code stays true: every ```python block of README.md and docs/ runs, and the
shell blocks run command by command (without `make`), each in a scratch directory that sees the repo's
configs/ and committed baselines: the README's "Your robot", the first tutorial's quick start and the
blocks of RUN (a transcript's output lines compared with the command's); every other shell block is in
NOT_RUN with the reason.  (tests/test_docs.py parses every robustsynth line of every block against the CLI,
and validates every YAML block, in `make test`.)"""

from __future__ import annotations

import glob
import os
import re
import shutil
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


def _scratch(tmp_path: Path, copy_baselines: bool = False) -> Path:
    (tmp_path / "configs").symlink_to(ROOT / "configs")
    (tmp_path / "results").mkdir()
    if copy_baselines:  # commands that write beside a committed gain (margin --gains ...) write into the copy
        shutil.copytree(ROOT / "results" / "baselines", tmp_path / "results" / "baselines")
    else:
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
    """Run a shell block's robustsynth lines (``make`` lines and comments skipped, ``> file`` honoured, globs
    expanded in ``cwd``); in a transcript (``$ `` prompts) the output lines shown must be the command's own.
    How many commands ran."""
    ran = 0
    lines = shell.splitlines()
    transcript = any(line.startswith("$ ") for line in lines)
    for n, line in enumerate(lines):
        if transcript and not line.startswith("$ "):
            continue  # output, compared below
        cmd = line.removeprefix("$ ").split("#", 1)[0].strip()
        if not cmd or cmd.startswith("make "):
            continue
        out = None
        if ">" in cmd:
            cmd, target = (part.strip() for part in cmd.split(">", 1))
            out = cwd / target
        argv = shlex.split(cmd)
        assert argv[0] in (".venv/bin/robustsynth", "robustsynth"), line
        args = [a for arg in argv[1:] for a in (sorted(glob.glob(arg, root_dir=cwd)) or [arg] if "*" in arg else [arg])]
        r = subprocess.run([sys.executable, "-m", "robustsynth", *args], cwd=cwd, capture_output=True, text=True,
                           env={**os.environ, "PYTHONWARNINGS": "ignore"})
        assert r.returncode == 0, f"{line}\n{r.stdout}\n{r.stderr}"
        if out is not None:
            out.write_text(r.stdout)
        if transcript:
            shown = []
            for later in lines[n + 1:]:
                if later.startswith("$ "):
                    break
                shown.append(later.strip())
            got = {x.strip() for x in (r.stdout + r.stderr).splitlines()}
            stale = [x for x in shown if x and x not in got]
            assert not stale, f"{line}: the docs show output it no longer prints: {stale}\n{r.stdout}{r.stderr}"
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


# ------------------------------------------------------------------ the other shell blocks of the docs

def _shell_blocks() -> dict[tuple[str, int], str]:
    out = {}
    for where, text in [("README.md", README), *((str(p), t) for p, t in PAGES.items())]:
        shell = [code for lang, code in re.findall(r"^```(\w+)\n(.*?)^```", text, flags=re.S | re.M)
                 if lang in ("sh", "bash", "console")]
        out.update({(where, i): code for i, code in enumerate(shell)})
    return out


SHELL = _shell_blocks()
# blocks run here, with the number of commands each runs (the README's "your robot" and the first tutorial's
# quick start have tests of their own above)
RUN = {
    ("docs/howto/exports-ros2.md", 0): 4,
    ("docs/howto/margins-sweeps.md", 0): 1,  # a transcript: its output lines are compared
    ("docs/tutorials/linear-plant.md", 0): 4,
    ("docs/tutorials/linear-plant.md", 1): 1,
    ("docs/tutorials/robot-logs.md", 1): 3,
    ("docs/tutorials/robot-logs.md", 2): 1,
}
# blocks not run, and why (tests/test_docs.py still parses each robustsynth line of them against the CLI)
NOT_RUN = {
    ("README.md", 0): "make demo / make test: CI runs make test; the 'your robot' block is make demo's job",
    ("README.md", 1): "run by test_readme_your_robot_block_runs",
    ("docs/index.md", 0): "make demo / make test, as the README's first block",
    ("docs/overview.md", 0): "make demo / make test, as the README's first block",
    ("docs/reference/installing.md", 0): "pip installs outside the Makefile (make install is what the suite runs in)",
    ("docs/tutorials/your-robot.md", 0): "make install, and default-config as the README's 'your robot' runs it",
    ("docs/tutorials/your-robot.md", 1): "run my.yaml --export c: the README's 'your robot' runs the same command",
    ("docs/tutorials/your-robot.md", 2): "run by test_quick_start_shell_block_runs",
    ("docs/tutorials/robot-logs.md", 0): "needs the first tutorial's results/my-robot gain (minutes); the next block runs "
                                         "verify's logs' commands, identify and check-log, on the kinematic robot",
    ("docs/tutorials/robot-logs.md", 3): "a hand merge between its commands; tests/verification/test_validate_physics.py "
                                         "runs this recipe",
    ("docs/howto/runtime-monitor.md", 0): "validate --inject push exits 1 (the push takes the robot beyond its bounds); "
                                          "tests/verification/test_validate_physics.py runs every injection",
    ("docs/howto/slip-compensation.md", 0): "run configs/harsh-compensated.yaml takes about 3 minutes (a robot proof's "
                                            "heading search): the regression re-checks its committed gain, "
                                            "tests/verification/test_compensated.py and test_validate_physics.py run "
                                            "its verification and validation, benchmarks/bench_compensated.py the whole",
}


def test_every_shell_block_is_run_or_says_why_not() -> None:
    assert set(SHELL) == set(RUN) | set(NOT_RUN), (
        f"unclassified: {sorted(set(SHELL) - set(RUN) - set(NOT_RUN))}; gone: {sorted(set(RUN) | set(NOT_RUN) - set(SHELL))}")
    assert not set(RUN) & set(NOT_RUN)


@pytest.mark.parametrize("key", sorted(RUN), ids=[f"{w}-{i}" for w, i in sorted(RUN)])
def test_shell_block_runs(key: tuple[str, int], tmp_path: Path) -> None:
    cwd = _scratch(tmp_path, copy_baselines=True)
    assert _run_shell_block(SHELL[key], cwd) == RUN[key]
