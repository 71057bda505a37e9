"""A linear plant from its config (``plant: kind: lti``, docs/theory.md §14): the arrays of ``plant:`` (A, B,
the disturbance E and its bound, the outputs C, the input limits, the names, a ``plant.file``) checked and
read, or built from the matrices (:func:`lti_plant_from`).  The mathematics of its lifted model and
over-approximation are every room's: :mod:`robustsynth.core.delays`."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..core.delays import check_lti_gain

__all__ = ["lti_plant", "lti_plant_from", "UNCONTROLLABLE_WARNING"]

# what the console and a margin report say of a plant whose (A, B) is not controllable
UNCONTROLLABLE_WARNING = "warning: plant: (A, B) is not controllable; a stabilizing gain may not exist"
def lti_plant(cfg, base_dir: str | None = None) -> dict:
    """The plant of an lti config as arrays: {"A", "B", "K" (m x n_k), "states", "units",
    "controllable"}.  A ``plant.file`` (.mat or .npz with arrays A and B) is read relative to
    ``base_dir``; its problems raise InputError naming the file and the key.

    Parameters
    ----------
    cfg : LtiConfig
        A linear plant's config.
    base_dir : str or None
        Where ``plant.file`` is read from.

    Returns
    -------
    dict
        The plant's arrays and names (above).
    """
    from pathlib import Path

    from ..errors import InputError, Interrupted

    pl = cfg.plant
    if pl.file is not None:
        path = Path(pl.file) if base_dir is None or Path(pl.file).is_absolute() else Path(base_dir) / pl.file
        try:
            if path.suffix == ".npz":
                import zipfile

                if path.is_file() and not zipfile.is_zipfile(path):  # np.load would read it as a pickle and say so
                    raise InputError(f"plant.file: {path}: cannot read (not an .npz archive: numpy.savez writes one)")
                with np.load(path, allow_pickle=False) as z:
                    data = {k: np.array(z[k]) for k in z.files}
            elif path.suffix == ".mat":
                from scipy.io import loadmat

                data = loadmat(path)
            else:
                raise InputError(f"plant.file: {path}: must be a .mat or .npz file")
        except (InputError, Interrupted):
            raise
        except Exception as exc:  # noqa: BLE001 - a corrupt file raises whatever its reader meets (EOFError on an
            # empty .npz, which click would report as an abort; BadZipFile; scipy's MatReadError)
            raise InputError(f"plant.file: {path}: cannot read ({type(exc).__name__}: {exc})") from None
        for key in ("A", "B"):
            if key not in data:
                have = ", ".join(sorted(k for k in data if not k.startswith("__")))
                raise InputError(f"plant.file: {path}: no array {key!r} (has {have})")
        raw = {k: np.asarray(data[k]) for k in ("A", "B")}
        for k, v in raw.items():
            if v.ndim != 2 or not (np.issubdtype(v.dtype, np.floating) or np.issubdtype(v.dtype, np.integer)):
                raise InputError(f"plant.file: {path}: {k} must be a 2-D array of real numbers (got {v.ndim}-D {v.dtype})")
        A, B = (raw[k].astype(float) for k in ("A", "B"))
        if A.shape[0] != A.shape[1] or B.shape[0] != A.shape[0]:
            raise InputError(f"plant.file: {path}: A must be n x n and B n x m (got {A.shape} and {B.shape})")
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
            raise InputError(f"plant.file: {path}: A and B must be finite")
        for key, names in (("states", pl.states), ("units", pl.units)):
            if names is not None and len(names) != A.shape[0]:
                raise InputError(f"plant.{key}: {len(names)} names for the {A.shape[0]} states of {path}")
    else:
        A, B = np.asarray(pl.A, dtype=float), np.asarray(pl.B, dtype=float)
    n, m = B.shape
    src = f"{pl.file}" if pl.file is not None else "A"
    dist, outs = pl.disturbance, pl.outputs
    if dist is not None and len(dist.E) != n:
        raise InputError(f"plant.disturbance.E: must have n = {n} rows like {src} (got {len(dist.E)})")
    if outs is not None and len(outs.C[0]) != n:
        raise InputError(f"plant.outputs.C: must have n = {n} columns like {src} (got {len(outs.C[0])})")
    if pl.input_limits is not None and len(pl.input_limits) != m:
        raise InputError(f"plant.input_limits: {len(pl.input_limits)} limits for the {m} inputs of {src}")
    K = None
    if cfg.controller is not None:
        K = np.asarray(cfg.controller.gain, dtype=float)
        check_lti_gain(K, n, m, "controller.gain")
    C = names = ounits = scale = None
    if outs is not None:
        C, names, ounits, scale = outs.C, outs.names, outs.units, outs.scale
    _representable(A, cfg.network, src)
    return lti_plant_from(A, B, K=K, E=None if dist is None else dist.E, w_max=None if dist is None else dist.bound,
                          C=C, u_max=pl.input_limits, states=pl.states, units=pl.units, outputs=names,
                          output_units=ounits, scale=scale)


GROWTH_LIMIT = 1e100  # the largest ||e^{A t}|| over the lifted horizon this double-precision pipeline accepts


def _representable(A: np.ndarray, net: Any, src: str) -> None:
    """InputError unless e^{A t} stays finite and below GROWTH_LIMIT over the lifted horizon (the longest
    delay and losses plus a period): beyond it the sampled matrices and their bounds overflow (a review
    found 'SVD did not converge' tracebacks for A of 1e6 and more)."""
    from scipy.linalg import expm

    from ..errors import InputError

    horizon = float(net.delay.max) + (int(net.dropouts.max_consecutive) + 1) * float(net.sampling_time)
    with np.errstate(all="ignore"):
        try:
            phi = expm(A * horizon)
            ok = bool(np.all(np.isfinite(phi))) and float(np.max(np.abs(phi))) < GROWTH_LIMIT
        except (np.linalg.LinAlgError, ValueError, OverflowError):
            ok = False
    if not ok:
        raise InputError(f"plant: e^(A t) of {src} overflows over the lifted horizon t = {horizon:g} s (the delay, the "
                         f"losses and a period; its entries exceed {GROWTH_LIMIT:g}): the plant grows too fast for double "
                         "precision at this sampling; sample faster, or rescale the states' units")


def lti_plant_from(A: Any, B: Any, *, K: Any = None, E: Any = None, w_max: float | None = None, C: Any = None,
                   u_max: Any = None, states: list[str] | None = None, units: list[str] | None = None,
                   outputs: list[str] | None = None, output_units: list[str] | None = None, scale: Any = None) -> dict:
    """The plant as arrays: {"A", "B", "K" (or None), "states", "units", "controllable", "E", "w_max",
    "C", "outputs", "output_units", "scale", "u_max"}; C defaults to every state (with the states' names)."""
    A, B = np.asarray(A, dtype=float), np.asarray(B, dtype=float)
    if A.size == 0 or B.size == 0:
        from ..errors import InputError

        raise InputError(f"plant: A is {A.shape[0]} x {A.shape[-1]} and B {B.shape[0]} x {B.shape[-1]}: the plant needs at "
                         "least one state and one input")
    n, m = B.shape
    states = list(states or [f"x{i + 1}" for i in range(n)])
    units = list(units or ["-"] * n)
    if C is None:
        C, outputs, output_units = np.eye(n), states, units
    C = np.atleast_2d(np.asarray(C, dtype=float))
    p = C.shape[0]
    # A scaled to unit norm: the same rank (each block of the controllability matrix only scales), and no
    # overflow of its powers for a large A (a review found 'SVD did not converge' there)
    An = A / max(float(np.max(np.abs(A))), 1e-300)
    ctrb = np.hstack([np.linalg.matrix_power(An, i) @ B for i in range(n)])
    return {"A": A, "B": B, "K": None if K is None else np.atleast_2d(np.asarray(K, dtype=float)),
            "states": states, "units": units, "controllable": int(np.linalg.matrix_rank(ctrb)) == n,
            "E": None if E is None else np.asarray(E, dtype=float), "w_max": None if w_max is None else float(w_max),
            "C": C, "outputs": list(outputs or [f"y{i + 1}" for i in range(p)]),
            "output_units": list(output_units or ["-"] * p),
            "scale": np.ones(p) if scale is None else np.asarray(scale, dtype=float),
            "u_max": None if u_max is None else np.asarray(u_max, dtype=float)}


