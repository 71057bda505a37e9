"""The stages of a linear plant (``plant: kind: lti``, docs/theory.md §14-15): build-model,
synthesize, verify, run and margin, each writing its files atomically (the gain's files last)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np

from .artifacts.files import commit_files, json_bytes, make_dir, mat_bytes
from .artifacts.gains import same_plant
from .artifacts.results_dir import clear_foreign

__all__ = ["lti_plant_of", "lti_model_stage", "lti_synthesis_stage", "lti_verification_stage", "lti_run"]

SYNTHESIS_FILES = ("gains.json", "gains.mat", "synthesis.md")
FIGURES = ("verification.png", "verification.pdf", "verification.svg")  # verify --format
VERIFICATION_FILES = ("verification.json", "verification.md") + FIGURES  # a new gain makes them stale
RUN_FILES = ("report.md", "summary.json")


def lti_plant_of(config: Any, config_path: str | Path | None = None) -> dict[str, Any]:
    from .model.lti import lti_plant

    return lti_plant(config, str(Path(config_path).parent) if config_path is not None else None)


def _net(config: Any) -> tuple[float, float, float, int]:
    net = config.network
    return net.sampling_time, net.delay.min, net.delay.max, net.dropouts.max_consecutive


def lti_model_stage(config: Any, outdir: str | Path, config_path: str | Path | None = None) -> dict[str, Any]:
    """The lifted model and its guaranteed over-approximation (open loop, K = 0), with the coverage test
    on 10 000 random instants; writes model.json."""
    from .core.network import Network
    from .plants.linear import LinearPlant

    plant = lti_plant_of(config, config_path)
    pieces = config.synthesis.pieces
    lin = LinearPlant(plant, Network.from_config(config), pieces, config.name)
    n, m, d = lin.n_x, lin.n_u, lin.d_hi
    pw = lin.description()
    cov = lin.coverage_figures(pw)
    data = {"kind": "lti", "config": config.name, "n": n, "m": m, "lifting": d, "lifted_states": n + d * m,
            "controllable": plant["controllable"], "pieces": pieces,
            "instants": [{"theta": th.tolist(), "width": w.tolist(), "remainder_bound": r.tolist(),
                          "directions": U.tolist(), "direction_bounds": rd.tolist()}
                         for th, w, r, U, rd in zip(pw.theta, pw.width, pw.rho, pw.dirs, pw.rho_dir)],
            "coverage": cov, "A": plant["A"], "B": plant["B"]}
    out = make_dir(outdir)
    data["cleared"] = clear_foreign(out, config)
    commit_files(out, {"model.json": json_bytes(data)}, primary="model.json")
    data["files"] = [str(out / "model.json")]
    return data


def lti_synthesis_stage(config: Any, outdir: str | Path, config_path: str | Path | None = None,
                        on_step: Callable[[str], None] | None = None, objective: str | None = None,
                        solver: str | None = None) -> dict[str, Any]:
    """Synthesize and prove a gain (:func:`robustsynth.synthesis.lti.synthesize_lti`), and find its delay margin
    (:func:`robustsynth.margins.linear.delay_margin`: certified / exhibited, seconds beside the synthesis); write
    gains.json (last, with the margin as ``delay_margin``), gains.mat and synthesis.md.  No certified gain: the
    old gain files are set aside and synthesize's InfeasibleError (exit 3) or SolverFailure (exit 4) raised."""
    from .artifacts.files import set_aside
    from .artifacts.gains import lti_gains_dict, lti_gains_mat_vars
    from .errors import InfeasibleError, SolverFailure
    from .core.network import Network
    from .plants.linear import LinearPlant
    from .report.lti import lti_synthesis_markdown
    from .synthesis import synthesize

    plant = lti_plant_of(config, config_path)
    say = on_step or (lambda s: None)
    try:
        linear = LinearPlant(plant, Network.from_config(config), config.synthesis.pieces, config.name, config.synthesis,
                             config.margin)
        design = synthesize(linear, objective=objective, solver=solver, on_step=say)
    except (InfeasibleError, SolverFailure):
        out = make_dir(outdir)
        clear_foreign(out, config)
        set_aside(out, SYNTHESIS_FILES + VERIFICATION_FILES + RUN_FILES + FIGURES,
                  f"synthesize found no certified gain for '{config.name}' as configured now; these are of the gain before")
        raise
    from .margins.linear import delay_margin

    # how far its delay bound goes: certified / exhibited, as `robustsynth margin` finds them
    margin = delay_margin(linear.network, linear.margin_settings, dict(plant, K=np.asarray(design.K, dtype=float)), say)
    out = make_dir(outdir)
    cleared = clear_foreign(out, config)
    over = {}  # review, stop 47: nothing in the file said that --objective / --solver were used
    if objective is not None and objective != config.objective:
        over["synthesis.objective"] = objective
    if solver is not None and solver != config.synthesis.solver:
        over["synthesis.solver"] = solver
    gd = lti_gains_dict(config, plant, design, over, margin)
    files = {"gains.mat": mat_bytes(lti_gains_mat_vars(gd)), "synthesis.md": lti_synthesis_markdown(gd).encode("utf-8"),
             "gains.json": json_bytes(gd)}
    written = commit_files(out, files, primary="gains.json", invalidate=VERIFICATION_FILES + RUN_FILES + FIGURES,
                           reason="they verified and reported the gain that synthesize replaced")
    return {"gains": gd, "design": design, "plant": linear, "files": [str(p) for p in written], "cleared": cleared}


