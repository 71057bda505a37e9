"""Stages that write files: build-model, synthesize, verify, and ``run`` chaining them.

Each stage is a function from frozen inputs to a frozen result; no printing, no click.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .config import Config
from .model import Model, build_model, coverage_check

__all__ = ["ModelStage", "model_stage", "SynthesisStage", "synthesis_stage", "default_outdir"]

MODEL_FILES = ("model.json", "model.md")
SYNTHESIS_FILES = ("gains.json", "gains.mat", "synthesis.md")
VERIFICATION_FILES = ("verification.json", "verification.md")
RUN_FILES = ("report.md", "summary.json")


def default_outdir(config: Config) -> Path:
    return Path("results") / config.name


@dataclass(frozen=True)
class ModelStage:
    model: Model
    coverage: dict[str, Any]
    files: tuple[Path, ...]


def model_stage(config: Config, outdir: str | Path) -> ModelStage:
    """Build the model, check the embedding's coverage, write model.json and model.md."""
    from .report.artifacts import commit_files, json_bytes
    from .report.model import model_dict, model_markdown

    model = build_model(config)
    cov = coverage_check(model)
    files = {
        "model.md": model_markdown(model, cov).encode("utf-8"),
        "model.json": json_bytes(model_dict(model, cov)),
    }
    written = commit_files(outdir, files, primary="model.json")
    return ModelStage(model, cov, tuple(written))


@dataclass(frozen=True)
class SynthesisStage:
    model: Model
    result: Any  # robustsynth.synthesis.SynthesisResult
    gains: dict[str, Any]
    files: tuple[Path, ...]


def _remove(outdir: Path, names: tuple[str, ...]) -> None:
    for name in names:
        try:
            (outdir / name).unlink()
        except FileNotFoundError:
            pass


def synthesis_stage(model: Model, outdir: str | Path, **overrides: Any) -> SynthesisStage:
    """Synthesize and certify a gain; write gains.json (last), gains.mat, synthesis.md.

    Files that depend on the gain (verification, report) are removed first.  When no certified
    gain is found, the old gain files are removed too, so nothing stale looks current."""
    from .errors import RobustSynthError
    from .report.artifacts import commit_files, json_bytes, mat_bytes
    from .report.synthesis import gains_dict, gains_mat_vars, synthesis_markdown
    from .synthesis import synthesize

    outdir = Path(outdir)
    try:
        result = synthesize(model, **overrides)
    except RobustSynthError:
        if outdir.is_dir():
            _remove(outdir, SYNTHESIS_FILES + VERIFICATION_FILES + RUN_FILES)
        raise
    gd = gains_dict(model, result)
    files = {
        "gains.mat": mat_bytes(gains_mat_vars(gd)),
        "synthesis.md": synthesis_markdown(model, result, gd).encode("utf-8"),
        "gains.json": json_bytes(gd),
    }
    written = commit_files(outdir, files, primary="gains.json", invalidate=VERIFICATION_FILES + RUN_FILES)
    return SynthesisStage(model, result, gd, tuple(written))


ProgressFn = Callable[[int, int], None]
