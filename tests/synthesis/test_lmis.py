"""The LMI builders' exact reductions (synthesis/lmis.py): heading rows implied by others left out, and many
heading rows as linear rows on a lifted matrix."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.config import load_config
from robustsynth.model import build_model
from robustsynth.synthesis.lmis import implied_rows_left_out

ROUND = 1e-9  # relative: the kept rows' bound carried to the others through float sums


def _worst_ratio(V: np.ndarray, room: np.ndarray, X: np.ndarray) -> np.ndarray:
    """sqrt(v_i X v_i') / room_i: row i's extent on the ellipsoid {xi' X^-1 xi <= 1} against its room."""
    return np.sqrt(np.einsum("ij,jk,ik->i", V, X, V)) / room


@settings(max_examples=40, deadline=None)
@given(st.integers(min_value=0, max_value=2**31 - 1))
def test_the_rows_left_out_hold_on_every_ellipsoid_the_kept_ones_hold_on(seed: int) -> None:
    """Rows built as signed combinations of a few base rows (some with room to spare, some without): on random
    ellipsoids scaled until the kept rows bind, no row left out exceeds its room."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 6))
    base = rng.normal(size=(int(rng.integers(1, 5)), n))
    base_room = rng.uniform(0.2, 1.0, size=len(base))
    rows, rooms = list(base), list(base_room)
    for _ in range(int(rng.integers(1, 12))):
        lam = rng.normal(size=len(base)) * (rng.random(len(base)) < 0.6)
        need = float(np.abs(lam) @ base_room)
        rows.append(lam @ base)
        rooms.append(need * rng.uniform(0.7, 1.5) + 1e-3)  # implied when its room exceeds what the combination needs
    V, room = np.array(rows), np.array(rooms)
    keep = implied_rows_left_out(list(V), list(room))
    assert keep and set(keep) <= set(range(len(V)))
    for _ in range(20):
        L = rng.normal(size=(n, n))
        X = L @ L.T + 1e-3 * np.eye(n)
        X /= np.max(_worst_ratio(V[keep], room[keep], X)) ** 2  # the kept rows bind, none exceeds
        assert np.all(_worst_ratio(V, room, X) <= 1.0 + ROUND)


def test_a_combination_with_room_to_spare_goes_and_a_new_direction_stays() -> None:
    e = np.eye(3)
    rows = [e[0], e[1], 2 * e[0] - e[1], 2 * e[0] - e[1], e[2], e[0] + e[1]]
    rooms = [1.0, 0.5, 2.6, 2.4, 1.0, 1.5]
    # 2 e0 - e1 needs 2 * 1 + 0.5 = 2.5: left out with room 2.6, kept with 2.4; e0 + e1 needs exactly its 1.5 (kept:
    # only rows inside their room by IMPLIED_ROOM go); e2 is a direction no other row has
    assert implied_rows_left_out(rows, rooms) == [0, 1, 3, 4, 5]


def test_the_default_robots_heading_rows_shrink_to_those_that_bound_the_others() -> None:
    """On configs/default.yaml's model at 0.15 rad most heading rows repeat others' break points (measured 217 -> 58),
    and the rows kept bound every row on random ellipsoids scaled to them."""
    from pathlib import Path

    cfg = load_config(Path(__file__).resolve().parents[2] / "configs" / "default.yaml")
    m = build_model(cfg).with_heading_bound(0.15)
    vecs, rooms, seen = [], [], set()
    for ch in m.heading_channels:
        for c, d, off in zip(ch.C_h, ch.D_h, ch.heading_offsets):
            key = np.concatenate([c, d, [off]]).tobytes()
            if key not in seen:
                seen.add(key)
                vecs.append(np.concatenate([c, d]))
                rooms.append(0.15 - float(off))
    keep = implied_rows_left_out(vecs, rooms)
    assert len(keep) < len(vecs) / 2
    V, room = np.array(vecs), np.array(rooms)
    rng = np.random.default_rng(0)
    for _ in range(50):
        L = rng.normal(size=(V.shape[1], V.shape[1]))
        X = L @ L.T + 1e-6 * np.eye(V.shape[1])
        X /= np.max(_worst_ratio(V[keep], room[keep], X)) ** 2
        assert np.all(_worst_ratio(V, room, X) <= 1.0 + ROUND)


def test_beyond_the_cap_every_row_is_kept() -> None:
    """The LPs cost ~n h: past IMPLIED_MAX_ROWS rows none is left out (the icr default at d_hi = 3 has 60 281)."""
    from robustsynth.synthesis.lmis import IMPLIED_MAX_ROWS

    e = np.eye(2)
    rows = [e[0], e[1]] + [e[0] + e[1]] * (IMPLIED_MAX_ROWS - 1)  # every copy implied by the first two
    rooms = [1.0, 1.0] + [10.0] * (IMPLIED_MAX_ROWS - 1)
    assert implied_rows_left_out(rows, rooms) == list(range(IMPLIED_MAX_ROWS + 1))
    assert implied_rows_left_out(rows[:3], rooms[:3]) == [0, 1]


@settings(max_examples=30, deadline=None)
@given(st.integers(min_value=0, max_value=2**31 - 1), st.integers(min_value=2, max_value=4))
def test_the_rows_kept_are_the_extreme_points_qhull_finds(seed: int, dim: int) -> None:
    """Cross-check with an independent method: in general position the rows kept are exactly those whose normalized
    row v_i / room_i is a vertex of the convex hull of every +-v_j / room_j (scipy's qhull), the others lying inside
    it (Clarkson's extreme points against the hull's own)."""
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(seed)
    n = int(rng.integers(dim + 2, 60))
    V = rng.normal(size=(n, dim)) * rng.uniform(0.2, 2.0, size=(n, 1))
    room = rng.uniform(0.5, 2.0, size=n)
    W = V / room[:, None]
    hull = ConvexHull(np.vstack([W, -W]))
    vertices = sorted({int(i) % n for i in hull.vertices})
    # in general position no point sits within the LP's margin IMPLIED_ROOM of the hull's boundary without being a
    # vertex: the points' distance to the facets, relative, is checked so that the draw is a fair one
    inside = [i for i in range(n) if i not in vertices]
    slack = -(hull.equations[:, :-1] @ W[inside].T + hull.equations[:, -1:]) if inside else np.ones((1, 1))
    if inside and float(np.min(slack / -hull.equations[:, -1:])) < 1e-4:
        return  # a point too near the boundary for either method's tolerance: not this test's case
    assert implied_rows_left_out(list(V), list(room)) == vertices


HEADING_AGREE = 1e-6  # relative: two interior-point optima of one feasible set (the solver's tolerance is 1e-9)


def test_the_heading_rows_lifted_to_linear_rows_allow_exactly_what_their_lmis_allow(monkeypatch) -> None:
    """The heading rows as an LMI each (``[[room^2, z R], [R' z', Q]] >= 0``) and as linear rows on one lifted matrix
    (``[[Z, R], [R', Q]] >= 0``, ``z Z z' <= room^2``) describe one set of (Q, Y): the largest value of random linear
    objectives over it agrees, and the lifted optimum satisfies every row's own inequality in numpy."""
    import cvxpy as cp
    from pathlib import Path

    from robustsynth.synthesis import lmis

    cfg = load_config(Path(__file__).resolve().parents[2] / "configs" / "default.yaml")
    m = build_model(cfg).with_heading_bound(0.15)
    rng = np.random.default_rng(1)
    rows = np.array([np.concatenate([c, d]) for ch in m.heading_channels for c, d in zip(ch.C_h, ch.D_h)])
    rooms = np.array([0.15 - float(o) for ch in m.heading_channels for o in ch.heading_offsets])
    for _ in range(3):
        C = rng.normal(size=(m.n_s, m.n_s))
        C = C @ C.T
        D = rng.normal(size=(m.n_u, m.n_s))
        best = {}
        for lift in (10**9, 0):
            monkeypatch.setattr(lmis, "LIFT_ROWS", lift)
            lmis._KEPT.clear()
            lv = lmis._Lyap(m, "common")
            heading = lmis.heading_constraints(m, lv)
            psd = sum(isinstance(c, cp.constraints.PSD) for c in heading)
            assert psd == (1 if lift == 0 else len(heading))  # lifted: one LMI, the rows linear
            cons = heading + [lv.Q << np.eye(m.n_s), cp.abs(lv.Y) <= 1.0]
            prob = cp.Problem(cp.Maximize(cp.trace(C @ lv.Q) + cp.sum(cp.multiply(D, lv.Y))), cons)
            prob.solve(solver=cp.CLARABEL)
            assert prob.status == "optimal"
            best[lift] = prob.value
            if lift == 0:
                Q, Y = lv.Q.value, lv.Y.value
                R = np.vstack([Q, Y])
                extent = np.einsum("ia,ab,ib->i", rows, R @ np.linalg.solve(Q, R.T), rows)
                assert np.all(extent <= rooms**2 * (1.0 + HEADING_AGREE))
        assert abs(best[0] - best[10**9]) <= HEADING_AGREE * max(1.0, abs(best[0]))
