"""Any linear plant ``x' = A x + B u (+ E w)`` closed over a network, as a
:class:`robustsynth.core.plant.Plant` (docs/theory.md §14).

:class:`LinearPlant` holds the plant's arrays (:func:`robustsynth.model.lti.lti_plant`: A, B, the
disturbance E and its bound, the outputs C, the input limits, the names) with its
:class:`~robustsynth.core.network.Network`.  Its lifted map is exact (matrix exponentials of the
augmented matrix); its vertex description is the guaranteed over-approximation of the open loop
(:func:`robustsynth.core.delays.over_approximation` at K = 0, ``pieces`` per instant's range).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.network import Network
from ..core.delays import coverage_check, exact_lifted, lti_depth, over_approximation, pad_lti_gain
from ..model.lti import lti_plant, lti_plant_from

__all__ = ["LinearPlant", "COVERAGE_RECONSTRUCTION_TOL"]

COVERAGE_RECONSTRUCTION_TOL = 1e-10  # |closed loop rebuilt from the decomposition - exact|, absolute


@dataclass(frozen=True, eq=False)
class LinearPlant:
    """A linear plant closed over ``network``: ``arrays`` as :func:`~robustsynth.model.lti.lti_plant` gives
    them, ``pieces`` per switching instant's range in its vertex description; ``settings``: the synthesis
    settings of the config it came from (``LtiSynthesisConfig``; None: a plant built from its matrices), what
    ``robustsynth.synthesize(plant)`` uses unless given others; ``margin_settings``: its ``margin:`` settings
    (``LtiMarginConfig``), what ``robustsynth.margin(plant)`` uses unless given others; ``config``: the config it
    came from, what the pipeline's stages record in their files (``user_config``, as the robot's model has it)."""

    arrays: dict
    network: Network
    pieces: int = 2
    name: str = "lti"
    settings: Any = None
    margin_settings: Any = None
    config: Any = None  # the config it came from (LtiConfig; None: a plant built from its matrices)

    plant_kind = "lti"  # core.plant.Plant: which plant this is (the names of objectives.PLANTS)

    @classmethod
    def from_config(cls, cfg: Any, base_dir: str | None = None) -> LinearPlant:
        """The plant of a ``plant: kind: lti`` config (``plant.file`` read relative to ``base_dir``)."""
        return cls(lti_plant(cfg, base_dir), Network.from_config(cfg), cfg.synthesis.pieces, cfg.name, cfg.synthesis,
                   cfg.margin, cfg)

    @classmethod
    def from_arrays(cls, A: Any, B: Any, network: Network, pieces: int = 2, name: str = "lti", **kw: Any) -> LinearPlant:
        """From the matrices (and ``robustsynth.model.lti.lti_plant_from``'s keywords)."""
        return cls(lti_plant_from(A, B, **kw), network, pieces, name)

    @property
    def user_config(self) -> Any:
        """The config it came from (None: built from its matrices)."""
        return self.config

    @property
    def A(self) -> np.ndarray:
        return self.arrays["A"]

    @property
    def B(self) -> np.ndarray:
        return self.arrays["B"]

    @property
    def n_x(self) -> int:
        return int(self.B.shape[0])

    @property
    def n_u(self) -> int:
        return int(self.B.shape[1])

    @property
    def d_hi(self) -> int:
        net = self.network
        return lti_depth(net.delay_max, net.max_lost, net.sampling_time)

    @property
    def n_s(self) -> int:
        return self.n_x + self.d_hi * self.n_u

    def padded_gain(self, K: np.ndarray) -> np.ndarray:
        """K on a lifting as deep as the network needs, or as its own if deeper (zeros for the commands it
        does not use)."""
        d = max(self.d_hi, (K.shape[1] - self.n_x) // self.n_u)
        return pad_lti_gain(K, self.n_x, self.n_u, d)

    def lifted(self, s_tilde: np.ndarray, theta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The exact lifted open loop (no uncertain parameter: ``theta`` is ignored)."""
        return exact_lifted(self.A, self.B, self.network.sampling_time, s_tilde)

    def continuous(self, theta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        return self.A, self.B

    def parameter_corners(self) -> np.ndarray:
        return np.zeros((1, 0))

    def _open_loop(self) -> tuple[np.ndarray, float, float, float]:
        """K = 0 on the lifted state, Ts, and the instants' delay range with the losses (tau_max + m Ts)."""
        net = self.network
        return (np.zeros((self.n_u, self.n_s)), net.sampling_time, net.delay_min,
                net.delay_max + net.max_lost * net.sampling_time)

    def description(self) -> Any:
        """The open loop's guaranteed over-approximation (``robustsynth.core.delays.over_approximation``
        at K = 0, ``pieces`` per instant's range)."""
        K0, Ts, lo, hi = self._open_loop()
        return over_approximation(self.A, self.B, K0, Ts, lo, hi, self.d_hi, self.pieces)

    def coverage_figures(self, pw: Any, samples: int = 10_000, seed: int = 0) -> dict[str, float]:
        """The description ``pw`` against the exact map at ``samples`` random in-order instants
        (``robustsynth.core.delays.coverage_check``: the worst remainder / bound, and the decomposition's residual)."""
        K0, Ts, lo, hi = self._open_loop()
        return coverage_check(self.A, self.B, K0, Ts, lo, hi, self.d_hi, pw, samples=samples, seed=seed)

    def coverage(self, samples: int = 10_000, seed: int = 0) -> dict[str, Any]:
        """The open loop's over-approximation against the exact map at ``samples`` in-order instants: every
        remainder within its bound (full block and directions) and the decomposition rebuilt exactly."""
        cov = self.coverage_figures(self.description(), samples, seed)
        ok = (cov["remainder_ratio"] <= 1.0 and cov["direction_ratio"] <= 1.0
              and cov["reconstruction"] <= COVERAGE_RECONSTRUCTION_TOL)
        return dict(cov, passed=bool(ok))

    def to_dict(self) -> dict[str, Any]:
        net = self.network
        return {"kind": "lti", "name": self.name, "n_x": self.n_x, "n_u": self.n_u, "d_hi": self.d_hi,
                "A": self.A.tolist(), "B": self.B.tolist(), "sampling_time": net.sampling_time,
                "delay": [net.delay_min, net.delay_max], "max_lost": net.max_lost, "pieces": self.pieces}
