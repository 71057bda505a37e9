"""What every generated controller file shares, whatever the plant: C double literals that read back exactly, the
word that names the controller (certified, UNCERTIFIED, UNVERIFIED) and the header lines that say what it is proven
for and whether it was verified, in text that can stand in any comment."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["_f", "_c_array", "certified_word", "UNVERIFIED_WHY", "comment_safe", "proof_lines"]


def _f(v: float) -> str:
    """A C double literal that reads back as exactly ``v`` (17 significant digits by repr)."""
    v = float(v)
    if not math.isfinite(v):
        raise ValueError(f"non-finite constant {v!r}")
    s = repr(v)
    return s if any(ch in s for ch in ".eE") else s + ".0"


def _c_array(values) -> str:
    """A C array initializer of the doubles ``values`` (:func:`_f` each)."""
    return "{" + ", ".join(_f(v) for v in values) + "}"


def certified_word(d: dict[str, Any]) -> str:
    """How a generated file names its controller: certified only when the gains file carries its certificate's
    figures (a bare K, or a file changed after synthesis, does not); UNVERIFIED first when the description's
    proof (``export_controller``) says this gain's verification failed or is missing (issue 50: a baseline whose
    verification failed was exported as "the certified controller")."""
    word = "certified" if d.get("certified") else "UNCERTIFIED (no certificate that holds for this gain)"
    proof = d.get("proof")
    if isinstance(proof, dict) and (proof.get("verification") or {}).get("status") != "passed":
        return f"UNVERIFIED ({UNVERIFIED_WHY.get(proof['verification'].get('status'), 'not verified')}), {word}"
    return word


UNVERIFIED_WHY = {"failed": "its verification FAILED", "missing": "no verification of this gain",
                  "other-gain": "its verification record is of another gain"}


def comment_safe(text: str) -> str:
    """Text that can stand in a C comment, a Python docstring and a YAML comment line (a path could end any of
    them)."""
    out = str(text).replace("*/", "* /").replace('"""', "'''").replace("\\", "/")
    return " ".join(out.splitlines())


def proof_lines(d: dict[str, Any]) -> list[str]:
    """The header lines that say what the gain is proven for and whether this gain was verified (none when the
    description carries no proof)."""
    proof = d.get("proof")
    if not isinstance(proof, dict):
        return []
    return [comment_safe(f"Proven: {proof['proven']}."), comment_safe(f"Verification: {proof['verified']}.")]
