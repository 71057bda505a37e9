"""The time of one Clarabel solve of an LMI problem, estimated from its structure before the first solve (issue 51).

Clarabel does not factor the LMIs as they are written: it decomposes each PSD cone along the cliques of a chordal
extension of its aggregate sparsity pattern (the entries that some variable or the constant touches) and merges
cliques whose union costs less than the two (its defaults: ``chordal_decomposition_enable``, merge method
``clique_graph``).  The invariance LMIs are sparse: their zero blocks, the diagonal multipliers and diag(beta) split
a 37-row vertex LMI of the issue-51 robot into cliques of at most 10 rows.  Its time per iteration grows with the dense
blocks those cliques put in the KKT system, sum over the cliques of (c(c+1)/2)^2 (and so does the number of
iterations a little: measured, the time grows as that sum to the power GROWTH).

Here the pattern is found by evaluating each PSD constraint's expression at random values of the variables (an entry
is nonzero there with probability one where some variable or constant reaches it), and the decomposition is emulated
(:func:`clique_sizes`: a minimum-degree elimination, its maximal cliques, merged while Clarabel's weight
``T(|C1|)^3 + T(|C2|)^3 - T(|C1 u C2|)^3`` is not negative, T(n) = n(n+1)/2).  Clarabel orders by AMD and merges
over its reduced clique graph, so the cliques are close to its own, not equal: on the issue-51 robot's 108-vertex
linearized problem 301 cones here against its 302.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

__all__ = ["solve_estimate", "clique_sizes", "psd_patterns", "SECONDS_AT_A_MILLION", "GROWTH"]

# Measured (Clarabel's own time, one thread, the machine's other core busy with other work): over ten problems from 12
# to 1440 vertices, 0.3 to 170 s a solve, the time grows as the cliques' dense entries to the power 1.3 (more entries
# also take more iterations: 19-25 on the smallest, 61 on the largest); least squares in logarithms, every problem
# within a factor 1.7 of it (docs/theory/06-lmis.md §6j lists them)
SECONDS_AT_A_MILLION = 2.9  # [s] a solve whose cliques hold 10^6 dense entries, sum of T(c)^2


GROWTH = 1.3  # the time's exponent in the entries


def _tri(n: int) -> int:
    return n * (n + 1) // 2


def psd_patterns(problem: Any, seed: int = 0) -> list[np.ndarray]:
    """The aggregate sparsity pattern (symmetric, the diagonal set) of each PSD constraint of a cvxpy problem:
    its expression evaluated twice at random values of every variable (and of a parameter without a value).  The
    variables' and parameters' values are restored."""
    import cvxpy as cp

    rng = np.random.default_rng(seed)
    psd = [c for c in problem.constraints if isinstance(c, cp.constraints.PSD)]
    leaves = list(problem.variables()) + [p for p in problem.parameters() if p.value is None]
    saved = [(leaf, leaf.value) for leaf in leaves]
    masks = [np.zeros(c.args[0].shape, dtype=bool) for c in psd]
    try:
        for _ in range(2):
            for leaf in leaves:
                x = rng.uniform(0.5, 1.5, leaf.shape) * rng.choice((-1.0, 1.0), leaf.shape)
                if leaf.is_nonneg():
                    x = np.abs(x)
                elif leaf.is_nonpos():
                    x = -np.abs(x)
                elif leaf.attributes.get("PSD") or leaf.attributes.get("NSD"):
                    x = (1.0 if leaf.attributes.get("PSD") else -1.0) * (x @ x.T + np.eye(x.shape[0]))
                leaf.value = leaf.project(x)  # symmetric, diagonal, ... as the leaf is declared
            for mask, c in zip(masks, psd):
                v = np.asarray(c.args[0].value)
                mask |= (v != 0) | (v.T != 0)
    finally:
        for leaf, value in saved:
            leaf.value = value
    for mask in masks:
        np.fill_diagonal(mask, True)
    return masks


@lru_cache(maxsize=256)
def _cliques_of(n: int, packed: bytes) -> tuple[int, ...]:
    mask = np.unpackbits(np.frombuffer(packed, dtype=np.uint8))[: n * n].reshape(n, n).astype(bool)
    return clique_sizes(mask)


def clique_sizes(mask: np.ndarray) -> tuple[int, ...]:
    """The sizes of the cliques a PSD cone of this sparsity pattern is decomposed into (largest first; the cone's own
    size where the pattern is dense): a minimum-degree elimination gives a chordal extension, its maximal cliques are
    merged while the merge does not cost more (Clarabel's clique-graph weight, between cliques that overlap)."""
    n = mask.shape[0]
    if mask.all():
        return (n,)
    adj = [set(np.flatnonzero(mask[i]).tolist()) - {i} for i in range(n)]
    alive = set(range(n))
    found: set[frozenset[int]] = set()
    while alive:
        v = min(alive, key=lambda u: (len(adj[u]), u))
        nb = adj[v]
        found.add(frozenset(nb | {v}))
        for a in nb:
            adj[a] |= nb - {a}
            adj[a].discard(v)
        alive.remove(v)
    cliques: list[set[int]] = []
    for c in sorted(found, key=len, reverse=True):
        if not any(c <= k for k in cliques):
            cliques.append(set(c))
    while len(cliques) > 1:
        best, pair = -1, None
        for i in range(len(cliques)):
            for j in range(i + 1, len(cliques)):
                if cliques[i] & cliques[j]:
                    w = _tri(len(cliques[i])) ** 3 + _tri(len(cliques[j])) ** 3 - _tri(len(cliques[i] | cliques[j])) ** 3
                    if w > best:
                        best, pair = w, (i, j)
        if pair is None:
            break
        i, j = pair
        cliques[i] |= cliques.pop(j)
    return tuple(sorted((len(c) for c in cliques), reverse=True))


def solve_estimate(lp: Any) -> float:
    """A rough time [s] of one Clarabel solve of ``lp`` (an LMIProblem) on a machine like the one the constants were
    measured on: SECONDS_AT_A_MILLION x (E / 10^6)^GROWTH, E the dense entries of the cones Clarabel factors (sum over
    the cliques of every PSD constraint of T(c)^2).  Shown before the first solve, and the refinement's cost rule
    (:data:`~.alpha_search.COSTLY_SOLVE_S`)."""
    entries = 0
    for mask in psd_patterns(lp.problem):
        n = mask.shape[0]
        entries += sum(_tri(c) ** 2 for c in _cliques_of(n, np.packbits(mask).tobytes()))
    return SECONDS_AT_A_MILLION * (entries / 1e6) ** GROWTH
