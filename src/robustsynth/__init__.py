"""robustsynth: certified robust controllers for a skid-slip tracked robot driven over a network.

The public API reads as a table of contents (each name is imported lazily from its module, so
``import robustsynth`` stays cheap):

=====================  ============================  ==========================================
name                   module                        what
=====================  ============================  ==========================================
load_config            robustsynth.config            YAML file -> validated frozen Config
parse_config           robustsynth.config            YAML text -> Config
default_config         robustsynth.config            embedded default with dotted-path overrides
Config                 robustsynth.config            the scenario (robot, network, slip, ...)
build_model            robustsynth.model             Config -> lifted norm-bounded Model
Model                  robustsynth.model             eqs. 25, 31-33 with its Delta structure
Network                robustsynth.core.network      the link: delay range, loss cap, every sequence
Plant                  robustsynth.core.plant        what the core asks of a plant (a protocol)
check_plant            robustsynth.core.conformance  the conformance suite every plant passes
LinearPlant            robustsynth.plants.linear     any linear plant over the network, as a Plant
synthesize             robustsynth.synthesis         any plant (Model, LinearPlant) -> certified gain
check_certificate      robustsynth.certificate       numpy-only re-check of an LMI certificate
verify                 robustsynth.verification      any plant's gain -> its checks (Monte Carlo, ...)
load_gains             robustsynth.artifacts.gains   gains.json / .mat -> mapping (one-line errors)
run                    robustsynth.pipeline          any plant's config: synthesize -> verify -> report
margin                 robustsynth.margins           any plant's gain -> its margins (delay, losses, slip)
sweep                  robustsynth.sweeps            synthesize (and verify) over a grid of keys
load_sweep             robustsynth.sweeps            sweep YAML file -> SweepSpec
Controller             robustsynth.runtime           the deployed control law (one robot, no numpy)
to_statespace          robustsynth.interop           closed loop as a python-control StateSpace
lti_config             robustsynth.interop           python-control StateSpace -> plant: kind: lti config
lti_plant              robustsynth.model.lti         lti config -> the plant's arrays (A, B, E, C, limits)
synthesize_lti         robustsynth.synthesis.lti     (deprecated: synthesize(LinearPlant))
verify_lti             robustsynth.verification.lti  (deprecated: verify(LinearPlant, design))
lti_margins            robustsynth.margins.linear    (deprecated: margin(LinearPlant))
=====================  ============================  ==========================================
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

__version__ = "0.1.0"

_EXPORTS = {
    "load_config": "robustsynth.config",
    "parse_config": "robustsynth.config",
    "default_config": "robustsynth.config",
    "Config": "robustsynth.config",
    "build_model": "robustsynth.model",
    "Model": "robustsynth.model",
    "Network": "robustsynth.core.network",
    "Plant": "robustsynth.core.plant",
    "check_plant": "robustsynth.core.conformance",
    "LinearPlant": "robustsynth.plants.linear",
    "synthesize": "robustsynth.synthesis",
    "SynthesisResult": "robustsynth.synthesis",
    "check_certificate": "robustsynth.certificate",
    "verify": "robustsynth.verification",
    "load_gains": "robustsynth.artifacts.gains",
    "run": "robustsynth.pipeline",
    "margin": "robustsynth.margins",
    "MarginReport": "robustsynth.margins",
    "sweep": "robustsynth.sweeps",
    "load_sweep": "robustsynth.sweeps",
    "SweepResult": "robustsynth.sweeps",
    "Controller": "robustsynth.runtime",
    "to_statespace": "robustsynth.interop",
    "lti_config": "robustsynth.interop",
    "lti_plant": "robustsynth.model.lti",
    "synthesize_lti": "robustsynth.synthesis.lti",
    "verify_lti": "robustsynth.verification.lti",
    "lti_margins": "robustsynth.margins.linear",
}

__all__ = [*_EXPORTS, "__version__"]


# names that remain one release beside what replaced them (issue 52), with the warning they give
_DEPRECATED = {
    "synthesize_lti": "robustsynth.synthesize_lti is deprecated: use robustsynth.synthesize(LinearPlant(...)), which "
                      "runs the same design (robustsynth.synthesis.lti.synthesize_lti stays)",
    "verify_lti": "robustsynth.verify_lti is deprecated: use robustsynth.verify(LinearPlant(...), design), which runs "
                  "the same checks (robustsynth.verification.lti.verify_lti stays)",
    "lti_margins": "robustsynth.lti_margins is deprecated: use robustsynth.margin(LinearPlant(...), K), which returns "
                   "the same margins as a MarginReport (robustsynth.margins.linear.lti_margins stays)",
}


def __getattr__(name: str) -> Any:
    if name in _DEPRECATED:
        import warnings

        warnings.warn(_DEPRECATED[name], DeprecationWarning, stacklevel=2)
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'robustsynth' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
