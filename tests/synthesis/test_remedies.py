"""Where no proof for the robot exists, the remedies are tried (robustsynth.synthesis.remedies, issue 49): what
each one changes in the config, and that a figure a quick try reports is one the full search reaches."""

from __future__ import annotations

from pathlib import Path

import pytest

from robustsynth.config import config_to_dict, load_config
from robustsynth.synthesis.remedies import RATE_PERIODS, _merged, candidates

ROOT = Path(__file__).resolve().parents[2]
EXACT = 1e-12  # the changed values are arithmetic on the config's own


def _changed(cfg, change):
    return load_config(_merged(config_to_dict(cfg), change))


def test_each_remedy_changes_what_it_says_and_nothing_else() -> None:
    """tracks-box (slip [0.6, 1] free to jump, straight path): the box half as wide about its centre, a rate that
    crosses it in RATE_PERIODS periods, half the speed; no turn radius to widen.  Every changed config loads, and
    apart from the changed keys it is the config itself.  Its one Lyapunov matrix covers every slip sequence, so the
    rate comes with a matrix per slip corner (synthesis.lyapunov slip-dependent), where it enters the LMIs; a config
    with such matrices already gets the rate alone."""
    cfg = load_config(ROOT / "configs" / "tracks-box.yaml")
    assert cfg.synthesis.lyapunov == "common"
    got = candidates(cfg)
    assert [c[0].split(" ")[0] for c in got] == ["slip", "slip.max_rate", "reference.speed"]
    assert got[1][0].endswith("with synthesis.lyapunov slip-dependent")
    half, rate, speed = (_changed(cfg, c[1]) for c in got)
    for track in ("right", "left"):
        r = getattr(half.slip, track)
        assert abs(r.min - 0.7) <= EXACT and abs(r.max - 0.9) <= EXACT
    assert abs(rate.slip.max_rate - 0.4 / (RATE_PERIODS * cfg.network.sampling_time)) <= EXACT
    assert rate.synthesis.lyapunov == "slip-dependent"
    assert speed.reference.speed == cfg.reference.speed / 2
    base = config_to_dict(cfg)
    for new, keys in ((half, ("slip",)), (rate, ("slip", "synthesis")), (speed, ("reference",))):
        d = config_to_dict(new)
        assert {k for k in base if base[k] != d[k]} == set(keys)
    per_corner = _changed(cfg, {"synthesis": {"lyapunov": "slip-dependent"}})
    alone = dict(candidates(per_corner))
    assert next(v for k, v in alone.items() if k.startswith("slip.max_rate")) == {"slip": {"max_rate": rate.slip.max_rate}}


def test_a_tracks_box_with_a_rate_bound_is_offered_the_compensated_law_first() -> None:
    """tracks-box with slip.max_rate: the slip-compensated law (docs/theory.md §18) is the first remedy, its config
    loads and builds the certificate on the ratio box; a config that compensates already, or an icr one, is not
    offered it, and a compensated model's remedies change the user's config (its true box), not the ratio box."""
    from robustsynth.model import build_model

    cfg = _changed(load_config(ROOT / "configs" / "tracks-box.yaml"), {"slip": {"max_rate": 0.02}})
    got = candidates(cfg)
    assert got[0][0].startswith("slip.compensation") and got[0][1] == {"slip": {"compensation": {"error": "auto"}}}
    comp = _changed(cfg, got[0][1])
    assert build_model(comp).compensation is not None
    assert not any(k.startswith("slip.compensation") for k, _ in candidates(comp))
    assert not any(k.startswith("slip.compensation") for k, _ in candidates(load_config(ROOT / "configs" / "default.yaml")))
    harsh = build_model(load_config(ROOT / "configs" / "harsh-compensated.yaml"))
    half = dict(candidates(harsh.user_config))
    box = next(v for k, v in half.items() if k.startswith("slip half"))["slip"]["right"]
    assert abs(box["min"] - 0.71) <= EXACT and abs(box["max"] - 0.93) <= EXACT  # [0.6, 1.04] halved, not the ratio box


