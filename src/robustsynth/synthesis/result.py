"""The result of a synthesis, any plant: the certified gain, its certificate and its check, and how it was found."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..results import CertificateCheck

__all__ = ["SynthesisResult"]


@dataclass(frozen=True)
class SynthesisResult:
    """A certified gain with its certificate, the figures it proves, and how it was found; the tracked robot's
    (``plant_kind`` "tracked-robot": ``du_k = K xi_k`` on its lifted tracking error) or a linear plant's ("lti":
    ``u_k = K xi_k`` on the lifted state, ``certificate`` holding P, alpha, the multipliers, the vertices, the
    pieces and the numpy proof's record).  ``check`` is the numpy re-check that proved it; ``certified`` its
    figures."""

    K: np.ndarray
    objective: str
    multiplier: str
    certificate: dict[str, Any]
    check: CertificateCheck
    solver: dict[str, Any]
    search: tuple[dict[str, Any], ...]
    timings: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    settings: Any = None  # the synthesis settings it was made with (the config's, with any overrides applied)
    plant_kind: str = "tracked-robot"

    @property
    def certified(self) -> dict[str, Any]:
        """The figures the certificate proves (the check's)."""
        return dict(self.check.figures)

    @property
    def P(self) -> np.ndarray:
        """The certified set's matrix: {xi' P xi <= level} (level 1 for a linear plant; the robot's
        ``certified["ellipsoid_level"]``)."""
        return np.asarray(self.certificate["P"], dtype=float)

    def to_dict(self) -> dict[str, Any]:
        """The result as plain data (arrays as lists): what defines the gain and how it was found (a gains file
        adds the plant, the config and the identifiers: ``robustsynth synthesize`` writes it)."""
        from ..artifacts.files import to_jsonable

        return to_jsonable({"plant_kind": self.plant_kind, "K": self.K, "objective": self.objective,
                            "multiplier": self.multiplier, "certified": self.certified, "certificate": self.certificate,
                            "check": self.check.to_dict(), "solver": self.solver, "search": list(self.search),
                            "timings": self.timings, "notes": list(self.notes)})

    def save(self, model: Any, outdir: Any) -> list[Any]:
        """Write gains.json and gains.mat of this result for ``model`` into ``outdir`` (atomically,
        gains.json last): what ``robustsynth synthesize`` writes, without the report (the tracked robot's; a linear
        plant's gain is written by ``robustsynth synthesize``, whose file records its config)."""
        from ..artifacts.files import commit_files, json_bytes, mat_bytes
        from ..artifacts.gains import gains_dict, gains_mat_vars
        from ..errors import InputError

        if self.plant_kind != "tracked-robot":
            raise InputError(f"SynthesisResult.save: writes the tracked robot's gains; this is a {self.plant_kind} "
                             "plant's (robustsynth synthesize CONFIG writes its gains.json)")
        gd = gains_dict(model, self)
        return commit_files(outdir, {"gains.mat": mat_bytes(gains_mat_vars(gd)), "gains.json": json_bytes(gd)},
                            primary="gains.json")
