"""The conformance suite (core/conformance.py) over every plant: the tracked robot of each committed
config, the committed linear plants, and a toy plant written here from the protocol alone (the "how to
add a plant" list of docs/architecture.md); and plants broken on purpose, which it must fail."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from robustsynth.config import is_lti, load_config
from robustsynth.core.conformance import ODE_TOL, check_plant
from robustsynth.core.network import Network
from robustsynth.core.plant import Plant
from robustsynth.model import build_model
from robustsynth.core.delays import exact_closed_loop, exact_lifted
from robustsynth.plants.linear import LinearPlant

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
ROBOT = sorted(p.name for p in CONFIGS.glob("*.yaml") if not is_lti(load_config(p)) and p.stem != "infeasible")
LINEAR = sorted(p.name for p in CONFIGS.glob("*.yaml") if is_lti(load_config(p)))


def _failed(checks: list[dict]) -> list[str]:
    return [c["name"] for c in checks if not c["passed"]]


@pytest.mark.parametrize("name", ROBOT)
def test_the_robot_of_every_committed_config_conforms(name) -> None:
    model = build_model(load_config(CONFIGS / name))
    assert isinstance(model, Plant)
    assert _failed(check_plant(model)) == []


@pytest.mark.parametrize("name", LINEAR)
def test_every_committed_linear_plant_conforms(name) -> None:
    plant = LinearPlant.from_config(load_config(CONFIGS / name), str(CONFIGS))
    assert isinstance(plant, Plant)
    assert _failed(check_plant(plant)) == []


def test_linear_examples_with_losses_and_long_delays_conform() -> None:
    net = Network(0.1, 0.03, 0.17, 2)  # d_hi = 4: tau_max + 2 Ts = 0.37 s
    unstable = LinearPlant.from_arrays([[0.0, 1.0], [2.0, -0.5]], [[0.0], [1.0]], net)
    two_inputs = LinearPlant.from_arrays(np.diag([-1.0, 0.3, -2.0]), [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]],
                                         Network(0.05, 0.0, 0.08))
    for plant in (unstable, two_inputs):
        assert _failed(check_plant(plant, samples=4)) == []
    assert unstable.d_hi == 4


# ----------------------------------------------------------------------------- a plant of its own


@dataclasses.dataclass(frozen=True)
class Heater:
    """A toy plant written from the protocol alone: a first-order heater x' = -a x + b u whose gain b
    is uncertain in [b_lo, b_hi], lifted in closed form (Gamma(h) = b (1 - e^{-a h}) / a)."""

    a: float
    b_lo: float
    b_hi: float
    network: Network

    n_x = 1
    n_u = 1
    plant_kind = "heater"

    @property
    def d_hi(self) -> int:
        net = self.network
        return int(np.ceil((net.delay_max + net.max_lost * net.sampling_time) / net.sampling_time - 1e-9))

    @property
    def n_s(self) -> int:
        return 1 + self.d_hi

    def _gamma(self, h, b):
        return b * (1.0 - np.exp(-self.a * h)) / self.a

    def lifted(self, s_tilde, theta=None):
        s = np.asarray(s_tilde, dtype=float)
        b = np.ones(s.shape[:-1]) if theta is None else np.asarray(theta, dtype=float)[..., 0]
        Ts, d = self.network.sampling_time, self.d_hi
        batch = np.broadcast_shapes(s.shape[:-1], b.shape)
        s, b = np.broadcast_to(s, batch + s.shape[-1:]), np.broadcast_to(b, batch)
        G = [self._gamma(Ts - s[..., j], b) for j in range(d)] + [self._gamma(Ts, b)]
        A = np.zeros(batch + (self.n_s, self.n_s))
        B = np.zeros(batch + (self.n_s, 1))
        A[..., 0, 0] = np.exp(-self.a * Ts)
        B[..., 0, 0] = G[0]
        for j in range(1, d + 1):  # the command sent j periods ago, in force from s~_j to s~_{j-1}
            A[..., 0, j] = G[j] - G[j - 1]
        B[..., 1, 0] = 1.0
        for j in range(2, d + 1):
            A[..., j, j - 1] = 1.0
        return A, B

    def continuous(self, theta=None):
        return np.array([[-self.a]]), np.array([[1.0 if theta is None else float(theta[0])]])

    def parameter_corners(self):
        return np.array([[self.b_lo], [self.b_hi]])

    def coverage(self, samples=1000, seed=0):
        """The gain b enters affinely: the two corners' maps hold every b between (checked at samples)."""
        rng = np.random.default_rng(seed)
        s = np.sort(rng.uniform(0, self.network.sampling_time, (samples, self.d_hi)), axis=1)[:, ::-1]
        b = rng.uniform(self.b_lo, self.b_hi, samples)
        lam = (b - self.b_lo) / (self.b_hi - self.b_lo)
        A, B = self.lifted(s, b[:, None])
        A0, B0 = self.lifted(s, np.full((samples, 1), self.b_lo))
        A1, B1 = self.lifted(s, np.full((samples, 1), self.b_hi))
        res = max(np.max(np.abs(A - ((1 - lam)[:, None, None] * A0 + lam[:, None, None] * A1))),
                  np.max(np.abs(B - ((1 - lam)[:, None, None] * B0 + lam[:, None, None] * B1))))
        return {"samples": samples, "max_residual": float(res), "passed": bool(res <= 1e-12)}

    def to_dict(self):
        return {"kind": "heater", "a": self.a, "b": [self.b_lo, self.b_hi], "d_hi": self.d_hi}


