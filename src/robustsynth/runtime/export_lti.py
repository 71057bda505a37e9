"""``robustsynth export`` of a linear plant's gain (``kind: lti`` gains files): the generic law

    u_k = K xi_k,   xi_k = [x_k; u_{k-1}; ...; u_{k-d}]   (the commands this controller sent)

as C99 (rs_lti.h / rs_lti.c, no heap, no libm) or a dependency-free Python module, with the sums
in one fixed order (row by row, state first, then the stored commands oldest last), so both give
the same floats; the tests compile the C code and compare both with numpy's K @ xi."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["lti_export_files", "lti_proven", "LTI_TARGETS"]

LTI_TARGETS = ("c", "python", "json")


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


def _description(gd: dict[str, Any]) -> dict[str, Any]:
    lift = gd["lifting"]
    return {"kind": "lti", "name": gd.get("config", {}).get("name", "lti"), "law": gd["law"], "K": gd["K"],
            "n": int(lift["n"]), "m": int(lift["m"]), "d": int(lift["d"]), "states": lift.get("states"),
            "sampling_time": gd["network"]["sampling_time"], "certified": gd.get("certified"),
            "gains_id": gd.get("gains_id")}


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


def _lifted(d: int) -> str:
    """The lifted state as the generated files write it: [x_k; u_(k-1)] for d = 1, [x_k; u_(k-1); ...; u_(k-d)]
    beyond two (a review found "u_(k-1); ...; u_(k-1)" for d = 1)."""
    if d <= 2:
        return "[x_k; " + "; ".join(f"u_(k-{j})" for j in range(1, d + 1)) + "]"
    return f"[x_k; u_(k-1); ...; u_(k-{d})]"


def _c_files(d: dict[str, Any]) -> dict[str, bytes]:
    n, m, dd = d["n"], d["m"], d["d"]
    K = d["K"]
    width = n + dd * m
    flat = ", ".join(_c_array(row) for row in K)
    proof = "".join(f"\n   {line}" for line in proof_lines(d))
    h = f"""/* rs_lti.h: the {certified_word(d)} law u_k = K xi_k of '{d['name']}' (robustsynth, plant: kind: lti).{proof}
   xi_k = {_lifted(dd)}: the state, then the commands this controller sent, newest first.
   Call rs_lti_step once per sampling instant (every RS_LTI_TS s) with the measured state; send u.
   Bit-identical to the verified law when compiled without floating-point contraction (-ffp-contract=off).
   Do not edit: regenerate with `robustsynth export GAINS --to c`. */
#ifndef RS_LTI_H
#define RS_LTI_H
#define RS_LTI_N {n}
#define RS_LTI_M {m}
#define RS_LTI_D {dd}
#define RS_LTI_TS {_f(d['sampling_time'])}
typedef struct {{ double sent[RS_LTI_D * RS_LTI_M + 1]; }} rs_lti_state;
void rs_lti_reset(rs_lti_state *s);
void rs_lti_step(rs_lti_state *s, const double x[RS_LTI_N], double u[RS_LTI_M]);
#endif
"""
    c = f"""/* rs_lti.c: see rs_lti.h (the {certified_word(d)} law).{proof} */
#include "rs_lti.h"

static const double K[RS_LTI_M][{width}] = {{{flat}}};

void rs_lti_reset(rs_lti_state *s) {{
    for (int i = 0; i < RS_LTI_D * RS_LTI_M + 1; ++i) s->sent[i] = 0.0;
}}

