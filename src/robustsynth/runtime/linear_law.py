"""``robustsynth export`` of a linear plant's gain (``kind: lti`` gains files): the generic law

    u_k = K xi_k,   xi_k = [x_k; u_{k-1}; ...; u_{k-d}]   (the commands this controller sent)

as C99 (rs_lti.h / rs_lti.c, no heap, no libm) or a dependency-free Python module, with the sums
in one fixed order (row by row, state first, then the stored commands oldest last), so both give
the same floats; the tests compile the C code and compare both with numpy's K @ xi."""

from __future__ import annotations

from typing import Any

from .codegen import _c_array, _f, certified_word, proof_lines

__all__ = ["LinearExporter", "lti_proven", "LTI_TARGETS", "foreign_target"]

LTI_TARGETS = ("c", "python", "json")


def foreign_target(target: str | None) -> str | None:
    """Why a linear plant's gain does not export to ``target`` (None: it does, or no target), for the option's line."""
    if target is None or target in LTI_TARGETS:
        return None
    return f"{target} is for the robot; a linear plant's gain exports to {', '.join(LTI_TARGETS)}"


def _description(gd: dict[str, Any]) -> dict[str, Any]:
    lift = gd["lifting"]
    return {"kind": "lti", "name": gd.get("config", {}).get("name", "lti"), "law": gd["law"], "K": gd["K"],
            "n": int(lift["n"]), "m": int(lift["m"]), "d": int(lift["d"]), "states": lift.get("states"),
            "sampling_time": gd["network"]["sampling_time"], "certified": gd.get("certified"),
            "gains_id": gd.get("gains_id")}


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


def _same_plant(gains: dict[str, Any], cfg: Any, config_path: Any) -> None:
    """--config with a linear plant's gains: the config must be a linear plant's with the gains' sizes,
    sampling time and lifting (the exported law has no config of its own to disagree with)."""
    from ..config import is_lti
    from ..core.delays import lti_depth
    from ..errors import InputError

    if not is_lti(cfg):
        raise InputError(f"--config: {config_path} is the tracked robot's; the gains are a linear plant's")
    lift, net = gains["lifting"], cfg.network
    d = lti_depth(net.delay.max, net.dropouts.max_consecutive, net.sampling_time)
    if cfg.plant.A is not None and cfg.plant.B is not None:
        n, m = len(cfg.plant.A), len(cfg.plant.B[0])
        if (n, m) != (int(lift["n"]), int(lift["m"])):
            raise InputError(f"--config: {config_path} has n = {n} states and m = {m} inputs; the gains were made for "
                             f"n = {lift['n']}, m = {lift['m']}")
    if float(net.sampling_time) != float(gains["network"]["sampling_time"]) or d != int(lift["d"]):
        raise InputError(f"--config: {config_path} samples at {net.sampling_time:g} s and lifts {d} commands; the gains "
                         f"were made for {gains['network']['sampling_time']:g} s and {lift['d']}")


class LinearExporter:
    """A linear plant's gain (``kind: lti``) as an exported controller: what ``runtime.export.export_controller``
    asks of a plant kind (the targets it offers, the config it agrees with, its description, what its certificate
    proves, its files)."""

    kind = "lti"
    targets = LTI_TARGETS

    @staticmethod
    def refuse_target(target: str) -> None:
        from ..errors import InputError

        why = foreign_target(target)
        if why is not None:
            raise InputError(f"--to: {why}")

    @staticmethod
    def prepare(gains: dict[str, Any]) -> dict[str, Any]:
        return gains

    check_config = staticmethod(_same_plant)

    @staticmethod
    def description(gains: dict[str, Any], cfg: Any) -> dict[str, Any]:
        """The law's constants from the gains mapping, its shapes checked (InputError naming the key)."""
        from ..errors import InputError

        try:
            d = _description(gains)
            K = [[float(v) for v in row] for row in d["K"]]
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"gains: not a complete linear plant's gains file ({exc})") from None
        if len(K) != d["m"] or any(len(r) != d["n"] + d["d"] * d["m"] for r in K):
            raise InputError(f"K: must be {d['m']} x {d['n'] + d['d'] * d['m']} (m x (n + d m)) for this lifting")
        d["K"] = K
        return d

    @staticmethod
    def proven(gains: dict[str, Any], cfg: Any) -> dict[str, Any]:
        return {"certificate": "lti" if gains.get("certified") else None, "proven": lti_proven(gains)}

    @staticmethod
    def files(d: dict[str, Any], target: str) -> dict[str, bytes]:
        """The files of one target (name -> content)."""
        import json

        if target == "c":
            return _c_files(d)
        if target == "python":
            return {"rs_lti.py": _python_module(d)}
        return {"rs_lti.json": (json.dumps(d, indent=2, allow_nan=False) + "\n").encode()}
