"""The options and parameter types the commands share."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click

from ..objectives import names as objective_names
from ._console import _Ctx


class _Objectives(click.Choice):
    """``--objective``: the registry's objectives, read when the option is parsed (:mod:`robustsynth.objectives`:
    one registered after the CLI was built is offered too)."""

    def __init__(self) -> None:
        super().__init__(objective_names())

    @property
    def choices(self):  # noqa: D102
        return objective_names()

    @choices.setter
    def choices(self, _value) -> None:
        pass


FILE = click.Path(dir_okay=False, path_type=Path)


DIR = click.Path(file_okay=False, path_type=Path)


CONFIG_ARG = click.argument("config", required=False, type=FILE)


LOGS_ARG = click.argument("logs", nargs=-1, required=True, type=FILE)


OUTDIR_OPT = click.option("-o", "--outdir", type=DIR, default=None,
                          help="Output directory [default: results/<config name>/].")


GAINS_OUTDIR_OPT = click.option("-o", "--outdir", type=DIR, default=None,
                                help="Output directory [default: the directory of --gains, else results/<config name>/].")


NO_FIGURE_OPT = click.option("--no-plots", is_flag=True, help="Skip the figure.")


class _FiniteNonNeg(click.ParamType):
    """A finite number >= 0 (click's FloatRange lets nan through: a review found --pose-noise nan nan taken)."""

    name = "float"

    def convert(self, value: Any, param: Any, ctx: Any) -> float:
        try:
            x = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not (math.isfinite(x) and x >= 0.0):
            self.fail(f"{value!r} is not a finite number >= 0", param, ctx)
        return x


_FINITE_NONNEG = _FiniteNonNeg()


def _set_flag(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if value and isinstance(ctx.find_object(_Ctx), _Ctx):
        setattr(ctx.find_object(_Ctx), param.name, True)


def _verbosity(fn):
    """-q/--quiet and -v/--verbose also after the subcommand (robustsynth run -q)."""
    fn = click.option("-v", "--verbose", is_flag=True, expose_value=False, callback=_set_flag,
                      help="Print the steps as they run (stderr).")(fn)
    return click.option("-q", "--quiet", is_flag=True, expose_value=False, callback=_set_flag,
                        help="Print nothing but errors.")(fn)


SYNTH_OPTS = [
    click.option("--objective", type=_Objectives(), default=None,
                 help="Override synthesis.objective."),
    click.option("--solver", type=click.Choice(["clarabel", "scs"]), default=None, help="Override synthesis.solver."),
    click.option("--multiplier", type=click.Choice(["structured", "full"]), default=None,
                 help="Override synthesis.multiplier."),
    click.option("--diagnose/--no-diagnose", "diagnose", default=None,
                 help="Re-solve with each constraint relaxed (motor limit, slip range, delay, slip rate) to show "
                      "which one binds [default: when the certified |e_y| exceeds half the track distance]."),
]


def _synth_opts(fn):
    for opt in reversed(SYNTH_OPTS):
        fn = opt(fn)
    return fn


VERIFY_OPTS = [
    click.option("--runs", type=click.IntRange(min=1, max=100_000), default=None, help="Monte Carlo runs [config]."),
    click.option("--seed", type=click.IntRange(min=0), default=None, help="Random seed [config]."),
    click.option("--format", "fmt", type=click.Choice(["png", "pdf", "svg"]), default="png", show_default=True,
                 help="Figure format."),
    click.option("--no-plots", is_flag=True, help="Skip the figures."),
]


def _verify_opts(fn):
    for opt in reversed(VERIFY_OPTS):
        fn = opt(fn)
    return fn

