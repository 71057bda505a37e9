"""The objectives' certificates, one module each (the descriptors: :mod:`robustsynth.objectives`).

A module has one function, ``rows(cert, family, K, X, lyap, mats, checks, figures)``, that the checker
(:func:`robustsynth.certificate.check_certificate`) calls with everything the objectives share rebuilt from the
certificate as written: the gain ``K``, the matrix ``X`` that multiplies the vertices' A (Q or G), the Lyapunov
kind and matrices, the vertex family (its ``items(name, lmi)`` proves an LMI at every vertex condition in verified
arithmetic).  It appends its items to ``checks``, its figures (rounded outwards) to ``figures``, and returns None,
or the failed check when the certificate's own values are out of range.
"""