def lti_verification_stage(config: Any, outdir: str | Path, gains_path: str | Path | None = None,
                           config_path: str | Path | None = None, runs: int | None = None,
                           seed: int | None = None, plots: bool = True, fmt: str = "png") -> dict[str, Any]:
    """The certified gain's claims on the exactly lifted loop (:func:`robustsynth.verification.lti.verify_lti`);
    writes verification.json, verification.md and (``plots``) verification.<fmt>."""
    from .artifacts.gains import gains_id, load_gains
    from .errors import InputError
    from .model.lti import check_lti_gain
    from .report.lti import lti_verification_markdown
    from .verification.lti import verify_lti

    out = Path(outdir)  # created once the inputs are checked: a refusal leaves no directory behind
    gp = Path(gains_path) if gains_path is not None else out / "gains.json"
    gd = load_gains(gp)
    cert = gd.get("certificate")
    if gd.get("kind") != "lti" and (gd.get("kind") is not None or cert is not None):
        raise InputError(f"{gp}: not a linear plant's gains file (kind: lti, with certificate.P; its certificate is "
                         "another kind's): run `robustsynth synthesize` on this config, or give a gains file with K only")
    plant = lti_plant_of(config, config_path)
    n, m = plant["B"].shape
    K = np.asarray(gd["K"], dtype=float)
    same_plant(gd, n, m, gp)
    check_lti_gain(K, n, m, f"{gp}: K")
    Ts, lo, hi, ml = _net(config)
    searched = None
    if cert is None:  # a gain of one's own (K only): its certificate is searched
        K, P, eps, pieces, figures = _searched_certificate(config, plant, K, gp)
        searched = {"kind": "common quadratic Lyapunov function, every delay and loss pattern", "pieces": pieces,
                    "decay": figures["decay"]}
    else:
        try:
            P = np.asarray(cert["P"], dtype=float)
            figures = dict(gd["certified"])
            float(figures["alpha"])
        except (TypeError, ValueError, KeyError) as exc:
            raise InputError(f"{gp}: certificate: malformed ({exc})") from None
        if (figures.get("disturbance_step_bound") is not None or figures.get("hinf_gain") is not None) \
                and plant.get("E") is None:
            raise InputError("plant.disturbance: the gain's certificate is for a disturbance input (ultimate-bound or "
                             "hinf); this config has none")
        outs = [o.get("name") for o in figures.get("outputs") or ()]
        if outs and outs != list(plant["outputs"]):
            raise InputError(f"plant.outputs: {list(plant['outputs'])} differ from the outputs the gain was certified "
                             f"for ({outs})")
        try:
            eps, pieces = np.asarray(cert["multipliers"], dtype=float), int(cert["pieces"])
        except (TypeError, ValueError, KeyError) as exc:
            raise InputError(f"{gp}: certificate: malformed ({exc})") from None
    data = verify_lti(plant, K, P, Ts, lo, hi, ml, figures, runs=runs or 64, seed=0 if seed is None else seed,
                      multipliers=eps, pieces=pieces)
    data["gains"] = str(gp)
    data["gains_id"] = gains_id(gd)
    data["certificate_searched"] = searched
    out = make_dir(out)
    written = commit_files(out, {"verification.md": lti_verification_markdown(data).encode("utf-8"),
                                 "verification.json": json_bytes(data)}, primary="verification.json",
                           invalidate=RUN_FILES + FIGURES, reason="they reported and drew the verification that verify replaced")
    if plots:
        from .report.plots import lti_verification_figure

        written.append(lti_verification_figure(data, out / f"verification.{fmt}"))
    data["files"] = [str(p) for p in written]
    return data


