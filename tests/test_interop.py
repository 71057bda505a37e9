"""robustsynth.interop.to_statespace: a real python-control StateSpace of the frozen closed loop,
its poles against numpy's eigenvalues, its step response against our lifted linear simulator."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

control = pytest.importorskip("control", reason="python-control is the optional extra robustsynth[control]")

from robustsynth.config import Config
from robustsynth.errors import InputError
from robustsynth.interop import closed_loop_matrices, to_statespace
from robustsynth.model import build_model
from robustsynth.verification.lifted import closed_loop_run

ROOT = Path(__file__).resolve().parents[1]
POLE_TOL = 1e-9  # python-control's poles vs numpy eigvals of the same matrix
RESPONSE_TOL = 1e-10  # step response vs closed_loop_run (same recursion, different code)


@pytest.fixture(scope="module", params=["tracks-box", "delay-multi-period"])
def case(request):
    g = json.loads((ROOT / "results" / "baselines" / request.param / "gains.json").read_text())
    return build_model(Config.model_validate(g["config"])), g


def test_statespace_is_discrete_named_and_has_the_closed_loop_poles(case) -> None:
    model, g = case
    sys = to_statespace(model, g)
    assert sys.dt == model.Ts and list(sys.state_labels) == list(model.state_names)
    assert list(sys.input_labels) == ["w_dV", "w_omega", "slip"]
    m = closed_loop_matrices(model, g)
    want = np.sort_complex(np.linalg.eigvals(m["A"]))
    got = np.sort_complex(np.asarray(sys.poles()))
    assert np.max(np.abs(got - want)) <= POLE_TOL
    assert np.max(np.abs(want)) < 1.0  # a certified gain is stable at any frozen admissible instant


def test_slip_step_response_is_our_lifted_simulation(case) -> None:
    """A unit step of the slip input from xi = 0 is the lifted closed loop under that constant slip
    and a constant delay; both tend to the steady state of the constant slip."""
    model, g = case
    K = np.asarray(g["K"])
    tau = 0.5 * (model.config.network.delay.min + model.config.network.delay.max)
    steps = 200
    taus = np.full((1, steps + model.d_hi), tau)
    instants = model.s_tilde(taus)[0, 0]
    mu = np.array([0.7, 0.9])
    sys = to_statespace(model, g, instants=instants, slip=mu)
    resp = control.forced_response(sys, T=np.arange(steps + 1) * model.Ts, U=np.vstack([np.zeros((2, steps + 1)),
                                                                                          np.ones((1, steps + 1))]),
                                   return_x=True)
    ours = closed_loop_run(model, K, taus, np.tile(mu, (1, steps, 1)), np.zeros((1, model.n_s)))[0]
    assert np.max(np.abs(resp.states.T - ours)) <= RESPONSE_TOL
    assert np.max(np.abs(resp.outputs[:3].T - ours[:, :3])) <= RESPONSE_TOL
    assert np.max(np.abs(ours[-1] - model.equilibrium(K, mu))) <= 1e-6  # settled within 20 s


def test_bad_instants_and_slip_are_refused(case) -> None:
    model, g = case
    with pytest.raises(InputError, match="instants: need"):
        to_statespace(model, g, instants=[0.01] * (model.d_hi + 1))
    with pytest.raises(InputError, match=r"instants: must lie in \[0, Ts"):
        to_statespace(model, g, instants=[2 * model.Ts] * model.d_hi)
    with pytest.raises(InputError, match="slip: need"):
        to_statespace(model, g, slip=[0.5, -1.0])


def test_lti_config_from_a_statespace() -> None:
    """A continuous-time StateSpace becomes a plant: kind: lti config with its names and its C as the
    bounded outputs; a discrete-time system and a wrong-sized limit are refused naming the key."""
    from robustsynth.errors import ConfigError, InputError
    from robustsynth.interop import lti_config
    from robustsynth.model.lti import lti_plant

    sys_ = control.ss([[0, 1], [0, -0.1]], [[0], [0.1]], [[1, 0]], 0, states=["position", "velocity"], outputs=["pos"])
    cfg = lti_config(sys_, sampling_time=0.5, delay=(0.0, 0.5), disturbance={"E": [[0], [0.1]], "bound": 0.5},
                     input_limits=[20])
    pl = lti_plant(cfg)
    assert cfg.objective == "ultimate-bound" and pl["states"] == ["position", "velocity"] and pl["outputs"] == ["pos"]
    assert np.array_equal(pl["A"], np.asarray(sys_.A)) and np.array_equal(pl["C"], [[1.0, 0.0]])
    with pytest.raises(InputError, match="continuous time"):
        lti_config(control.ss([[0.5]], [[1]], [[1]], 0, dt=0.1), sampling_time=0.5, delay=(0, 0.5))
    with pytest.raises(InputError, match="feedthrough D"):
        lti_config(control.ss([[0, 1], [0, -0.1]], [[0], [0.1]], [[1, 0]], [[5]]), sampling_time=0.5, delay=(0, 0.5))
    with pytest.raises(ConfigError, match="plant.input_limits: 2 limits for the 1 inputs"):
        lti_config(sys_, sampling_time=0.5, delay=(0.0, 0.5), input_limits=[20, 3])