def test_the_icr_box_halves_every_parameter_and_a_turning_path_gets_wider_turns() -> None:
    """The default (icr box, 8 m turns): all four parameters' ranges halved about their centres, turns of 16 m
    (which its path's short segment refuses: the remedy's line then says why); a config that already bounds the
    slip's rate gets no rate remedy."""
    from robustsynth.errors import ConfigError

    cfg = load_config(ROOT / "configs" / "default.yaml")
    got = dict(candidates(cfg))
    half = _changed(cfg, next(v for k, v in got.items() if k.startswith("slip half")))
    for key in ("right", "left", "yaw", "icr_offset"):
        old, new = getattr(cfg.slip, key), getattr(half.slip, key)
        assert abs((new.min + new.max) - (old.min + old.max)) <= EXACT
        assert abs(2 * (new.max - new.min) - (old.max - old.min)) <= EXACT
    wider = next(v for k, v in got.items() if k.startswith("reference.turn_radius"))
    assert wider == {"reference": {"turn_radius": 2 * cfg.reference.turn_radius}}
    with pytest.raises(ConfigError, match="reference.path: with reference.turn_radius 16 m"):
        _changed(cfg, wider)
    rated = _changed(cfg, next(v for k, v in got.items() if k.startswith("slip.max_rate")))
    assert not any(k.startswith("slip.max_rate") for k, _ in candidates(rated))


@pytest.mark.slow  # three syntheses of the tracks box: about a minute and a half
def test_an_exit_3_names_the_remedies_tried_and_their_figures_hold() -> None:
    """tracks-box with nonlinear kinematics has no robot proof: the exit-3 message says what each remedy gave
    at the first try, on one line; the half-wide box is proven there, and the full search on that box reaches
    that figure or better (the quick try's is one point of the full search's space)."""
    import re

    from robustsynth.errors import InfeasibleError
    from robustsynth.model import build_model
    from robustsynth.synthesis import synthesize

    cfg = load_config(ROOT / "configs" / "tracks-box.yaml")
    nl = load_config(_merged(config_to_dict(cfg), {"synthesis": {"kinematics": "nonlinear", "heading_bound": "auto"}}))
    with pytest.raises(InfeasibleError) as info:
        synthesize(build_model(nl))
    msg = str(info.value)
    assert "\n" not in msg and ". Tried (" in msg
    found = re.search(r"slip half as wide \([^)]*\): proven for the robot, \|e_y\| <= ([0-9.]+) cm at the first try", msg)
    assert found, msg
    for what, _ in candidates(nl):
        assert what in msg
    half = next(v for k, v in candidates(nl) if k.startswith("slip half"))
    full = synthesize(build_model(_changed(nl, half)))
    assert full.check.passed
    assert 100 * full.check.figures["ultimate_bound"]["e_y"] <= float(found.group(1)) + 0.005  # the message's 2 decimals


def test_each_try_gets_its_share_of_what_is_left_of_the_budget(monkeypatch) -> None:
    """try_remedies on a clock of its own (no time measured): each try's deadline is what is left of the budget over
    the remedies still to try, so a try that runs to its deadline leaves the later ones their turn; the bounds a try
    left untried are named; a try is not started where what is left is shorter than the longest try so far; once the
    budget is spent a remedy is named, not tried."""
    from robustsynth.model import build_model
    from robustsynth.synthesis import remedies

    clock = [100.0]
    monkeypatch.setattr(remedies.time, "perf_counter", lambda: clock[0])
    # a Lyapunov matrix per slip corner: its rate remedy is tried too (three tries)
    model = build_model(_changed(load_config(ROOT / "configs" / "tracks-box.yaml"), {"synthesis": {"lyapunov": "slip-dependent"}}))
    deadlines = []

    def slow(m, deadline, say):  # runs to its deadline (and a second beyond), untried bounds left
        deadlines.append(deadline)
        clock[0] = deadline + 1.0
        return None, (0.5, 0.7)

    lines = remedies.try_remedies(model, slow, lambda _m: None, budget_s=60.0, workers=1)
    assert len(deadlines) == 2 and len(lines) == 3
    assert deadlines[0] == 100.0 + 60.0 / 3 and deadlines[1] == 121.0 + (60.0 - 21.0) / 2
    assert all("none at the first try (heading bounds 0.5, 0.7 rad not tried" in line for line in lines[:2])
    # the tries took 21 and 20.5 s: the 18.5 s left hold no third
    assert lines[2].endswith("not tried (a try took up to 21 s here; 18 s of the tries' 60 s were left)"), lines[2]

    def quick(m, deadline, say):  # 10 s each: all three fit
        deadlines.append(deadline)
        clock[0] += 10.0
        return None, ()

    deadlines.clear()
    lines = remedies.try_remedies(model, quick, lambda _m: None, budget_s=60.0, workers=1)
    assert len(deadlines) == 3 and all(line.endswith("none at the first try") for line in lines)

    def hog(m, deadline, say):  # the first try takes the whole budget
        clock[0] += 61.0
        return None, ()

    lines = remedies.try_remedies(model, hog, lambda _m: None, budget_s=60.0, workers=1)
    assert lines[0].endswith("none at the first try") and all("not tried (the tries' 60 s were spent)" in x for x in lines[1:])


