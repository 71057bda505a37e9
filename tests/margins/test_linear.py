"""`robustsynth margin` on a linear plant: the benchmark of Zhang, Branicky and Phillips (2001) with its
published gain.  The exhibited figures are checked against closed-loop matrices built here by hand
(independent of robustsynth's lifting); no random switching sequence below the certified bound is
unstable; the certified bound is never above the exhibited one and reaches >= 0.85 of it; the numpy
check rejects a broken certificate."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from robustsynth.config import load_config
from robustsynth.margins.linear import lti_margins
from robustsynth.model.lti import lti_plant

ROOT = Path(__file__).resolve().parents[2]
A = np.array([[0.0, 1.0], [0.0, -0.1]])
B = np.array([[0.0], [0.1]])
K = -np.array([[3.75, 11.5]])
RATIO = 0.85  # issue 28's target: certified / exhibited
EDGE = 2e-3  # s: a witness bound bisected to 1e-3


def G(t: float) -> np.ndarray:
    """int_0^t e^{As} ds B by the block exponential, written out here."""
    M = np.zeros((3, 3))
    M[:2, :2], M[:2, 2:] = A, B
    return expm(M * t)[:2, 2:]


def one_period(h: float, tau: float) -> np.ndarray:
    """[x; u_{k-1}] -> next, for a delay tau <= h of the command sent at t_k (the previous acts until tau)."""
    Phi = expm(A * h)
    return np.block([[Phi + G(h - tau) @ K, G(h) - G(h - tau)], [K, np.zeros((1, 1))]])


def frozen_two_period(h: float, tau: float) -> np.ndarray:
    """[x; u_{k-1}; u_{k-2}] -> next for a constant delay h < tau <= 2h: u_{k-2} acts until tau - h, then u_{k-1}."""
    Phi = expm(A * h)
    g = G(2 * h - tau)
    return np.block([[Phi, g, G(h) - g], [K, np.zeros((1, 2))], [np.zeros((1, 2)), np.ones((1, 1)), np.zeros((1, 1))]])


def rho(M: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(M))))


@pytest.fixture(scope="module")
def h1():
    cfg = load_config(ROOT / "configs" / "zbp-h1.yaml")
    return cfg, lti_margins(cfg, lti_plant(cfg))


def test_benchmark_h1_exhibited_by_hand_and_certified_close_to_it(h1) -> None:
    _, mg = h1
    d = mg["delay_max"]
    assert d["certified"] is not None and d["exhibited"] is not None
    assert d["certified"] <= d["exhibited"] and d["certified"] / d["exhibited"] >= RATIO
    w = d["witness"]
    seq = [x for x in w["delays"]]
    assert max(seq) == pytest.approx(d["exhibited"])
    prod = np.eye(3)
    for tau in seq:  # the packets of one period in the order sent
        prod = one_period(1.0, tau) @ prod
    assert rho(prod) ** (1 / len(seq)) > 1.0  # the witness destabilizes, by hand
    below = np.eye(3)
    for tau in seq:
        below = one_period(1.0, tau * (1 - EDGE)) @ below
    assert rho(below) ** (1 / len(seq)) < 1.0 + 1e-9  # and just below the bound it no longer does


def test_no_random_switching_sequence_below_the_certified_bound_is_unstable(h1) -> None:
    """A brute-force search (random delay sequences of 6 periods, each in [0, certified]) of the
    hand-built closed loop: a certificate must never be above a destabilizing sequence."""
    _, mg = h1
    c = mg["delay_max"]["certified"]
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(2000):
        seq = rng.choice([0.0, c], size=6) if rng.random() < 0.5 else rng.uniform(0.0, c, size=6)
        prod = np.eye(3)
        for tau in seq:
            prod = one_period(1.0, tau) @ prod
        worst = max(worst, rho(prod) ** (1 / 6))
    assert worst < 1.0


def test_benchmark_h05_frozen_delay_beyond_one_period_by_hand() -> None:
    """h = 0.5: the delay margin lies beyond one period (0.92 s); the constant delay that robustsynth
    exhibits is where the hand-built two-period closed loop loses stability."""
    from robustsynth.margins.linear import spectral_radius

    base = json.loads((ROOT / "results" / "baselines" / "zbp" / "summary.json").read_text())
    ex = base["margins"]["delay_max"]["exhibited"]
    assert 0.5 < ex < 1.0
    assert rho(frozen_two_period(0.5, ex + EDGE)) > 1.0 > rho(frozen_two_period(0.5, ex - EDGE))
    cfg = load_config(ROOT / "configs" / "zbp.yaml")
    pl = lti_plant(cfg)
    for tau in (0.6, ex - EDGE, ex + EDGE, 0.99):  # robustsynth's lifting agrees with the hand-built loop
        assert spectral_radius(pl, 0.5, np.array([[tau]]))[0] == pytest.approx(rho(frozen_two_period(0.5, tau)), rel=1e-9)
    assert base["margins"]["delay_max"]["certified"] / ex >= RATIO


def test_the_numpy_check_rejects_a_broken_certificate() -> None:
    from robustsynth.certificate.lti import check_lti_certificate
    from robustsynth.core.delays import over_approximation, pad_lti_gain
    from robustsynth.synthesis.lti import analyze_lti, vertex_combinations

    pw = over_approximation(A, B, pad_lti_gain(K, 2, 1, 1), 1.0, 0.0, 0.5, 1, 4)
    res = analyze_lti(pw)
    assert res.certified and res.check.passed
    said = json.loads(json.dumps(res.to_dict()))  # plain data, and its lines say it was found and proven
    assert np.array_equal(np.asarray(said["certificate"]["P"]), res.P) and said["check"]["passed"]
    assert res.lines()[0].startswith("certificate found") and res.lines()[1].startswith("certificate check passed")
    verts = vertex_combinations(pw)
    P = res.P.copy()
    P[0, 0] *= 0.5  # no longer a Lyapunov function
    assert not check_lti_certificate(pw, P, res.certificate["multipliers"], 1.0 - 1e-6, verts)["ok"]
    assert not check_lti_certificate(pw, res.P, -res.certificate["multipliers"] - 1.0, 1.0 - 1e-6, verts)["ok"]
    far = over_approximation(A, B, pad_lti_gain(K, 2, 1, 1), 1.0, 0.0, 0.9, 1, 4)  # beyond the exhibited 0.685
    assert not analyze_lti(far).certified


def test_cli_margin_on_a_linear_plant_and_the_commands_it_lacks(tmp_path) -> None:
    run = lambda *a: subprocess.run([sys.executable, "-m", "robustsynth", *a], capture_output=True, text=True)  # noqa: E731
    r = run("margin", str(ROOT / "configs" / "zbp-h1.yaml"), "-o", str(tmp_path), "--json")
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert data["delay_max"]["exhibited"] == pytest.approx(0.685, abs=5e-3)
    assert (tmp_path / "margin.json").exists() and "certified / exhibited" in (tmp_path / "margin.md").read_text()
    r = run("margin", str(ROOT / "configs" / "zbp-h1.yaml"), "-o", str(tmp_path), "--lyapunov", "common")
    assert r.returncode == 2 and "--lyapunov" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    bad = tmp_path / "bad.yaml"
    bad.write_text((ROOT / "configs" / "zbp-h1.yaml").read_text().replace("B: [[0], [0.1]]", "B: [[0]]"))
    r = run("margin", str(bad))
    assert r.returncode == 2 and "plant.B" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_a_certificate_holds_on_sampled_exact_loops_of_a_harder_plant() -> None:
    """Certificate vs the exact loops: a 3-state, 2-input, open-loop unstable plant with complex
    eigenvalues, a gain on the lifted state, delays in [1.2, 2.6] periods and one loss in a row.  The
    certified P must make V shrink (by decay^2) on 5000 exactly lifted closed loops at random
    admissible instants (and at the extremes)."""
    from robustsynth.core.lifting import delay_indices, instant_ranges
    from robustsynth.core.delays import exact_closed_loop, over_approximation, pad_lti_gain
    from robustsynth.synthesis.lti import DECAY, analyze_lti

    Ah = np.array([[0.1, 1.0, 0.0], [-1.0, 0.1, 0.0], [0.0, 0.0, -0.5]])
    Bh = np.array([[0.0, 0.2], [1.0, 0.0], [0.0, 1.0]])
    Ts, t_lo, t_hi, m = 0.1, 0.12, 0.26, 1
    d = delay_indices(t_lo, t_hi + m * Ts, Ts)[1]
    Kx = np.array([[-0.6, -1.2, 0.0], [0.0, 0.0, -0.3]])
    Kl = np.hstack([Kx, 0.05 * np.ones((2, 2)), np.zeros((2, 2 * (d - 1)))])  # a gain on u_{k-1} too
    K = pad_lti_gain(Kl, 3, 2, d)
    res = analyze_lti(over_approximation(Ah, Bh, K, Ts, t_lo, t_hi + m * Ts, d, 3))
    assert res.certified, res.status
    rng = np.random.default_rng(5)
    r = instant_ranges(t_lo, t_hi + m * Ts, Ts, d)
    s = r[:, 0] + (r[:, 1] - r[:, 0]) * rng.random((5000, d))
    s = np.concatenate([s, r[:, 0][None], r[:, 1][None]])
    s = np.maximum.accumulate(s[:, ::-1], axis=1)[:, ::-1]  # in order
    M = exact_closed_loop(Ah, Bh, K, Ts, s)
    lhs = np.einsum("vba,bc,vcd->vad", M, res.P, M) - DECAY**2 * res.P
    assert np.max(np.linalg.eigvalsh(lhs)) < 0.0


def test_no_certificate_at_the_exhibited_bound(h1) -> None:
    """Independently of the bisection (which stops at the exhibited value): the LMIs fail just above
    the exhibited delay bound, where a destabilizing sequence exists."""
    from robustsynth.margins.linear import _certify

    cfg, mg = h1
    ex = mg["delay_max"]["exhibited"]
    assert not _certify(lti_plant(cfg), 1.0, 0.0, ex + EDGE, 0, 8).certified


@pytest.mark.slow
def test_schema_of_a_linear_plant_and_the_controllability_warning(tmp_path) -> None:
    run = lambda *a: subprocess.run([sys.executable, "-m", "robustsynth", *a], capture_output=True, text=True)  # noqa: E731
    r = run("schema", "--plant", "lti")
    assert r.returncode == 0 and set(json.loads(r.stdout)["properties"]) >= {"name", "plant", "controller", "network"}
    text = (ROOT / "configs" / "zbp-h1.yaml").read_text()
    for a, b in (("A: [[0, 1], [0, -0.1]]", "A: [[-1, 0], [0, -2]]"), ("B: [[0], [0.1]]", "B: [[1], [0]]"),
                 ("gain: [[-3.75, -11.5]]", "gain: [[-0.5, 0.0]]"), ("name: zbp-h1", "name: unctrl")):
        assert a in text, a  # an edit that silently does nothing would test another plant
        text = text.replace(a, b)
    # a short search (the warning is the point): the open loop is stable, so the full search is long
    short = re.sub(r"^  pieces: \d+.*$", "  pieces: 2\n  delay_far: 1.2", text, flags=re.M)
    assert short != text
    unctrl = tmp_path / "u.yaml"
    unctrl.write_text(short)
    r = run("margin", str(unctrl), "-o", str(tmp_path / "m"))
    assert r.returncode == 0, r.stderr
    assert "not controllable" in r.stderr


def test_the_compiled_analysis_problem_holds_no_stale_answer() -> None:
    """The analysis LMIs are compiled once per structure and re-solved with new coefficients: a
    certifiable gain, one that a constant delay in the range destabilizes and again the certifiable one, on
    the same delay range (one structure: the in-order vertices depend on the range, not on the gain), give
    True, False, True, each proven on its own."""
    from robustsynth.margins.linear import spectral_radius
    from robustsynth.core.delays import over_approximation, vertex_combinations
    from robustsynth.synthesis.lti import analyze_lti

    A = np.array([[0.0, 1.0], [0.0, -0.1]])
    B = np.array([[0.0], [0.1]])
    K = -np.array([[3.75, 11.5]])
    from robustsynth.synthesis import lti as syn

    ok = over_approximation(A, B, np.hstack([K, np.zeros((1, 2))]), 0.5, 0.0, 0.84, 2, 4)
    bad = over_approximation(A, B, np.hstack([1.5 * K, np.zeros((1, 2))]), 0.5, 0.0, 0.84, 2, 4)
    assert spectral_radius({"A": A, "B": B, "K": 1.5 * K}, 0.5, np.array([[0.84]]))[0] > 1.0  # no certificate exists
    assert np.array_equal(vertex_combinations(ok)[1], vertex_combinations(bad)[1])
    before = len(syn._PROBLEMS)
    got = [analyze_lti(pw).certified for pw in (ok, bad, ok)]
    assert got == [True, False, True]
    assert len(syn._PROBLEMS) <= before + 1  # one structure (13 piece combinations each): one compiled problem


def test_margin_of_the_gain_synthesize_wrote_and_a_margin_at_the_search_end(tmp_path) -> None:
    """Without controller.gain, margin analyses OUTDIR/gains.json (as its --help says); a certified
    value at the end of the search is printed as a lower bound ("at least"), with the note in
    margin.json, and lost packets read "lost"."""
    from click.testing import CliRunner

    from robustsynth.cli import main

    cfg = tmp_path / "own.yaml"
    cfg.write_text("name: own\nplant: {kind: lti, A: [[0, 1], [0, -0.1]], B: [[0], [0.1]]}\n"
                   "network: {sampling_time: 0.5, delay: {min: 0.0, max: 0.5}}\nmargin: {delay_far: 0.9}\n")
    out = tmp_path / "o"
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "robust stability of this gain, delay_max: configured 0.5 s, certified at least 0.9 s" in r.output
    r = CliRunner().invoke(main, ["margin", str(cfg), "-o", str(out)])
    assert r.exit_code == 0, r.output
    data = json.loads((out / "margin.json").read_text())
    gd = json.loads((out / "gains.json").read_text())
    assert data["meta"]["gains"] == str(out / "gains.json")
    assert data["meta"]["gain"] == gd["K"]
    dm = data["delay_max"]
    assert dm["exhibited"] is None and dm["certified"] >= 0.9 - 1e-3 and "at least" in dm["note"]
    assert "delay_max: configured 0.5 s, certified at least 0.9 s" in r.output
    # synthesize recorded the same delay margin for its gain (one function, margins.linear.delay_margin)
    assert {k: gd["delay_margin"][k] for k in ("certified", "exhibited", "at_least", "note")} == \
        {k: dm[k] for k in ("certified", "exhibited", "at_least", "note")}
    lo = data["dropouts"]
    assert lo["exhibited"] is None and lo["certified"] == lo["searched"][1] == 3 and "at least" in lo["note"]
    assert "dropouts: configured 0 packets, certified at least 3 packets, exhibited none" in r.output
    assert "None" not in r.output


def test_synthesize_reports_and_records_certified_over_exhibited_for_its_gain(tmp_path) -> None:
    """Issue 53 item 3: synthesize on a linear plant prints the delay margin of the gain it made and records it in
    gains.json (delay_margin, outside the gain's id): certified below exhibited, at least the configured delay
    (the synthesis proved that range), their ratio as printed, and a witness that destabilizes the exactly lifted
    loop of the synthesized K (recomputed here)."""
    from click.testing import CliRunner

    from robustsynth.artifacts.gains import gains_id
    from robustsynth.cli import main
    from robustsynth.margins.linear import spectral_radius

    cfg = ROOT / "configs" / "zbp.yaml"
    out = tmp_path / "o"
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "-o", str(out)])
    assert r.exit_code == 0, r.output
    gd = json.loads((out / "gains.json").read_text())
    dm = gd["delay_margin"]
    conf = load_config(cfg)
    assert conf.network.delay.max <= dm["certified"] < dm["exhibited"]
    assert dm["ratio"] == pytest.approx(dm["certified"] / dm["exhibited"], rel=1e-12)
    # the line margin prints: the share of the exhibited margin the certificate may miss, 1 - certified / exhibited
    assert f"may miss {100 * (1 - dm['ratio']):.1f} % of the exhibited margin" in r.output
    assert "robust stability of this gain, delay_max: configured 0.5 s" in r.output
    w = dm["witness"]
    assert w["check"]["ok"]
    K = np.asarray(gd["K"], dtype=float)
    pl = dict(lti_plant(conf), K=K)
    assert spectral_radius(pl, conf.network.sampling_time, np.array([w["delays"]]))[0] > 1.0
    assert gains_id({k: v for k, v in gd.items() if k != "delay_margin"}) == gd["gains_id"]
    assert "**Delay margin**" in (out / "synthesis.md").read_text()


def test_a_gain_made_for_another_plant_or_the_robot_is_refused(tmp_path) -> None:
    """K's shape alone cannot tell plants apart (1 x 4 is d = 2 on the benchmark's 2 states, d = 1 on 3 states):
    a linear plant's gains file names its n and m, and margin / verify refuse another plant's (a review found
    margin answering for dc-motor's gain on the benchmark); the robot's gains are refused by name."""
    from robustsynth.errors import InputError
    from robustsynth.artifacts.gains import lti_gain
    from robustsynth.pipeline import plant_of

    root = Path(__file__).resolve().parents[2]
    cfg = load_config(root / "configs" / "zbp.yaml")
    plant = plant_of(cfg, root / "configs" / "zbp.yaml").arrays
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"kind": "lti", "K": [[0.1, 0.2, 0.3, 0.4]], "lifting": {"n": 3, "m": 1, "d": 1}}))
    with pytest.raises(InputError, match="made for a plant of n = 3 states and m = 1 inputs; this config's has n = 2"):
        lti_gain(cfg, plant, other)
    same = tmp_path / "same.json"
    same.write_text(json.dumps({"kind": "lti", "K": [[0.1, 0.2, 0.3, 0.4]], "lifting": {"n": 2, "m": 1, "d": 2}}))
    assert lti_gain(cfg, plant, same)[0].shape == (1, 4)
    # the robot's own file (2 x 5 K): named as the robot's, not reported as a K of the wrong shape (review)
    with pytest.raises(InputError, match="the tracked robot's gains"):
        lti_gain(cfg, plant, root / "results" / "baselines" / "tracks-box" / "gains.json")


def test_delay_far_must_reach_beyond_the_configured_delay() -> None:
    """margin.delay_far at or below network.delay.max would search nothing beyond what is configured, and its
    "certified at least" would name a delay below the configured one (a review found 0.1 s against 0.5 s).  It
    is refused where the margin runs, not in the config: a sweep over delay.max with one delay_far stays valid."""
    from robustsynth.errors import InputError

    base = {"name": "far", "plant": {"kind": "lti", "A": [[0.0, 1.0], [0.0, -0.1]], "B": [[0.0], [0.1]]},
            "controller": {"gain": [[-3.75, -11.5]]},
            "network": {"sampling_time": 0.5, "delay": {"min": 0.0, "max": 0.5}}}
    for far in (0.1, 0.5):
        cfg = load_config(dict(base, margin={"delay_far": far}))
        with pytest.raises(InputError, match=rf"margin.delay_far: {far:g} s does not reach beyond network.delay.max"):
            lti_margins(cfg, lti_plant(cfg))


# ------------------------------------------------------------------ issue 53: the exhibited search goes far

SERVO_A = np.array([[0.0, 1.0], [0.0, -72.5]])
SERVO_B = np.array([[0.0], [75.3]])
SERVO_K = -np.array([[7.27, 0.14]])
SERVO_TS = 0.02


def _servo_G(t: float) -> np.ndarray:
    M = np.zeros((3, 3))
    M[:2, :2], M[:2, 2:] = SERVO_A, SERVO_B
    return expm(M * t)[:2, 2:]


def servo_frozen(tau: float, depth: int = 12) -> np.ndarray:
    """By hand: [x_k; u_{k-1}; ...; u_{k-depth}] -> next for a constant delay tau = q Ts + r (0 <= r < Ts),
    q < depth: u_{k-q-1} acts for the first r of the period, then u_{k-q}."""
    q = int(np.floor(tau / SERVO_TS + 1e-12))
    r = tau - q * SERVO_TS
    assert q < depth
    Phi = expm(SERVO_A * SERVO_TS)
    late, early = _servo_G(SERVO_TS - r), _servo_G(SERVO_TS) - _servo_G(SERVO_TS - r)
    M = np.zeros((2 + depth, 2 + depth))
    M[:2, :2] = Phi
    for j, g in ((q, late), (q + 1, early)):  # u_{k-q} and u_{k-q-1}; u_{k-j} is K x_k for j = 0
        if j == 0:
            M[:2, :2] += g @ SERVO_K
        else:
            M[:2, 1 + j:2 + j] += g  # u_{k-j} sits in column 2 + (j - 1)
    M[2:3, :2] = SERVO_K  # u_k is stored as u_{(k+1)-1}
    for j in range(1, depth):
        M[2 + j, 1 + j] = 1.0  # shift the register
    return M


SERVO_EDGE = 2e-3  # s: the search bisects to margin.tolerance = 1e-3; two steps of it
SERVO_RATIO = 0.8  # issue 53's target for a fast plant with multi-period delays: certified / exhibited


def _servo_cfg(tmp_path: Path) -> Path:
    text = (ROOT / "tests" / "data" / "dc-servo.yaml").read_text()
    assert "max: 0.06" in text  # the configured delay the issue tried
    path = tmp_path / "servo.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def servo(tmp_path_factory):
    path = _servo_cfg(tmp_path_factory.mktemp("servo"))
    cfg = load_config(path)
    return cfg, lti_margins(cfg, lti_plant(cfg))


def test_servo_instability_is_found_far_beyond_the_configured_delay(servo) -> None:
    """Issue 53: with delay.max 0.06 s the search used to stop at 0.08 s and report none.  It must go on
    until it destabilizes: the exhibited bound is the hand-built loop's first unstable constant delay
    (found here by an independent scan and bisection) to SERVO_EDGE, far beyond 4/3 of the configured."""
    cfg, mg = servo
    d = mg["delay_max"]
    assert d["exhibited"] is not None, d["note"]
    assert d["exhibited"] > 4.0 / 3.0 * cfg.network.delay.max + SERVO_EDGE
    rho_hand = lambda tau: rho(servo_frozen(tau))  # noqa: E731
    taus = np.arange(0.0, 0.4, SERVO_TS / 20)
    first = next(t for t in taus if rho_hand(t) > 1.0)
    lo, hi = first - SERVO_TS / 20, first
    while hi - lo > 1e-6:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if rho_hand(mid) > 1.0 else (mid, hi)
    # no switching sequence of the search destabilizes below the frozen threshold for this plant, so the
    # exhibited bound is that threshold (from above: the bisection's bad end)
    assert hi - 1e-6 <= d["exhibited"] <= hi + SERVO_EDGE
    w = d["witness"]
    assert max(x for x in w["delays"] if x is not None) <= d["exhibited"] + 1e-12
    assert w["check"]["ok"] and w["check"]["lower_bound"] > 1.0 + w["check"]["margin"]
    if w["period"] == 1:  # a frozen witness: by hand
        assert rho_hand(w["delays"][0]) == pytest.approx(w["spectral_radius"], rel=1e-9)
    # the certified bound stays below it, within SERVO_RATIO of it (issue 53's target), and the ratio is reported
    assert d["certified"] is not None and SERVO_RATIO * d["exhibited"] <= d["certified"] < d["exhibited"]
    assert d["ratio"] == pytest.approx(d["certified"] / d["exhibited"], rel=1e-12)
    assert f"certified / exhibited {d['ratio']:.3f}" in d["note"]
    assert d["searched_up_to"] == pytest.approx(20 * SERVO_TS) and "20 Ts" in d["note"]


def test_hand_built_servo_loop_matches_the_library_lifting() -> None:
    """The hand-built frozen loop above is what the library lifts (so the comparison above is not vacuous)."""
    from robustsynth.margins.linear import spectral_radius

    pl = {"A": SERVO_A, "B": SERVO_B, "K": SERVO_K}
    for tau in (0.0, 0.013, 0.06, 0.1999, 0.2031):
        assert spectral_radius(pl, SERVO_TS, np.array([[tau]]))[0] == pytest.approx(rho(servo_frozen(tau)), rel=1e-9)


def test_the_witness_check_recomputes_the_exact_product_and_rejects_a_stable_sequence(h1) -> None:
    """check_witness rebuilds the periodic product from the exact lifted matrices: on the benchmark's
    switching witness it agrees with the hand-built product (rel 1e-9) and confirms it; the same
    sequence 5 % shorter is stable, and the check says not ok."""
    from robustsynth.margins.linear import check_witness

    cfg, mg = h1
    pl = lti_plant(cfg)
    w = mg["delay_max"]["witness"]
    c = check_witness(pl, 1.0, w)
    prod = np.eye(3)
    for tau in w["delays"]:
        prod = one_period(1.0, tau) @ prod
    assert c["spectral_radius"] == pytest.approx(rho(prod) ** (1 / len(w["delays"])), rel=1e-9)
    assert c["ok"] and c["lower_bound"] > 1.0 + c["margin"] and 0.0 < c["rounding_bound"] < 1e-6
    shorter = dict(w, delays=[0.95 * x for x in w["delays"]])
    assert not check_witness(pl, 1.0, shorter)["ok"]


def test_a_switching_witness_where_no_constant_delay_destabilizes(h1) -> None:
    """ZBP at h = 1 s: the exhibited bound (about 0.685 s) is a switching sequence; every constant delay up
    to it is stable in the hand-built loop (a GRID s grid), and the witness's product, by hand, is not."""
    GRID = 5e-4  # s; the first unstable constant delay (about 0.715 s) lies some 60 grid steps beyond the witness
    _, mg = h1
    d = mg["delay_max"]
    w = d["witness"]
    assert w["period"] >= 2 and len(set(w["delays"])) >= 2  # not a constant delay
    grid = np.arange(0.0, d["exhibited"] + GRID, GRID)  # one step beyond the exhibited bound too
    assert max(rho(one_period(1.0, tau)) for tau in grid) < 1.0
    prod = np.eye(3)
    for tau in w["delays"]:
        prod = one_period(1.0, tau) @ prod
    assert rho(prod) ** (1 / len(w["delays"])) > 1.0


def test_the_cap_is_reported_when_nothing_destabilizes(tmp_path) -> None:
    """A strongly stable loop (x' = -5 x + u, u = -0.1 x: small gain 0.02, stable for any delay): nothing is
    found, and the result and the CLI line say how far the search went, 20 Ts = 2 s, not 4/3 of the
    configured 0.1 s."""
    from click.testing import CliRunner

    from robustsynth.cli import main

    cfg = tmp_path / "stable.yaml"
    cfg.write_text("name: stable\nplant: {kind: lti, A: [[-5]], B: [[1]]}\ncontroller: {gain: [[-0.1]]}\n"
                   "network: {sampling_time: 0.1, delay: {min: 0.0, max: 0.1}}\nmargin: {pieces: 2}\n")
    r = CliRunner().invoke(main, ["margin", str(cfg), "-o", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    dm = json.loads((tmp_path / "o" / "margin.json").read_text())["delay_max"]
    assert dm["exhibited"] is None and dm["witness"] is None and dm["gap"] is None
    assert dm["searched"][1] == pytest.approx(2.0) and dm["searched_periods"] == pytest.approx(20.0)
    assert "20 Ts" in dm["note"]
    line = next(x for x in r.output.splitlines() if x.startswith("delay_max:"))
    assert "no instability found in [0, 2]" in line and "switching sequences" in line


def test_margin_takes_a_linear_plant_and_returns_the_one_report(h1) -> None:
    """Issue 52: ``robustsynth.margin`` takes a LinearPlant and returns the MarginReport the robot's margins come in:
    the figures and witnesses of the records (``lti_margins``, computed separately by the fixture), the loss margin
    counted in packets (its gap too), no slip margin; the robot's --lyapunov and a K of strings refused in one line;
    the old top-level name warns."""
    import warnings

    import robustsynth
    from robustsynth.errors import InputError
    from robustsynth.margins import Margin

    cfg, rec = h1
    plant = robustsynth.LinearPlant.from_config(cfg)
    rep = robustsynth.margin(plant)
    assert rep.names == ("delay_max", "dropouts") and rep.slip_min is None and rep.slip_parameters == ()
    for name in rep.names:
        m, r = rep[name], rec[name]
        assert (m.configured, m.certified, m.exhibited, m.at_least, m.witness) == \
            (r["configured"], r["certified"], r["exhibited"], r["at_least"], r["witness"])
    assert rep.dropouts.unit == "packets" and rep.dropouts.gap_packets == 0
    assert all(isinstance(m, Margin) and {"configured", "certified", "exhibited", "witness", "searched", "at_least", "gap",
                                          "gap_packets" if m.integer else "gap"} <= set(m.to_dict()) for m in rep.margins)
    assert rep.to_dict()["meta"]["plant"]["kind"] == "lti" and rep.warnings == ()
    with pytest.raises(InputError, match="^lyapunov: a linear plant's certificate"):
        robustsynth.margin(plant, lyapunov="common")
    with pytest.raises(InputError, match="^K: must be a matrix of numbers"):
        robustsynth.margin(plant, [["a", "b"]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert robustsynth.lti_margins is lti_margins
    assert [w.category for w in caught] == [DeprecationWarning]
