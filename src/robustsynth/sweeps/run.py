"""Run a sweep: one ``synthesize`` (and optionally ``verify``) per point, serially, on local worker
processes or on a ``dask.distributed`` cluster, with every finished point stored at once.

The driver (this process) writes every file; workers only compute and return plain data, so a
Dask cluster needs no shared file system.  ``points/<key>.json`` is written atomically as soon as
a point's result arrives, so an interrupted sweep (even SIGKILL) loses only the points in flight,
and a rerun skips the stored ones.  The key is a hash of the point's resolved config, the
verification runs and the robustsynth version.
"""

from __future__ import annotations

import json
import os
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator

from .. import __version__
from ..config import config_to_dict, config_with
from ..errors import ConfigError, InfeasibleError, InputError, Interrupted, SolverFailure, check_interrupt
from .spec import SweepSpec

__all__ = ["SweepResult", "sweep", "run_point", "point_key"]

# the figures of a row (SI units, named in the column); verification columns follow when --verify
FIGURE_FIELDS = ("e_x_m", "e_y_m", "e_theta_rad", "rho_bound_rad_s", "decay_rate", "hinf_gain", "output_bound")
VERIFY_FIELDS = ("verified", "max_e_x_m", "max_e_y_m", "max_e_theta_rad", "max_rho_rad_s")
STATUSES = ("certified", "infeasible", "solver-failure", "invalid")

ProgressFn = Callable[[int, int, int, float | None], None]  # done, total, not certified so far, eta [s]


def point_key(config_data: dict[str, Any], verify_runs: int | None) -> str:
    import hashlib

    blob = json.dumps({"config": config_data, "verify_runs": verify_runs, "version": __version__},
                      sort_keys=True, separators=(",", ":")).encode("utf-8")
    return hashlib.sha256(blob).hexdigest()[:24]


def run_point(payload: dict[str, Any]) -> dict[str, Any]:
    """Synthesize (and verify) one point; plain data in, plain data out (runs on any worker).

    Returns {key, status, figures, verification, gains, gains_id, message, time_s}.  Only an
    interrupt escapes; every other outcome is a status (a failed synthesis raises, of either plant)."""
    from ..artifacts.files import to_jsonable
    from ..config import is_lti

    t0 = time.perf_counter()
    out: dict[str, Any] = {"key": payload["key"], "status": "", "figures": None, "verification": None,
                           "gains": None, "gains_id": "", "message": ""}
    try:
        (_lti_point if is_lti(payload["config"]) else _robot_point)(payload, out)
    except Interrupted:
        raise
    except InfeasibleError as exc:
        out.update(status="infeasible", message=str(exc))
    except SolverFailure as exc:
        out.update(status="solver-failure", message=str(exc))
    except (ConfigError, InputError) as exc:
        out.update(status="invalid", message=str(exc))
    out["time_s"] = time.perf_counter() - t0
    return to_jsonable(out)


def _robot_point(payload: dict[str, Any], out: dict[str, Any]) -> None:
    """run_point for the tracked robot: synthesize (and verify)."""
    from ..artifacts.files import to_jsonable
    from ..artifacts.gains import gains_dict, gains_id
    from ..config import Config
    from ..model import build_model
    from ..synthesis import synthesize

    cfg = Config.model_validate(payload["config"])
    model = build_model(cfg)
    res = synthesize(model)
    gd = gains_dict(model, res)
    out.update(status="certified", figures=res.certified, gains=to_jsonable(gd), gains_id=gains_id(gd),
               message="; ".join(res.notes))
    runs = payload.get("verify_runs")
    if runs:
        from ..verification import verify

        v = verify(model, gd, runs=runs)
        mx = v.monte_carlo.get("maxima", {})
        out["verification"] = {
            "passed": bool(v.passed),
            "max": {k: (mx.get(k) or {}).get("max") for k in ("e_x", "e_y", "e_theta", "motor_speed")},
            "failed_checks": v.failed_checks,
        }