void rs_lti_step(rs_lti_state *s, const double x[RS_LTI_N], double u[RS_LTI_M]) {{
    for (int i = 0; i < RS_LTI_M; ++i) {{
        double acc = 0.0;
        for (int j = 0; j < RS_LTI_N; ++j) acc += K[i][j] * x[j];
        for (int j = 0; j < RS_LTI_D * RS_LTI_M; ++j) acc += K[i][RS_LTI_N + j] * s->sent[j];
        u[i] = acc;
    }}
    for (int j = RS_LTI_D * RS_LTI_M - 1; j >= RS_LTI_M; --j) s->sent[j] = s->sent[j - RS_LTI_M];
    for (int i = 0; i < RS_LTI_M && i < RS_LTI_D * RS_LTI_M; ++i) s->sent[i] = u[i];
}}
"""
    return {"rs_lti.h": h.encode(), "rs_lti.c": c.encode()}


def _python_module(d: dict[str, Any]) -> bytes:
    n, m, dd = d["n"], d["m"], d["d"]
    rows = ",\n    ".join("(" + ", ".join(_f(v) for v in row) + ",)" for row in d["K"])
    proof = "".join(f"\n{line}" for line in proof_lines(d))
    return f'''"""rs_lti.py: the {certified_word(d)} law u_k = K xi_k of '{d['name']}' (robustsynth, plant: kind: lti), no numpy.{proof}

xi_k = {_lifted(dd)}: the state, then the commands this controller sent, newest first.
Call step(x) once per sampling instant (every TS s) and send the commands it returns.
Do not edit: regenerate with `robustsynth export GAINS --to python`.
"""

N, M, D, TS = {n}, {m}, {dd}, {_f(d['sampling_time'])}
K = (
    {rows},
)


class Controller:
    def __init__(self):
        self.reset()

    def reset(self):
        self.sent = [0.0] * (D * M)

    def step(self, x):
        if len(x) != N:
            raise ValueError(f"x: {{len(x)}} values, the plant has {{N}} states")
        u = []
        for i in range(M):
            acc = 0.0
            for j in range(N):
                acc += K[i][j] * x[j]
            for j in range(D * M):
                acc += K[i][N + j] * self.sent[j]
            u.append(acc)
        self.sent = (u + self.sent)[: D * M]
        return u
'''.encode()


def lti_proven(gd: dict[str, Any]) -> str:
    """What a linear plant's certificate is a proof for (the first half of the exports' statement)."""
    if not gd.get("certified"):
        return "no certificate that holds for this gain"
    net = gd.get("network") or {}
    delay, ml = net.get("delay"), net.get("max_consecutive")
    losses = "no packet losses" if not ml else f"up to {int(ml)} consecutive packet losses"
    where = (f" with delays in [{float(delay[0]):g}, {float(delay[1]):g}] s and {losses}"
             if isinstance(delay, (list, tuple)) and len(delay) == 2 and ml is not None else "")
    return (f"certified for the linear plant (plant: kind: lti) on its exactly lifted loop{where}; no slip model "
            "(not the tracked robot)")


def lti_export_files(gd: dict[str, Any], target: str,
                     proof: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, bytes]]:
    """(description, files) of a linear plant's gains mapping for ``target`` (c, python or json); ``proof``
    (``export_controller``): what the gain is proven for and whether it was verified, stated in the files."""
    import json

    from ..errors import InputError

    if target not in LTI_TARGETS:
        raise InputError(f"--to: {target} is for the robot; a linear plant's gain exports to {', '.join(LTI_TARGETS)}")
    try:
        d = _description(gd)
        K = [[float(v) for v in row] for row in d["K"]]
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"gains: not a complete linear plant's gains file ({exc})") from None
    if len(K) != d["m"] or any(len(r) != d["n"] + d["d"] * d["m"] for r in K):
        raise InputError(f"K: must be {d['m']} x {d['n'] + d['d'] * d['m']} (m x (n + d m)) for this lifting")
    d["K"] = K
    if proof is not None:
        d["proof"] = proof
    if target == "c":
        return d, _c_files(d)
    if target == "python":
        return d, {"rs_lti.py": _python_module(d)}
    return d, {"rs_lti.json": (json.dumps(d, indent=2, allow_nan=False) + "\n").encode()}
