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

    def lines(self, model: Any) -> list[str]:
        """What the CLI prints of this result on ``model`` (the plant it was synthesized for): the certified figures in
        the plant's units (the robot's cm and rad, with the nonlinear proof's heading bound and the compensated law's
        condition; a linear plant's outputs, with its lifting), then the notes.  ``synthesize`` adds a linear gain's
        delay margin, which it computes beside the result."""
        from ..artifacts.certified import certified_lines
        from ..artifacts.gains import certified_figures

        if self.plant_kind == "lti":
            record = {"objective": self.objective, "certified": self.certified,
                      "lifting": {"d": (np.shape(self.K)[1] - model.n_x) // model.n_u}}
        else:
            compensation = getattr(model, "compensation", None)
            record = {"objective": self.objective, "certified": certified_figures(self.certified),
                      "certificate": self.certificate,
                      **({"compensation": compensation.to_dict()} if compensation is not None else {})}
        return certified_lines(record) + [f"note: {note}" for note in self.notes]

    def save(self, model: Any, outdir: Any) -> list[Any]:
        """Write gains.json and gains.mat of this result for ``model`` (the plant it was synthesized for) into
        ``outdir`` (atomically, gains.json last): what ``robustsynth synthesize`` writes, without the report (and,
        for a linear plant, without the delay margin the command adds beside it).  A linear plant records its
        config: one built from its matrices has none (InputError)."""
        from ..artifacts.files import commit_files, json_bytes, mat_bytes
        from ..artifacts.gains import gains_dict, gains_mat_vars, lti_gains_dict, lti_gains_mat_vars
        from ..errors import InputError

        if getattr(model, "plant_kind", "tracked-robot") != self.plant_kind:
            raise InputError(f"SynthesisResult.save: this is a {self.plant_kind} plant's gain; the model given is a "
                             f"{getattr(model, 'plant_kind', type(model).__name__)}'s")
        if self.plant_kind == "lti":
            if model.config is None:
                raise InputError("SynthesisResult.save: a linear plant built from its matrices has no config to record "
                                 "in gains.json: build it with LinearPlant.from_config")
            gd = lti_gains_dict(model.config, model.arrays, self)
            mat = lti_gains_mat_vars(gd)
        else:
            gd = gains_dict(model, self)
            mat = gains_mat_vars(gd)
        return commit_files(outdir, {"gains.mat": mat_bytes(mat), "gains.json": json_bytes(gd)}, primary="gains.json")
