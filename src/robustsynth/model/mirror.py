"""The robot's left/right mirror symmetry (docs/theory.md §6h): which vertex and which Lyapunov matrix a reflection
maps onto which, and with which sign each uncertainty channel maps (:meth:`robustsynth.model.Model.mirror`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .vertices import Vertex

__all__ = ["Mirror", "closure", "find_mirror", "mirror_pairs", "restrict"]


@dataclass(frozen=True)
class Mirror:
    """The left/right mirror symmetry of a model (:meth:`robustsynth.model.Model.mirror`): the reflection's signs on the
    lifted state (``t``) and on the command (``tu``), and the permutations it induces on the vertices
    and on a certificate's Lyapunov matrices (involutions)."""

    t: np.ndarray
    tu: np.ndarray
    vertex: tuple[int, ...]
    lyapunov: tuple[int, ...]
    q_signs: tuple[np.ndarray, ...] = ()  # per vertex: the signs S_i of its uncertainty channels


def _channel_signs(v: Vertex, w: Vertex, t: np.ndarray, tu: np.ndarray, s_w: np.ndarray) -> np.ndarray | None:
    """The sign of each uncertainty channel k with which vertex ``w`` is the mirror image of ``v``
    (``Model.mirror``), or None when some channel maps with neither sign.  A channel's input p (the
    column of B_p) and output q (the rows of C_q, D_q, F_q) must map with the same sign when Delta
    has blocks (d1 I2, d2: its multiplier then maps as S M S); with ``diagonal`` Delta (independent
    scalars in [-1, 1], a diagonal multiplier) they may differ: the mirror then takes delta_k to
    -delta_k, which is as admissible, and the multiplier is unchanged.  Every channel at once: column k of
    each matrix is compared as ``np.allclose`` compares it (:func:`_close_columns`)."""
    Bp, Cq, Dq, F = (np.asarray(x, dtype=float) for x in (v.B_p, v.C_q, v.D_q, v.F))
    images = (t[:, None] * Bp, (Cq * t).T, (Dq * tu).T, (F * s_w).T)  # channel k: column k of each
    targets = (np.asarray(w.B_p, dtype=float), np.asarray(w.C_q, dtype=float).T, np.asarray(w.D_q, dtype=float).T,
               np.asarray(w.F, dtype=float).T)
    parts = [(images[:1], targets[:1]), (images[1:], targets[1:])] if v.diagonal else [(images, targets)]
    out = np.ones(v.n_q)
    for ims, tgs in parts:  # the output's part last: its sign is the channel's (the multiplier maps as S M S)
        plus, minus = (np.logical_and.reduce([_close_columns(tg, s * im) for im, tg in zip(ims, tgs)])
                       for s in (1.0, -1.0))
        if not np.all(plus | minus):
            return None
        out = np.where(plus, 1.0, -1.0)
    return out


