"""The output directory's bookkeeping, every plant's: the files each stage writes, and the files another
config left behind (set aside, never deleted), so that a directory never reads as one run of two configs."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .files import set_aside

__all__ = ["MODEL_FILES", "SYNTHESIS_FILES", "VERIFICATION_FILES", "RUN_FILES", "clear_foreign", "figure_files"]

MODEL_FILES = ("model.json", "model.md")
SYNTHESIS_FILES = ("gains.json", "gains.mat", "synthesis.md")
VERIFICATION_FILES = ("verification.json", "verification.md")
RUN_FILES = ("report.md", "summary.json")


def clear_foreign(outdir: str | Path, config: Any) -> list[str]:
    """Set aside the files another config left in ``outdir``: when its model.json, gains.json or
    summary.json was written for a different config, every file of every stage moves to
    ``outdir/stale/<time>/`` (a foreign model beside an old gain and report would read as one run;
    deleting them had cost a user 14 files, issue 50).  Returns the moved files' new paths."""
    from ..config import config_to_dict

    outdir = Path(outdir)
    mine = config_to_dict(config)
    foreign = False
    for name in ("model.json", "gains.json", "summary.json"):
        try:
            data = json.loads((outdir / name).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        ref = data.get("config") if isinstance(data, dict) else None
        if not isinstance(data, dict):
            foreign = True
        elif name == "summary.json" and "name" in data:  # the robot's summary names its config
            foreign = data["name"] != config.name
        elif isinstance(ref, str):  # a linear plant's model.json and summary.json name theirs
            foreign = ref != config.name
        else:
            foreign = not _same_config(ref, mine)
        if foreign:
            break
    if not foreign:
        return []
    names = list(MODEL_FILES + SYNTHESIS_FILES + VERIFICATION_FILES + RUN_FILES + ("margin.json", "margin.md")
                 + LINEAR_FIGURES)
    if (outdir / "figures").is_dir():
        names += [f"figures/{p.name}" for p in sorted((outdir / "figures").iterdir()) if p.is_file()]
    return list(set_aside(outdir, names, f"they were written for another config than '{config.name}' "
                                         "(a stage of that config wrote into this directory)"))


LINEAR_FIGURES = ("verification.png", "verification.pdf", "verification.svg")  # a linear plant's, beside its files


def figure_files(outdir: str | Path) -> tuple[str, ...]:
    """The verification figures in ``outdir`` (relative names): the robot's in ``figures/``, a linear plant's
    verification.<format> beside the other files."""
    out = Path(outdir)
    fig = out / "figures"
    robot = tuple(f"figures/{p.name}" for p in sorted(fig.iterdir()) if p.is_file() and p.suffix in (".png", ".pdf", ".svg")) \
        if fig.is_dir() else ()
    return robot + tuple(name for name in LINEAR_FIGURES if (out / name).is_file())


def _same_config(stored: Any, mine: dict[str, Any]) -> bool:
    """Whether a stored config dict is this config.  The stored one is read through the config
    model first: a file written before a key existed (``reference.turn_radius``) holds the same
    config as one with the key at its default."""
    from ..config import ConfigError, config_from_dict, config_to_dict

    if stored == mine:
        return True
    if not isinstance(stored, dict):
        return False
    try:
        return config_to_dict(config_from_dict(stored)) == mine
    except (ConfigError, TypeError, ValueError):
        return False