def _lti_point(payload: dict[str, Any], out: dict[str, Any]) -> None:
    """run_point for a linear plant (plant: kind: lti): synthesize (and verify_lti)."""
    from ..artifacts.files import to_jsonable
    from ..artifacts.gains import gains_id, lti_gains_dict
    from ..config import config_from_dict
    from ..plants.linear import LinearPlant
    from ..synthesis import synthesize

    cfg = config_from_dict(payload["config"])
    lin = LinearPlant.from_config(cfg)
    plant = lin.arrays
    design = synthesize(lin, threads=payload.get("solve_threads"))
    f = design.certified
    bounds = [o["bound"] / s for o, s in zip(f.get("outputs") or (), plant["scale"]) if o.get("bound") is not None]
    gd = lti_gains_dict(cfg, plant, design)
    out.update(status="certified", gains=to_jsonable(gd), gains_id=gains_id(to_jsonable(gd)),
               figures={"decay_rate": f["decay"], "hinf_gain": f.get("hinf_gain"),
                        "output_bound": max(bounds) if bounds else None})
    runs = payload.get("verify_runs")
    if runs:
        from ..verification import verify

        v = verify(lin, design, runs=runs)
        out["verification"] = {"passed": bool(v.passed), "max": {}, "failed_checks": v.failed_checks}


@dataclass(frozen=True)
class SweepResult:
    spec: SweepSpec
    rows: tuple[dict[str, Any], ...]
    columns: tuple[str, ...]
    engine: dict[str, Any]
    files: tuple[Path, ...] = ()
    counts: dict[str, int] = field(default_factory=dict)
    time_s: float = 0.0
    reused: int = 0  # points read from outdir/points/ instead of computed

    def column(self, name: str) -> list[Any]:
        return [r.get(name) for r in self.rows]


def _row(index: int, point: dict[str, Any], res: dict[str, Any] | None, invalid_msg: str,
         verify_runs: int | None) -> dict[str, Any]:
    row: dict[str, Any] = {"index": index, **point}
    if res is None:
        res = {"status": "invalid", "message": invalid_msg, "figures": None, "verification": None, "gains_id": "",
               "time_s": 0.0}
    row["status"] = res["status"]
    f = res.get("figures") or {}
    ub = f.get("ultimate_bound") or {}
    row.update({"e_x_m": ub.get("e_x"), "e_y_m": ub.get("e_y"), "e_theta_rad": ub.get("e_theta"),
                "rho_bound_rad_s": f.get("motor_speed_bound"), "decay_rate": f.get("decay_rate"),
                "hinf_gain": f.get("hinf_gain"), "output_bound": f.get("output_bound")})
    if verify_runs:
        v = res.get("verification") or {}
        mx = v.get("max") or {}
        row.update({"verified": v.get("passed"), "max_e_x_m": mx.get("e_x"), "max_e_y_m": mx.get("e_y"),
                    "max_e_theta_rad": mx.get("e_theta"), "max_rho_rad_s": mx.get("motor_speed")})
    msg = res.get("message", "")
    failed = (res.get("verification") or {}).get("failed_checks") or []
    if failed:  # which checks failed, in the row itself (not only in points/<hash>.json)
        msg = f"verification failed: {'; '.join(failed)}" + (f"; {msg}" if msg else "")
    row.update({"time_s": res.get("time_s"), "gains_id": res.get("gains_id", ""), "message": msg})
    return row


def _columns(spec: SweepSpec, verify_runs: int | None) -> tuple[str, ...]:
    return ("index", *spec.keys, "status", *FIGURE_FIELDS, *(VERIFY_FIELDS if verify_runs else ()),
            "time_s", "gains_id", "message")


# ---------------------------------------------------------------------------------- engines


