"""Stages that write files: build-model, synthesize, verify, and ``run`` chaining them.

Each stage is a function from frozen inputs to a frozen result; no printing, no click.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .config import Config
from .model import Model, build_model, coverage_check

__all__ = ["ModelStage", "model_stage", "default_outdir", "MODEL_FILES"]

MODEL_FILES = ("model.json", "model.md")


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


ProgressFn = Callable[[int, int], None]