def test_where_the_start_s_solves_are_slow_each_remedy_is_named_with_why() -> None:
    """try_remedies with ``skip`` (the search's reason: its start's solves are estimated at COSTLY_SOLVE_S or more)
    starts no try: every remedy is named with that reason, and one the config refuses is named as refused."""
    from robustsynth.model import build_model
    from robustsynth.synthesis import remedies

    def never(m, deadline, say):
        raise AssertionError("a try was started")

    model = build_model(load_config(ROOT / "configs" / "tracks-box.yaml"))
    lines = remedies.try_remedies(model, never, lambda _m: None, skip="slow here")
    assert len(lines) == len(candidates(model.user_config)) == 3
    assert lines[0].endswith(": not tried (slow here)"), lines  # said once, then referred to
    assert all(line.endswith(": not tried (the same)") for line in lines[1:]), lines
    default = build_model(load_config(ROOT / "configs" / "default.yaml"))  # its turns of 16 m do not fit the path
    lines = remedies.try_remedies(default, never, lambda _m: None, skip="slow here")
    assert lines[-1].startswith("reference.turn_radius 16 m: refused (reference.path:"), lines[-1]
    assert lines[0].endswith(": not tried (slow here)"), lines
    assert all(line.endswith(": not tried (the same)") for line in lines[1:-1]), lines


def test_a_remedy_no_quick_try_makes_is_named_and_takes_no_share(monkeypatch) -> None:
    """tracks-box under one Lyapunov matrix: its rate remedy changes the synthesis settings (a matrix per slip corner),
    which a quick try, this search's own, does not: it is named with why, and the two remedies tried split the budget
    between them; the lines keep the candidates' order."""
    from robustsynth.model import build_model
    from robustsynth.synthesis import remedies

    clock = [100.0]
    monkeypatch.setattr(remedies.time, "perf_counter", lambda: clock[0])
    model = build_model(load_config(ROOT / "configs" / "tracks-box.yaml"))
    tried = []

    def slow(m, deadline, say):
        tried.append((m.config.slip.max_rate, m.config.synthesis.lyapunov, deadline))
        clock[0] = deadline
        return None, ()

    lines = remedies.try_remedies(model, slow, lambda _m: None, budget_s=60.0, workers=1)
    assert [line.split(" ")[0] for line in lines] == ["slip", "slip.max_rate", "reference.speed"]
    assert lines[1].endswith(f"not tried ({remedies.NOT_QUICK})"), lines[1]
    assert [t[:2] for t in tried] == [(None, "common")] * 2  # the half box and the half speed, this search's settings
    assert [t[2] for t in tried] == [100.0 + 60.0 / 2, 130.0 + 30.0 / 1]


# ------------------------------------------------------------------ tries at once, in forked processes

OVERLAP_S = 3.0  # [s] each fake try sleeps this long: the second is started long before the first ends


def _log_try(log: Path, value: float | None, sleep: float = OVERLAP_S):
    """A fake quick try that appends 'pid start end speed' to ``log`` and gives |e_y| = ``value`` (None: no set)."""
    import os
    import time

    def first_try(m, deadline, say):
        t0 = time.perf_counter()  # (the deadline's clock: CLOCK_MONOTONIC, one for every process here)
        time.sleep(sleep if m.config.reference.speed >= 0.5 or value is None else sleep / 3)
        with open(log, "a") as fp:
            fp.write(f"{os.getpid()} {t0} {time.perf_counter()} {m.config.reference.speed} {deadline}\n")
        say("said in the child")
        return (None if value is None else {"ultimate_bound": {"e_y": value}, "heading_bound": 0.1}), ()

    return first_try