def _serial(payloads: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
    for p in payloads:
        check_interrupt()
        yield run_point(p)


def _worker_init() -> None:
    # the driver handles Ctrl-C / SIGTERM and stops the pool; a worker must not print a traceback
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with_parent()
    from .. import forked

    forked.BESIDE = False  # the points share the cores already: a verify's checks run one after the other here
    import robustsynth.synthesis  # noqa: F401  (warm: cvxpy and the solvers are imported once per worker)


def _die_with_parent() -> None:
    """Linux: SIGTERM this worker when the driver dies, even by SIGKILL (otherwise an orphaned worker
    would finish its point and linger).  Elsewhere a no-op."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGTERM, 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() == 1:  # the driver died before prctl took effect
        os._exit(1)


def _local(payloads: list[dict[str, Any]], workers: int) -> Iterator[dict[str, Any]]:
    import concurrent.futures as cf
    import multiprocessing as mp

    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"), initializer=_worker_init)
    futures = [pool.submit(run_point, p) for p in payloads]
    try:
        pending = set(futures)
        while pending:
            check_interrupt()
            done, pending = cf.wait(pending, timeout=0.2, return_when=cf.FIRST_COMPLETED)
            for fut in done:
                yield fut.result()
    finally:
        for fut in futures:
            fut.cancel()
        procs = list(getattr(pool, "_processes", {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:  # points in flight are lost, by design (the stored ones are kept)
            if proc.is_alive():
                proc.terminate()
        for proc in procs:
            proc.join(timeout=5)


def _dask(payloads: list[dict[str, Any]], address: str) -> Iterator[dict[str, Any]]:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError("--scheduler needs dask.distributed: pip install 'robustsynth[dask]'") from None
    try:
        client = Client(address, timeout="10s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"--scheduler {address}: cannot connect ({exc})") from None
    try:
        futures = client.map(run_point, payloads, key=[f"robustsynth-point-{p['key']}-{i}" for i, p in enumerate(payloads)],
                             pure=False)
        with client.as_current():
            ac = as_completed(futures)
        for fut in ac:
            check_interrupt()
            yield fut.result()
    finally:
        try:
            client.cancel(futures)  # type: ignore[possibly-undefined]
        except Exception:  # noqa: BLE001 - cleanup of a client that may be half-connected
            pass
        client.close()


# ------------------------------------------------------------------------------------ the sweep


def _load_point(path: Path) -> dict[str, Any] | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None  # unreadable (a foreign file): computed again and overwritten
    return data if isinstance(data, dict) and data.get("status") in STATUSES else None


def sweep(spec: SweepSpec, outdir: str | Path, *, verify_runs: int | None = None, workers: int | None = None,
          scheduler: str | None = None, force: bool = False, progress: ProgressFn | None = None,
          write: bool = True) -> SweepResult:
    """Run every point of ``spec``; write ``outdir/points/``, ``sweep.csv``, ``sweep.json`` (and the
    figure, unless ``write`` is False).  ``workers``: local processes (default: all cores; 1 runs
    in this process); ``scheduler``: the address of a dask.distributed scheduler.

    Parameters
    ----------
    spec : SweepSpec
        The grid (:func:`~robustsynth.sweeps.load_sweep`).
    outdir : str or Path
        Output directory.
    verify_runs : int or None
        Also verify each point with this many Monte Carlo runs.
    workers : int or None
        Local processes (above).
    scheduler : str or None
        A dask.distributed scheduler's address.
    force : bool
        Recompute points whose results exist.
    progress : callable or None
        Called with (points done, points in all, points failed, seconds left or None).
    write : bool
        Write the table, JSON and figure.

    Returns
    -------
    SweepResult
        The rows (one per point), the columns and the files written.
    """
    from ..artifacts.files import atomic_write, json_bytes, make_dir, remove_stale_temps

    t0 = time.perf_counter()
    outdir = make_dir(outdir)
    points_dir = make_dir(outdir / "points")
    remove_stale_temps(outdir)
    remove_stale_temps(points_dir)  # a killed sweep's half-written point
    points = spec.points()
    payloads: dict[int, dict[str, Any]] = {}
    results: dict[int, dict[str, Any] | None] = {}
    invalid: dict[int, str] = {}
    for i, pt in enumerate(points):
        try:
            cfg = config_with(spec.base, pt)
        except ConfigError as exc:
            invalid[i] = str(exc)
            results[i] = None
            continue
        data = config_to_dict(cfg)
        key = point_key(data, verify_runs)
        stored = None if force else _load_point(points_dir / f"{key}.json")
        if stored is not None:
            results[i] = stored
        else:
            payloads[i] = {"key": key, "config": data, "verify_runs": verify_runs}
    # identical configs (e.g. a zip with repeated values) run once
    by_key: dict[str, list[int]] = {}
    for i, p in payloads.items():
        by_key.setdefault(p["key"], []).append(i)
    todo = [payloads[idx[0]] for idx in by_key.values()]
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    serial = not scheduler and (n_workers <= 1 or len(todo) <= 1)
    if not serial:  # a point per worker already fills the cores: each lti line search solves one alpha at a time
        for p in todo:
            p["solve_threads"] = 1
    if scheduler:
        engine = {"kind": "dask", "scheduler": scheduler}
        stream = _dask(todo, scheduler) if todo else iter(())
    elif serial:
        engine = {"kind": "serial", "workers": 1}
        stream = _serial(todo)
    else:
        engine = {"kind": "local", "workers": n_workers}
        stream = _local(todo, n_workers)
    total = len(points)
    done = total - len(payloads)
    bad = sum(1 for r in results.values() if r is None or r.get("status") != "certified")
    t_run = time.perf_counter()
    if progress:
        progress(done, total, bad, None)
    for res in stream:
        if write:
            atomic_write(points_dir / f"{res['key']}.json", json_bytes(res))
        for i in by_key[res["key"]]:
            results[i] = res
            done += 1
            bad += res["status"] != "certified"
        if progress:
            computed = done - (total - len(payloads))
            rate = (time.perf_counter() - t_run) / max(computed, 1)
            progress(done, total, bad, rate * (total - done))
    rows = tuple(_row(i, points[i], results.get(i), invalid.get(i, ""), verify_runs) for i in range(total))
    counts = {s: sum(1 for r in rows if r["status"] == s) for s in STATUSES}
    if verify_runs:  # certified but failing verification: said beside the statuses
        counts["verification-failed"] = sum(1 for r in rows if r["status"] == "certified" and r.get("verified") is False)
    reused = sum(1 for i in results if i not in payloads and i not in invalid)
    result = SweepResult(spec, rows, _columns(spec, verify_runs), engine, (), counts, time.perf_counter() - t0, reused)
    if not write:
        return result
    files = [outdir / "sweep.csv", outdir / "sweep.json"]
    atomic_write(files[0], csv_bytes(result))
    atomic_write(files[1], json_bytes(sweep_dict(result, verify_runs)))
    from ..report.plots import write_sweep_figure

    fig = write_sweep_figure(result, outdir)
    if fig is not None:
        files.append(fig)
    return SweepResult(spec, rows, result.columns, engine, tuple(files), counts, time.perf_counter() - t0, reused)


def csv_bytes(result: SweepResult) -> bytes:
    import csv
    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(result.columns), lineterminator="\n")
    w.writeheader()
    for r in result.rows:
        w.writerow({k: ("" if r.get(k) is None else (repr(r[k]) if isinstance(r[k], float) else r[k]))
                    for k in result.columns})
    return buf.getvalue().encode("utf-8")


def sweep_dict(result: SweepResult, verify_runs: int | None) -> dict[str, Any]:
    return {
        "robustsynth_version": __version__,
        "spec": result.spec.to_dict(),
        "source": result.spec.source,
        "points": len(result.rows),
        "shape": list(result.spec.shape),
        "verify_runs": verify_runs,
        "counts": result.counts,
        "engine": result.engine,
        "columns": list(result.columns),
        "rows": list(result.rows),
    }