def test_a_plant_written_from_the_protocol_alone_conforms() -> None:
    heater = Heater(0.8, 0.5, 2.0, Network(0.2, 0.05, 0.35, 1))
    assert isinstance(heater, Plant) and heater.d_hi == 3
    assert _failed(check_plant(heater)) == []


# ----------------------------------------------------------------------------- broken on purpose


class _Wrapped:
    """A plant with one of its answers replaced."""

    def __init__(self, plant, **override):
        self._plant, self._override = plant, override

    def __getattr__(self, name):
        return self._override.get(name, getattr(self._plant, name))


def test_a_lifted_map_of_the_wrong_period_fails_the_ode_check() -> None:
    good = LinearPlant.from_config(load_config(CONFIGS / "dc-motor.yaml"), str(CONFIGS))
    Ts = good.network.sampling_time
    wrong = _Wrapped(good, lifted=lambda s, theta=None: exact_lifted(good.A, good.B, 1.01 * Ts, s))
    checks = {c["name"]: c for c in check_plant(wrong)}
    ode = checks["the lifted map is the plant's ODE over a period"]
    assert not ode["passed"] and ode["value"] > 100 * ODE_TOL
    assert _failed(list(checks.values())) == ["the lifted map is the plant's ODE over a period"]


def test_a_slip_the_continuous_plant_forgets_fails_the_ode_check() -> None:
    model = build_model(load_config(CONFIGS / "icr-physics.yaml"))
    blind = _Wrapped(model, continuous=lambda theta=None: (np.asarray(model.A_c), np.asarray(model.B_c)))
    assert "the lifted map is the plant's ODE over a period" in _failed(check_plant(blind))


def test_a_network_deeper_than_the_lifted_state_fails() -> None:
    heater = Heater(0.8, 0.5, 2.0, Network(0.2, 0.05, 0.35, 1))
    shallow = _Wrapped(heater, network=Network(0.2, 0.05, 0.55, 1))  # needs 3.75 periods, keeps 3
    assert "the lifted state keeps every command that can act" in _failed(check_plant(shallow))


def test_a_shift_register_out_of_order_fails() -> None:
    heater = Heater(0.8, 0.5, 2.0, Network(0.2, 0.05, 0.35, 1))

    def swapped(s, theta=None):
        A, B = heater.lifted(s, theta)
        A = A.copy()
        A[..., [2, 3], :] = A[..., [3, 2], :]
        return A, B

    assert "the commands' shift register" in _failed(check_plant(_Wrapped(heater, lifted=swapped)))


@pytest.mark.parametrize("bad", [{"kind": "heater", "a": np.ones(2)}, {"kind": "heater", "a": float("nan")},
                                 {"kind": "", "a": 1.0}, {"kind": "boiler", "a": 1.0}])
def test_a_to_dict_that_is_not_plain_json_fails(bad) -> None:
    """Not JSON, not equal after a round trip, no kind, or a kind that is not the plant's plant_kind."""
    heater = Heater(0.8, 0.5, 2.0, Network(0.2, 0.05, 0.35, 1))
    assert _failed(check_plant(_Wrapped(heater, to_dict=lambda: bad))) == ["to_dict is plain JSON that reads back equal, of kind plant_kind"]


def test_the_closed_loop_is_the_open_loop_plus_the_gain() -> None:
    plant = LinearPlant.from_arrays([[0.0, 1.0], [-2.0, -0.3]], [[0.0], [1.0]], Network(0.1, 0.02, 0.15))
    s = np.array([[0.07], [0.0], [0.1]])
    K = np.array([[-1.0, -0.5, 0.2]])
    A, B = plant.lifted(s)
    assert np.allclose(exact_closed_loop(plant.A, plant.B, K, 0.1, s), A + B @ K, rtol=0, atol=1e-15)