def test_tries_run_two_at_once_each_in_a_process_of_its_own_and_keep_their_order(tmp_path) -> None:
    """tracks-box has two remedies a quick try makes (the half box and the half speed): with two workers both run at
    once, each in a forked process (neither is this one, they differ, and the second started before the first ended),
    each with the share of the budget it would get one after the other (half of it); the half speed's try ends first
    (a third of the sleep) and its line still comes after the half box's."""
    import os

    from robustsynth.model import build_model
    from robustsynth import forked
    from robustsynth.synthesis import remedies

    if not forked.AVAILABLE:
        pytest.skip("no fork here")
    model = build_model(load_config(ROOT / "configs" / "tracks-box.yaml"))
    log = tmp_path / "tries.log"
    lines = remedies.try_remedies(model, _log_try(log, 0.0123), lambda _m: None, budget_s=60.0, workers=2)
    rows = [r.split() for r in log.read_text().splitlines()]
    pids = [int(r[0]) for r in rows]
    assert len(rows) == 2 and os.getpid() not in pids and pids[0] != pids[1]
    first, second = sorted(rows, key=lambda r: float(r[1]))
    assert float(second[1]) < float(first[2])  # started before the other ended
    assert all(25.0 < float(r[4]) - float(r[1]) <= 30.0 for r in rows)  # each the share of one after the other: 60 / 2
    assert [line.split(" ")[0] for line in lines] == ["slip", "slip.max_rate", "reference.speed"]
    assert lines[0].endswith("proven for the robot, |e_y| <= 1.23 cm at the first try (heading bound 0.1 rad)"), lines
    assert lines[2].endswith("proven for the robot, |e_y| <= 1.23 cm at the first try (heading bound 0.1 rad)"), lines


def test_a_try_that_raises_or_dies_in_its_process_is_named_so() -> None:
    """The child's expected failure (a RobustSynthError: the changed model refused) comes back as 'refused (its
    message)'; a child that ends without a result (here by os._exit) as 'not concluded', and the other try's line is
    whole."""
    import os

    from robustsynth.errors import InputError
    from robustsynth.model import build_model
    from robustsynth import forked
    from robustsynth.synthesis import remedies

    if not forked.AVAILABLE:
        pytest.skip("no fork here")
    model = build_model(load_config(ROOT / "configs" / "tracks-box.yaml"))

    def bad(m, deadline, say):
        if m.config.reference.speed < 0.5:
            os._exit(3)  # the process ends: no result written
        raise InputError("reference.speed: the changed model says no")

    lines = remedies.try_remedies(model, bad, lambda _m: None, budget_s=60.0, workers=2)
    assert lines[0].endswith(": refused (reference.speed: the changed model says no)"), lines[0]
    assert lines[2].endswith(": not concluded (its process: the child process ended without its result)"), lines[2]


