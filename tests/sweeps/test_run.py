"""Running sweeps: statuses per point, the files, resuming from points/, identical rows serially,
on local workers and on a real dask.distributed LocalCluster, and a SIGKILL that loses only the
points in flight."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robustsynth.sweeps import load_sweep, sweep

BASE = """name: sweep-base
robot: {gear_radius: 0.09, track_distance: 0.45, max_motor_speed: 12.0}
reference: {speed: 0.5}
network: {sampling_time: 0.1, delay: {min: 0.01, max: 0.08}}
slip: {right: {min: 0.6, max: 1.0}, left: {min: 0.6, max: 1.0}}
synthesis: {alpha_points: 5}
verification: {runs: 5, lifted_runs: 20, lifted_steps: 50, adversarial_runs: 2, adversarial_steps: 50, frozen_grid: 11}
"""
# 2 x 3 points: max < min is invalid; rho_max = 5 cannot hold 0.5 m/s (infeasible, no LMI); the rest certified
SPEC = """base: base.yaml
axes:
  robot.max_motor_speed: [5.0, 12.0]
  network.delay.max: [0.005, 0.04, 0.08]
"""
POLL_S = 0.05  # how often the kill test looks for stored points
WAIT_S = 120.0  # how long it waits for them at most
ORPHAN_S = 10.0  # how long the workers of a killed driver may take to exit


def _no_time(rows):
    return [{k: v for k, v in r.items() if k != "time_s"} for r in rows]


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("sweep")
    (d / "base.yaml").write_text(BASE)
    (d / "s.yaml").write_text(SPEC)
    return d / "s.yaml"


@pytest.fixture(scope="module")
def serial(spec_path, tmp_path_factory):
    return sweep(load_sweep(spec_path), tmp_path_factory.mktemp("serial"), workers=1)


def test_statuses_and_files(serial) -> None:
    rows = serial.rows
    assert [r["status"] for r in rows] == ["invalid", "infeasible", "infeasible", "invalid", "certified", "certified"]
    assert serial.counts == {"certified": 2, "infeasible": 2, "solver-failure": 0, "invalid": 2}
    assert rows[0]["message"].startswith("network.delay.max:")
    assert "rad/s" in rows[1]["message"]
    for r in rows[4:]:
        assert r["e_y_m"] > 0 and r["decay_rate"] < 1 and len(r["gains_id"]) == 64
    out = serial.files[0].parent
    with (out / "sweep.csv").open() as fh:
        table = list(csv.DictReader(fh))
    assert [t["status"] for t in table] == [r["status"] for r in rows]
    assert float(table[5]["e_y_m"]) == rows[5]["e_y_m"]  # full precision in the CSV
    data = json.loads((out / "sweep.json").read_text())
    assert data["rows"] == json.loads(json.dumps(list(rows)))
    assert (out / "sweep.png").stat().st_size > 0
    assert len(list((out / "points").glob("*.json"))) == 4  # invalid points are not stored


def test_a_rerun_reads_stored_points_and_force_recomputes(spec_path, tmp_path) -> None:
    spec = load_sweep(spec_path)
    first = sweep(spec, tmp_path, workers=1)
    stamps = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "points").glob("*.json")}
    again = sweep(spec, tmp_path, workers=1)
    assert again.reused == 4 and again.rows == first.rows
    assert {p.name: p.stat().st_mtime_ns for p in (tmp_path / "points").glob("*.json")} == stamps
    forced = sweep(spec, tmp_path, workers=1, force=True)
    assert forced.reused == 0
    assert _no_time(forced.rows) == _no_time(first.rows)
    assert all(p.stat().st_mtime_ns != stamps[p.name] for p in (tmp_path / "points").glob("*.json"))


def test_local_workers_give_the_serial_rows(spec_path, serial, tmp_path) -> None:
    seen = []
    res = sweep(load_sweep(spec_path), tmp_path, workers=2, progress=lambda *a: seen.append(a))
    assert res.engine == {"kind": "local", "workers": 2}
    assert _no_time(res.rows) == _no_time(serial.rows)
    done = [a[0] for a in seen]
    assert done == sorted(done) and done[-1] == 6 and seen[-1][2] == 4  # 4 points not certified


@pytest.mark.slow
def test_dask_cluster_gives_the_serial_rows(spec_path, serial, tmp_path) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        res = sweep(load_sweep(spec_path), tmp_path, scheduler=cluster.scheduler_address)
    assert res.engine["kind"] == "dask"
    assert _no_time(res.rows) == _no_time(serial.rows)


def test_verify_adds_the_robot_columns(tmp_path, spec_path) -> None:
    (tmp_path / "base.yaml").write_text((spec_path.parent / "base.yaml").read_text())
    (tmp_path / "v.yaml").write_text("base: base.yaml\naxes:\n  network.delay.max: [0.08]\n")
    res = sweep(load_sweep(tmp_path / "v.yaml"), tmp_path / "o", verify_runs=3, workers=1)
    row = res.rows[0]
    assert row["status"] == "certified" and isinstance(row["verified"], bool)
    assert 0 < row["max_e_y_m"]
    if row["verified"]:
        assert row["max_e_y_m"] <= row["e_y_m"]


def _children(pid: int) -> set[int]:
    out: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out |= {int(x) for x in (task / "children").read_text().split()}
        except OSError:
            pass
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")  # a zombie has exited (nobody may reap it in a container)


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_sigkill_loses_only_points_in_flight(tmp_path, workers) -> None:
    """The driver is killed with SIGKILL: stored points are whole, local workers exit with it (no
    orphan finishing its point), and a rerun reuses exactly the stored points."""
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "k.yaml").write_text("base: base.yaml\naxes:\n  network.delay.max: [0.02, 0.03, 0.04, 0.05, 0.06, 0.07]\n")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "robustsynth", "sweep", str(tmp_path / "k.yaml"), "-o", str(out),
                             "--workers", str(workers), "-q"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    t0 = time.monotonic()
    kids: set[int] = set()
    try:
        while len(list((out / "points").glob("*.json"))) < 2:
            assert proc.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() - t0 < WAIT_S
            time.sleep(POLL_S)
        kids = _children(proc.pid)
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    t1 = time.monotonic()
    while any(_alive(k) for k in kids) and time.monotonic() - t1 < ORPHAN_S:
        time.sleep(POLL_S)
    assert not any(_alive(k) for k in kids), "worker processes outlived the killed driver"
    stored = list((out / "points").glob("*.json"))
    for p in stored:
        assert json.loads(p.read_text())["status"] == "certified"  # each file whole (atomic writes)
    assert not (out / "sweep.csv").exists()
    res = sweep(load_sweep(tmp_path / "k.yaml"), out, workers=1)
    assert res.reused == len(stored) and res.counts["certified"] == 6
    assert not list((out / "points").glob(".*.tmp"))


def test_a_row_that_fails_verification_says_which_checks() -> None:
    """Issue 27: the CSV row itself names the failed checks (not only points/<hash>.json)."""
    from robustsynth.sweeps.run import _row

    res = {"status": "certified", "figures": {"ultimate_bound": {"e_x": 1.0, "e_y": 2.29, "e_theta": 2.24}},
           "verification": {"passed": False, "max": {}, "failed_checks": ["nonlinear: max |e_y| <= certified"]},
           "gains_id": "x", "message": "certified |e_theta| <= 2.24 rad lies beyond", "time_s": 1.0}
    row = _row(0, {"network.delay.max": 0.2}, res, "", verify_runs=20)
    assert row["verified"] is False
    assert row["message"].startswith("verification failed: nonlinear: max |e_y| <= certified")
    assert "beyond" in row["message"]


def test_validity_notes_flag_bounds_beyond_the_model() -> None:
    from robustsynth.model import build_model
    from robustsynth.synthesis.design import validity_notes

    from ..conftest import make_config

    m = build_model(make_config())
    assert validity_notes(m, {"ultimate_bound": {"e_x": 0.08, "e_y": 0.044, "e_theta": 0.31}}, {}) == []
    notes = validity_notes(m, {"ultimate_bound": {"e_x": 0.08, "e_y": 2.29, "e_theta": 2.24}}, {})
    assert len(notes) == 2 and "linearization" in notes[0] and "segment" in notes[1]
    # a nonlinear certificate proves its own heading bound: no heading note
    assert len(validity_notes(m, {"ultimate_bound": {"e_x": 0.08, "e_y": 0.04, "e_theta": 0.6}},
                              {"kinematics": "nonlinear"})) == 0
