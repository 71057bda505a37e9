"""The files a command is given, told apart before any work: a file robustsynth wrote given where a config goes,
a linear plant's gain without its config, the config stored in a gains file; and the output directories a
command creates, removed again when it fails and leaves them empty.  Light to import: the gains file's
module is imported where a file is read."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..errors import InputError

__all__ = ["not_a_config", "needs_its_config", "gains_own_config", "check_log_config", "motor_limit", "NewDirs"]


def not_a_config(path: Path, option: str | None = None, command: str | None = None, takes_gains: bool = False) -> None:
    """InputError in one line when the file given as a config is one robustsynth wrote (a gains file given where
    CONFIG goes had printed 18 validation errors, issue 50); nothing when it is not.  ``command``: the command's
    name (None: not run by the CLI); ``takes_gains``: whether it has a --gains option."""
    from .gains import written_by_robustsynth

    found = written_by_robustsynth(path)
    if found is None:
        return
    what, data = found
    where = f"{option}: {path}" if option else str(path)
    inside = " (the config it was made with is stored inside, under 'config')" if isinstance(data.get("config"), dict) else ""
    if what == "gains file":
        if option == "--config" and command == "export":
            raise InputError(f"{where}: this is a gains file, not a config: give it as GAINS (its config is stored inside)")
        if takes_gains:
            raise InputError(f"{where}: this is a gains file, not a config: use --gains {path} (its config is stored inside)")
        cmd = f"`robustsynth {command}`" if command is not None else "this"
        raise InputError(f"{where}: this is a gains file, not a config: {cmd} takes a config YAML (the gain's own "
                         "config is stored inside the gains file, under 'config')")
    raise InputError(f"{where}: this is a {what}, not a config: pass the config YAML{inside}")


def needs_its_config(config: Path | None, gains: Path | None, command: str) -> None:
    """Without CONFIG the tracked robot's default config is used: a linear plant's gains file with it is
    a mistake whose error would speak of the robot's shapes; say what is missing instead."""
    if config is not None or gains is None:
        return
    from .gains import load_gains

    try:
        kind = load_gains(gains).get("kind")
    except (InputError, OSError, ValueError, AttributeError):
        return  # the command's own loading reports what is wrong with the file
    if kind == "lti":
        raise InputError(f"--gains: {gains} is a linear plant's gain (kind: lti): pass its config too "
                         f"(robustsynth {command} CONFIG --gains {gains})")


def gains_own_config(default: Any, gains: Path) -> Any:
    """Without CONFIG: the config stored in the gains file when it is another than the default one (the
    gain's margins against the default robot, network and slip had been reported silently), else ``default``."""
    from ..config import config_to_dict
    from .gains import load_gains, stored_config

    try:
        gd = load_gains(gains)
    except (InputError, OSError):
        return default  # the command's own loading reports what is wrong with the file
    stored = stored_config(gd)  # an invalid one: InputError naming it (review)
    if stored is None or config_to_dict(stored) == config_to_dict(default):
        return default
    return stored


def check_log_config(gains: Path) -> Any:
    """check-log --gains: the tracked robot's config stored in the gains file."""
    from .gains import load_gains, stored_config

    gd = load_gains(gains)
    if gd.get("kind") == "lti":
        raise InputError(f"{gains}: a linear plant's gains (kind: lti); check-log reads the tracked robot's logs")
    cfg = stored_config(gd)
    if cfg is None:
        raise InputError(f"{gains}: config: the gains file holds no config (use --config)")
    return cfg


def motor_limit(given: float | None, cfg: Any) -> float | None:
    """--max-motor-speed, else the config's robot.max_motor_speed: the motors saturate there, and a period
    with a command beyond it says nothing about slip (a review found the verifier's own logs flagged at
    the waypoint turns, commands of 19.7 rad/s against 12); inf: no period skipped."""
    if given is None:
        return cfg.robot.max_motor_speed
    return None if given == float("inf") else given


class NewDirs:
    """The output directories a command creates: removed again if it fails and leaves them empty (review, stop
    47: `synthesize` exiting 3 left one)."""

    def __init__(self) -> None:
        self.dirs: list[Path] = []

    def clear(self) -> None:
        self.dirs.clear()

    def note(self, out: Path) -> Path:
        """Record the directories of ``out`` that do not exist yet (deepest first, so that each is empty when its
        turn comes).  The path is resolved first ('a/ghost/../kept' is 'a/kept', a symlink's '..' its target's
        parent); one the system cannot even look at (too long, no permission) is left to the stage, whose error
        names it."""
        p = Path(os.path.realpath(out))  # symlinks followed, then '..' (as the system resolves it)
        try:
            while not p.exists() and p != p.parent:
                self.dirs.append(p)
                p = p.parent
        except OSError:
            pass
        return out

    def remove_empty(self) -> None:
        for d in self.dirs:
            try:
                d.rmdir()  # only when empty: whatever a stage wrote and kept stays
            except OSError:
                pass