def _close_columns(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per column, ``np.allclose(a[:, k], b[:, k])`` at the mirror's tolerances (rtol 1e-10, atol 1e-12)."""
    return np.isclose(a, b, rtol=1e-10, atol=1e-12).all(axis=0)


def mirror_pairs(vertices: Sequence[Vertex], t: np.ndarray, tu: np.ndarray) -> list[int] | None:
    """For vertices without a slip corner of their own (within-period ones), each one's mirror image among them: the
    index j with ``A_j = T A_i T`` and ``B_j = T B_i T_u`` (the mirror's tolerances) in the same ``Vertex.group``, or
    None where one has none."""
    if not len(vertices):
        return []
    A = np.stack([np.asarray(v.A, dtype=float) for v in vertices])
    B = np.stack([np.asarray(v.B, dtype=float) for v in vertices])
    groups = np.array([int(v.group) for v in vertices])  # (a vertex sharing a multiplier maps into its own group)
    tA, tB = t[None, :, None] * A * t[None, None, :], t[None, :, None] * B * tu[None, None, :]
    out = []
    for i in range(len(vertices)):
        hit = np.flatnonzero(np.isclose(A, tA[i], rtol=1e-10, atol=1e-12).all(axis=(1, 2))
                             & np.isclose(B, tB[i], rtol=1e-10, atol=1e-12).all(axis=(1, 2)) & (groups == groups[i]))
        if hit.size == 0:
            return None
        out.append(int(hit[0]))
    return out


def find_mirror(corners: np.ndarray, state_names: Sequence[str], input_names: Sequence[str], n_d: int,
                vertices: Sequence[Vertex], kind: str) -> Mirror | None:
    """The mirror symmetry of a model with slip ``corners`` (rows: mu_r, mu_l, ...), lifted state and command names,
    ``n_d`` delay vertices per slip corner and ``vertices``, for a certificate of ``kind``; None where it has none
    (the conditions are :meth:`robustsynth.model.Model.mirror`'s)."""
    swap = []
    order = [1, 0] + list(range(2, corners.shape[1]))  # the tracks swap; the yaw factor and x_icr stay
    for c in corners:
        hit = np.flatnonzero(np.all(np.abs(corners - c[order]) <= 1e-12, axis=1))
        if hit.size != 1:
            return None
        swap.append(int(hit[0]))
    t = np.array([-1.0 if n.startswith(("e_y", "e_theta", "omega", "int_e_y")) else 1.0 for n in state_names])
    tu = np.array([1.0 if n == "dV" else -1.0 for n in input_names])
    n_base = len(corners) * n_d  # the corner-major vertices; after them, within-period ones (Model.with_cuts)
    sigma = [swap[int(v.corner)] * n_d + i % n_d for i, v in enumerate(vertices[:n_base])]
    extra = mirror_pairs(vertices[n_base:], t, tu)
    if extra is None:
        return None
    sigma += [n_base + j for j in extra]
    close = lambda a, b: bool(_close_columns(a, b).all())  # noqa: E731  (np.allclose of two matrices)
    q_signs = []
    for i, v in enumerate(vertices):
        w = vertices[sigma[i]]
        tE, wE = t[:, None] * np.asarray(v.E, dtype=float), np.asarray(w.E, dtype=float)
        s_w = np.where(_close_columns(wE, tE), 1.0, np.where(_close_columns(wE, -tE), -1.0, 0.0))
        if (i < n_base and int(w.corner) != swap[int(v.corner)]) or w.n_q != v.n_q or w.diagonal != v.diagonal or \
                0.0 in s_w or not (close(w.A, t[:, None] * np.asarray(v.A) * t)
                                   and close(w.B, t[:, None] * np.asarray(v.B) * tu)):
            return None
        signs = _channel_signs(v, w, t, tu, s_w)
        if signs is None:
            return None
        q_signs.append(signs)
    n_c = corners.shape[0]
    if kind == "common":
        lyap = [0]
    elif kind == "slip-dependent":
        lyap = swap
    elif kind == "delay-dependent":
        lyap = [swap[j // n_d] * n_d + j % n_d for j in range(n_c * n_d)]
    else:
        lyap = [swap[j // (n_d * n_d)] * n_d * n_d + j % (n_d * n_d) for j in range(n_c * n_d * n_d)]
    return Mirror(t=t, tu=tu, vertex=tuple(sigma), lyapunov=tuple(lyap), q_signs=tuple(q_signs))


def closure(mirror: Mirror, index: Sequence[int]) -> tuple[int, ...]:
    """The vertices ``index`` (of the model ``mirror`` is of) with their mirror images, sorted."""
    return tuple(sorted(set(int(i) for i in index) | {mirror.vertex[int(i)] for i in index}))


def _exact_columns(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether each column of ``a`` equals the same column of ``b`` or its negative, bit for bit."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all(np.all(a == b, axis=0) | np.all(a == -b, axis=0)))


def _exact_image(v: Vertex, w: Vertex, t: np.ndarray, tu: np.ndarray) -> bool:
    """Whether vertex ``w``'s data are the mirror image of ``v``'s, bit for bit: A and B exactly; each slip input (a
    column of E) with a sign of its own; each channel's input (a column of B_p) up to a sign; and each channel's output
    (a row of C_q, D_q and F together, F's columns with the slip inputs' signs) up to one sign."""
    f = lambda x: np.asarray(x, dtype=float)  # noqa: E731
    if not (np.array_equal(t[:, None] * f(v.A) * t, f(w.A)) and np.array_equal(t[:, None] * f(v.B) * tu, f(w.B))):
        return False
    tE, wE = t[:, None] * f(v.E), f(w.E)
    plus, minus = np.all(tE == wE, axis=0), np.all(tE == -wE, axis=0)
    if not np.all(plus | minus):
        return False
    if not v.n_q:
        return True
    s_w = np.where(plus, 1.0, -1.0)
    out_v = np.hstack([f(v.C_q) * t, f(v.D_q) * tu, f(v.F) * s_w])
    out_w = np.hstack([f(w.C_q), f(w.D_q), f(w.F)])
    return _exact_columns(t[:, None] * f(v.B_p), w.B_p) and _exact_columns(out_v.T, out_w.T)


def restrict(mirror: Mirror, vertices: Sequence[Vertex], index: Sequence[int]) -> Mirror | None:
    """The mirror of the model whose vertices are ``vertices[index]`` (``vertices``: those of the model ``mirror`` is
    of, a common Lyapunov matrix's): the same reflection, its vertex map renumbered within ``index``.  None where
    ``index`` is not closed under the map (:func:`closure`), or where a vertex's data are not their partner's mirror
    image to the last bit (A, B; E, B_p, C_q, D_q, F column by column up to a sign).  ``find_mirror`` accepts images
    within 1e-10; a vertex subset posed mirror-invariant on the strength of it is used to *prove* that no set exists
    (:func:`robustsynth.synthesis.phase1.prove_no_set`, docs/theory.md §6j), so here the images must be exact."""
    if len(mirror.lyapunov) != 1:
        return None
    index = tuple(int(i) for i in index)
    pos = {v: k for k, v in enumerate(index)}
    if len(pos) != len(index) or any(mirror.vertex[i] not in pos for i in index):
        return None
    if not all(_exact_image(vertices[i], vertices[mirror.vertex[i]], mirror.t, mirror.tu) for i in index):
        return None
    return Mirror(t=mirror.t, tu=mirror.tu, vertex=tuple(pos[mirror.vertex[i]] for i in index), lyapunov=mirror.lyapunov,
                  q_signs=tuple(mirror.q_signs[i] for i in index) if mirror.q_signs else ())