def test_tries_still_running_at_the_budget_s_end_are_stopped_there(tmp_path) -> None:
    """Tries that would run 30 s with a budget of 5 s: both are stopped at its end (their processes killed and
    reaped), named so, and the call returns long before the 30 s."""
    import os
    import time

    from robustsynth.model import build_model
    from robustsynth import forked
    from robustsynth.synthesis import remedies

    if not forked.AVAILABLE:
        pytest.skip("no fork here")
    model = build_model(load_config(ROOT / "configs" / "tracks-box.yaml"))
    pids = tmp_path / "pids"

    def sleeper(m, deadline, say):
        with open(pids, "a") as fp:
            fp.write(f"{os.getpid()}\n")
        time.sleep(30.0)
        return None, ()

    t0 = time.monotonic()
    lines = remedies.try_remedies(model, sleeper, lambda _m: None, budget_s=5.0, workers=2)
    assert time.monotonic() - t0 < 20.0
    assert lines[0].endswith(": not concluded (stopped at the end of the tries' 5 s)"), lines
    assert lines[2].endswith(": not concluded (stopped at the end of the tries' 5 s)"), lines
    assert len(pids.read_text().split()) == 2  # both had started (their model rebuilt, their try entered)
    for pid in map(int, pids.read_text().split()):
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (an orphan's is reaped by whoever adopts it, maybe late)."""
    try:
        return open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _sleeping_tries(tmp_path, handlers: bool):
    """A python process whose two remedy tries (forked) each write their pid and sleep 30 s; with ``handlers`` it has
    the CLI's signal handlers and exits 143 on Interrupted.  Returned once both tries run: (the process, their pids)."""
    import subprocess
    import sys
    import time

    pids = tmp_path / "pids"
    script = f"""
import os, sys, time
from robustsynth.config import load_config
from robustsynth.errors import Interrupted, install_signal_handlers
from robustsynth.model import build_model
from robustsynth.synthesis import remedies
if {handlers!r}:
    install_signal_handlers()
model = build_model(load_config({str(ROOT / "configs" / "tracks-box.yaml")!r}))
def first_try(m, deadline, say):
    with open({str(pids)!r}, "a") as fp:
        fp.write(f"{{os.getpid()}}\\n")
    time.sleep(30)
    return None, ()
try:
    remedies.try_remedies(model, first_try, lambda _m: None, budget_s=60.0, workers=2)
except Interrupted:
    sys.exit(143)
sys.exit(0)
"""
    proc = subprocess.Popen([sys.executable, "-c", script])
    deadline = time.monotonic() + 60.0
    while (not pids.exists() or len(pids.read_text().split()) < 2) and time.monotonic() < deadline:
        time.sleep(0.1)
    return proc, [int(p) for p in pids.read_text().split()] if pids.exists() else []


def test_tries_die_with_a_parent_killed_by_sigkill(tmp_path) -> None:
    """SIGKILL leaves the parent no handler to run: its tries' processes end with it all the same (PR_SET_PDEATHSIG),
    rather than sleeping out their 30 s."""
    import signal
    import time

    from robustsynth import forked

    if not forked.AVAILABLE:
        pytest.skip("no fork here")
    proc, children = _sleeping_tries(tmp_path, handlers=False)
    assert len(children) == 2 and all(_running(p) for p in children)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=20)
    gone = time.monotonic() + 10.0
    while any(_running(p) for p in children) and time.monotonic() < gone:
        time.sleep(0.1)
    assert not any(_running(p) for p in children)


def test_sigterm_while_tries_run_stops_them_all(tmp_path) -> None:
    """The CLI's signal handler raises Interrupted in the waiting parent: the tries' processes are killed, the
    parent exits 143 at once (not after the tries' 30 s), and no try's process is left."""
    import os
    import signal
    import time

    from robustsynth import forked

    if not forked.AVAILABLE:
        pytest.skip("no fork here")
    proc, children = _sleeping_tries(tmp_path, handlers=True)
    assert len(children) == 2
    t0 = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=20) == 143
    assert time.monotonic() - t0 < 20.0  # (the tries sleep 30 s: they were not waited for)
    for pid in children:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)  # gone (and reaped by the parent: no zombie answers either)


def test_a_try_the_system_gives_no_process_is_named_and_the_others_run(monkeypatch) -> None:
    """fork refused (EAGAIN: the process limit) for the first try: it is named "not tried (no process for it: ...)",
    and the next try still runs in its own process."""
    import errno
    import os

    from robustsynth.model import build_model
    from robustsynth import forked
    from robustsynth.synthesis import remedies

    if not forked.AVAILABLE:
        pytest.skip("no fork here")
    real = os.fork
    calls = []

    def fork():
        calls.append(1)
        if len(calls) == 1:
            raise OSError(errno.EAGAIN, os.strerror(errno.EAGAIN))
        return real()

    monkeypatch.setattr(forked.os, "fork", fork)
    model = build_model(load_config(ROOT / "configs" / "tracks-box.yaml"))
    lines = remedies.try_remedies(model, lambda m, deadline, say: (None, ()), lambda _m: None, budget_s=60.0, workers=2)
    assert lines[0].endswith(f": not tried (no process for it: {os.strerror(errno.EAGAIN)})"), lines[0]
    assert lines[2].endswith(": none at the first try"), lines[2]
