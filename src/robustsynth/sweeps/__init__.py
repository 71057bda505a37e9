"""Design-space sweeps: a base config, axes over dotted config keys, one certified synthesis (and
optionally a verification) per point, on one machine or a Dask cluster.

``sweep(load_sweep("configs/sweeps/delay-slip.yaml"), "results/sweeps/delay-slip")`` returns a
:class:`SweepResult` whose ``rows`` are plain dicts (the CSV's rows); pandas is not needed.
"""

from __future__ import annotations

from .run import SweepResult, run_point, sweep
from .spec import SweepSpec, load_sweep, parse_sweep

__all__ = ["SweepSpec", "SweepResult", "load_sweep", "parse_sweep", "sweep", "run_point"]
