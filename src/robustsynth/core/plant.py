"""What the plant-generic core asks of a plant (issue 52: one house for every plant).

A plant closed over the network is, for the certificates, its **lifted map**: over one sampling
period the state ``xi_k = (x_k, u_{k-1}, ..., u_{k-d_hi}, extra_k)`` (the plant's state, the commands
still in flight, and any extra states such as integrators) moves to

    xi_{k+1} = A~(s~, theta) xi_k + B~(s~, theta) u_k

for the switching instants ``s~`` of the period (docs/theory.md §3; from the delays by
:func:`robustsynth.core.network.s_tilde_sequence`) and the plant's uncertain parameter ``theta``
(the robot's slip; none for a linear plant).  The plant's rows are exactly the continuous plant
``x' = A_c(theta) x + B_c(theta) u(t)`` driven by the command in force (:meth:`Plant.continuous`):
the conformance suite (:func:`robustsynth.core.conformance.check_plant`) integrates that ODE and holds
the lifted map to it, together with the shapes, the shift register of the commands, the network's
depth, the vertex description's coverage and the ``to_dict`` round trip.

The tracked robot's :class:`robustsynth.model.Model` and the linear plant's
:class:`robustsynth.plants.linear.LinearPlant` implement it.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from .network import Network

__all__ = ["Plant"]


@runtime_checkable
class Plant(Protocol):
    """A plant closed over a network: its lifted map and what it is exact for (``plant_kind``, also
    ``to_dict()["kind"]``, names the plant: "tracked-robot", "lti", ...)."""

    @property
    def plant_kind(self) -> str:
        """Which plant this is: what ``robustsynth.synthesize`` and ``robustsynth.verify`` dispatch on, named as
        the objectives name the plants they serve (``robustsynth.objectives.PLANTS``) and the commands their jobs."""

    @property
    def network(self) -> Network:
        """The link its commands cross."""

    @property
    def n_x(self) -> int:
        """The plant's own states (the first rows of the lifted state)."""

    @property
    def n_u(self) -> int:
        """Commands per period."""

    @property
    def d_hi(self) -> int:
        """Commands in flight the lifted state keeps."""

    @property
    def n_s(self) -> int:
        """The lifted state's size: n_x + d_hi n_u + the extra states (last)."""

    def lifted(self, s_tilde: np.ndarray, theta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(A~, B~) for switching instants ``s_tilde[..., d_hi]`` and parameters ``theta[..., n_theta]``,
        shapes (..., n_s, n_s) and (..., n_s, n_u)."""

    def continuous(self, theta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(A_c, B_c) of the continuous plant whose period the lifted map's first n_x rows are, at one
        parameter ``theta`` (n_theta,)."""

    def parameter_corners(self) -> np.ndarray:
        """The corners of the uncertain parameter's box, (n_c, n_theta); (1, 0) for a plant without one."""

    def coverage(self, samples: int = 1000, seed: int = 0) -> dict[str, Any]:
        """The vertex description checked against the exact map on random admissible samples:
        ``{"samples", "passed", ...}``."""

    def to_dict(self) -> dict[str, Any]:
        """The plant as plain JSON data with its ``kind`` (what a record of the plant holds; the conformance
        suite holds it to a JSON round trip)."""
