"""A sweep file: a base config and axes over dotted config keys.

.. code-block:: yaml

    base: ../default.yaml          # a config path relative to this file; omitted: the embedded default
    axes:                          # dotted config keys
      network.delay.max: [0.04, 0.08, 0.12]
      slip.left.min: {linspace: [0.5, 0.9, 5]}   # also {logspace: [first, last, n]}
    mode: grid                     # grid (every combination, default) or zip (axes in lock-step)
    figure: e_y                    # the heatmap of a 2-D sweep: e_x, e_y, e_theta, rho, decay_rate

Every problem with the file itself (unknown axis key, bad axis values, zip of unequal lengths) is a
:class:`ConfigError` naming the key path, raised before any point runs.  A point whose *values*
make an invalid config is not an error of the file: it becomes a row with status 'invalid'.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..config import Config, check_config_key, is_lti, load_config, read_config_text
from ..errors import ConfigError

__all__ = ["SweepSpec", "parse_sweep", "load_sweep", "FIGURE_KEYS", "MAX_POINTS"]

MAX_POINTS = 100_000
FIGURE_KEYS = ("e_x", "e_y", "e_theta", "rho", "decay_rate", "hinf_gain", "output_bound")
_TOP_KEYS = ("base", "axes", "mode", "figure")


@dataclass(frozen=True)
class SweepSpec:
    base: Config
    base_path: str | None  # as written in the file (None: the embedded default)
    axes: tuple[tuple[str, tuple[Any, ...]], ...]  # (dotted key, values) in file order
    mode: str = "grid"
    figure: str = "e_y"
    source: str = "<sweep>"

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(k for k, _ in self.axes)

    def points(self) -> list[dict[str, Any]]:
        """The points in order: dicts key -> value (grid: the last axis varies fastest)."""
        values = [v for _, v in self.axes]
        combos = itertools.product(*values) if self.mode == "grid" else zip(*values)
        return [dict(zip(self.keys, c)) for c in combos]

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(v) for _, v in self.axes) if self.mode == "grid" else (len(self.axes[0][1]),)

    def to_dict(self) -> dict[str, Any]:
        return {"base": self.base_path, "axes": {k: list(v) for k, v in self.axes}, "mode": self.mode,
                "figure": self.figure}


def _clean(x: float) -> float:
    """Grid values without round-off tails (0.30000000000000004 -> 0.3)."""
    return float(f"{x:.12g}")


def _axis_values(key: str, raw: Any, where: str) -> tuple[Any, ...]:
    path = f"{where}axes.{key}"
    if isinstance(raw, list):
        if not raw:
            raise ConfigError(f"{path}: needs at least one value")
        for v in raw:
            if isinstance(v, (dict, list)):
                raise ConfigError(f"{path}: values must be scalars (got a {type(v).__name__})")
        return tuple(raw)
    if isinstance(raw, dict) and len(raw) == 1:
        (kind, args), = raw.items()
        if kind not in ("linspace", "logspace"):
            raise ConfigError(f"{path}: unknown generator {kind!r} (use a list, linspace or logspace)")
        ok = (isinstance(args, list) and len(args) == 3 and all(isinstance(a, (int, float)) and not isinstance(a, bool)
                                                                for a in args))
        if not ok or not float(args[2]).is_integer() or args[2] < 1:
            raise ConfigError(f"{path}.{kind}: must be [first, last, n] with n a positive integer")
        a, b, n = float(args[0]), float(args[1]), int(args[2])
        if not (np.isfinite(a) and np.isfinite(b)):
            raise ConfigError(f"{path}.{kind}: first and last must be finite")
        if kind == "logspace" and (a <= 0 or b <= 0):
            raise ConfigError(f"{path}.logspace: first and last must be > 0 (they are values, not exponents)")
        if n > MAX_POINTS:
            raise ConfigError(f"{path}.{kind}: at most {MAX_POINTS} values")
        vals = np.linspace(a, b, n) if kind == "linspace" else np.geomspace(a, b, n)
        return tuple(_clean(float(v)) for v in vals)
    raise ConfigError(f"{path}: must be a list of values or {{linspace: [first, last, n]}} / {{logspace: [...]}}")


def parse_sweep(text: str | bytes, source: str = "<sweep>", directory: Path | None = None) -> SweepSpec:
    """Parse a sweep document; ``base`` is resolved relative to ``directory``."""
    where = f"{source}: "
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f"line {mark.line + 1}: " if mark is not None else ""
        raise ConfigError(f"{where}{line}invalid YAML: {getattr(exc, 'problem', None) or exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{where}the document must be a mapping with 'axes'")
    for k in data:
        if k not in _TOP_KEYS:
            raise ConfigError(f"{where}{k}: unknown key (expected {', '.join(_TOP_KEYS)})")
    base_path = data.get("base")
    if base_path is None:
        base = load_config(None)
    else:
        if not isinstance(base_path, str):
            raise ConfigError(f"{where}base: must be a path to a config file")
        p = Path(base_path)
        if not p.is_absolute() and directory is not None:
            p = directory / p
        base = load_config(p)
    mode = data.get("mode", "grid")
    if mode not in ("grid", "zip"):
        raise ConfigError(f"{where}mode: must be grid or zip (got {mode!r})")
    figure = data.get("figure", "e_y")
    if figure not in FIGURE_KEYS:
        raise ConfigError(f"{where}figure: must be one of {', '.join(FIGURE_KEYS)} (got {figure!r})")
    axes_raw = data.get("axes")
    if not isinstance(axes_raw, dict) or not axes_raw:
        raise ConfigError(f"{where}axes: required, a mapping of dotted config keys to values")
    axes = []
    for key, raw in axes_raw.items():
        if not isinstance(key, str):
            raise ConfigError(f"{where}axes: keys must be dotted config keys (got {key!r})")
        try:
            check_config_key(key, type(base))
        except ConfigError as exc:
            raise ConfigError(f"{where}axes.{exc}") from None
        axes.append((key, _axis_values(key, raw, where)))
    if mode == "zip":
        lengths = {k: len(v) for k, v in axes}
        if len(set(lengths.values())) > 1:
            raise ConfigError(f"{where}axes: mode zip needs axes of equal length (got "
                              + ", ".join(f"{k}: {n}" for k, n in lengths.items()) + ")")
    if is_lti(base):
        if figure in ("e_x", "e_y", "e_theta", "rho"):
            figure = "output_bound" if "figure" not in data else figure
        if figure in ("e_x", "e_y", "e_theta", "rho"):
            raise ConfigError(f"{where}figure: {figure} is the robot's; a linear plant's are decay_rate, hinf_gain, "
                              "output_bound")
        if base.plant.file is not None and not Path(base.plant.file).is_absolute():  # workers do not know this file's folder
            folder = Path(base_path).parent if directory is None else directory / Path(base_path).parent
            base = base.model_copy(update={"plant": base.plant.model_copy(
                update={"file": str((folder / base.plant.file).resolve())})})
    elif figure == "output_bound":  # the robot has no outputs of its own (a review found an empty heatmap)
        raise ConfigError(f"{where}figure: output_bound is a linear plant's; the robot's are e_x, e_y, e_theta, rho, "
                          "decay_rate, hinf_gain")
    spec = SweepSpec(base, base_path, tuple(axes), mode, figure, source)
    n = int(np.prod(spec.shape))
    if n > MAX_POINTS:
        raise ConfigError(f"{where}axes: {n} points; at most {MAX_POINTS}")
    return spec


def load_sweep(path: str | Path) -> SweepSpec:
    """Read a sweep file: a base config, the axes (dotted config keys and their values), the mode and
    the figure (docs/howto/margins-sweeps.md).

    Parameters
    ----------
    path : str or Path
        The sweep's YAML file; its ``base`` is read relative to it.

    Returns
    -------
    SweepSpec
        The validated grid (every axis a known config key; the point count within the limit).

    Raises
    ------
    ConfigError
        An unreadable or invalid file, one line naming the key.
    """
    p = Path(path)
    return parse_sweep(read_config_text(p, "sweep file"), str(p), p.parent)