def _searched_certificate(config: Any, plant: dict[str, Any], K: np.ndarray, gp: Path):
    """A certificate for a gain that came without one (a hand-tuned K): the analysis LMIs of
    ``robustsynth margin`` (:func:`robustsynth.margins.linear.lti_certificate`: a common quadratic function,
    V shrinking by DECAY per period for every delay and loss pattern, margin.pieces), proven in numpy.
    Returns (K padded to the lifting, P, the multipliers, pieces, figures); InfeasibleError (exit 3) when
    there is none."""
    from .errors import InfeasibleError
    from .margins.linear import lti_certificate
    from .synthesis.lti import DECAY

    Ts, lo, hi, ml = _net(config)
    an, K, pieces = lti_certificate(dict(plant, K=K), Ts, lo, hi, ml, int(config.margin.pieces))
    if not an.certified:
        raise InfeasibleError(f"{gp}: no certificate found for this gain on this network (a common quadratic "
                              f"Lyapunov function, {pieces} pieces per switching instant: {an.status}); "
                              "`robustsynth margin` shows how far the gain is from one")
    return K, an.P, an.eps, pieces, {"alpha": DECAY**2, "decay": DECAY}

def lti_run(config: Any, outdir: str | Path, config_path: str | Path | None = None,
            on_step: Callable[[str], None] | None = None, objective: str | None = None, solver: str | None = None,
            runs: int | None = None, seed: int | None = None, plots: bool = True, fmt: str = "png",
            on_stage: Callable[[str], None] | None = None) -> dict[str, Any]:
    """synthesize, then verify (``on_stage``: called with each one's name as it starts); report.md and summary.json."""
    from .report.lti import lti_synthesis_markdown, lti_verification_markdown

    stage = on_stage or (lambda _name: None)
    stage("synthesize")
    syn = lti_synthesis_stage(config, outdir, config_path, on_step, objective, solver)
    stage("verify")
    ver = lti_verification_stage(config, outdir, None, config_path, runs, seed, plots, fmt)
    out = Path(outdir)
    report = lti_synthesis_markdown(syn["gains"]) + "\n" + lti_verification_markdown(ver)
    summary = {"config": config.name, "kind": "lti", "certified": syn["gains"]["certified"],
               "verification": {"passed": ver["passed"], "checks": ver["checks"]}}
    written = commit_files(out, {"report.md": report.encode("utf-8"), "summary.json": json_bytes(summary)},
                           primary="summary.json")
    return {"synthesis": syn, "verification": ver, "files": syn["files"] + ver["files"] + [str(p) for p in written]}
