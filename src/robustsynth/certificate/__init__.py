"""The **proof checker**: every LMI of a certificate rebuilt in numpy from the values as written and
proven positive definite in verified arithmetic (docs/theory.md §6, §7).

- :mod:`.check`: the checker of the tracked robot's certificates (``check_certificate``,
  ``recheck_gains``) and its result (``CertificateCheck``);
- ``objectives/``: what each objective's certificate proves (a module per objective, its ``rows``; named by the
  objective's descriptor in :mod:`robustsynth.objectives`);
- :mod:`.lmis`: the LMIs at a vertex or a stack of vertices, and their magnitudes;
- :mod:`.rebuild`: the model a certificate's LMIs are written on;
- :mod:`.lyapunov`: the Lyapunov function of a checked certificate (``Lyapunov``, ``lyapunov_of``);
- :mod:`.bounds`: the figures on the set, the heading within a period, the errors between samples;
- :mod:`.turns`: the bounds through each waypoint turn;
- :mod:`.lti`: a linear plant's certificate (vertex blocks, ``check_lti_certificate``, ``recheck_lti``).
"""

from __future__ import annotations

from .check import (CHECK_FRACTION, SYMMETRY_TOL, VARYING_FAILURES, CertificateCheck, check_certificate, recheck_gains,
                    varying_failures)
from .lyapunov import Lyapunov, lyapunov_of

__all__ = ["CHECK_FRACTION", "SYMMETRY_TOL", "VARYING_FAILURES", "varying_failures", "CertificateCheck",
           "check_certificate", "recheck_gains", "Lyapunov", "lyapunov_of"]
