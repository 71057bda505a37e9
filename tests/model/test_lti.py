"""A linear plant from its config (plant: kind: lti, robustsynth.model.lti): its arrays from the config, a
file or the matrices, each bad input one line; and the robot's calls refusing its config."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.config import load_config
from robustsynth.model.lti import lti_plant

ZBP_A = np.array([[0.0, 1.0], [0.0, -0.1]])
ZBP_B = np.array([[0.0], [0.1]])
ZBP_K = -np.array([[3.75, 11.5]])


def _zbp_cfg(**over):
    base = {"name": "zbp-test", "plant": {"kind": "lti", "A": ZBP_A.tolist(), "B": ZBP_B.tolist()},
            "controller": {"gain": ZBP_K.tolist()}, "network": {"sampling_time": 1.0, "delay": {"min": 0.0, "max": 0.5}}}
    for k, v in over.items():
        base[k] = v
    return load_config(base)


def test_lti_plant_from_arrays_and_files(tmp_path) -> None:
    from scipy.io import savemat

    from robustsynth.errors import ConfigError, InputError

    pl = lti_plant(_zbp_cfg())
    assert np.array_equal(pl["A"], ZBP_A) and pl["controllable"] and pl["states"] == ["x1", "x2"]
    np.savez(tmp_path / "p.npz", A=ZBP_A, B=ZBP_B)
    savemat(tmp_path / "p.mat", {"A": ZBP_A, "B": ZBP_B})
    for f in ("p.npz", "p.mat"):
        pf = lti_plant(_zbp_cfg(plant={"kind": "lti", "file": f}), str(tmp_path))
        assert np.array_equal(pf["A"], ZBP_A) and np.array_equal(pf["B"], ZBP_B)
    np.savez(tmp_path / "q.npz", A=ZBP_A)
    with pytest.raises(InputError, match="q.npz: no array 'B'"):
        lti_plant(_zbp_cfg(plant={"kind": "lti", "file": "q.npz"}), str(tmp_path))
    with pytest.raises(ConfigError, match="plant.A: must be square"):
        _zbp_cfg(plant={"kind": "lti", "A": [[0, 1]], "B": [[0], [1]]})
    with pytest.raises(ConfigError, match=r"plant.*A\[1\]\[0\]: must be a finite number"):
        _zbp_cfg(plant={"kind": "lti", "A": [[0, 1], [None, 0]], "B": [[0], [1]]})
    with pytest.raises(InputError, match="controller.gain: must be a finite m x n"):
        lti_plant(_zbp_cfg(controller={"gain": [[1.0]]}))
    with pytest.raises(ConfigError, match="plant.kind"):
        load_config({**_zbp_cfg().model_dump(mode="json"), "plant": {"kind": "boat"}})
    unctrl = lti_plant(_zbp_cfg(plant={"kind": "lti", "A": [[-1, 0], [0, -2]], "B": [[1], [0]]}))
    assert not unctrl["controllable"]


def test_bad_plant_files_and_missing_matrices_are_one_line_each(tmp_path) -> None:
    """A corrupt file is bad input naming plant.file (an empty .npz raised EOFError, which the CLI took
    for an interrupt; a garbage .mat a traceback); a missing matrix is named as missing."""
    from robustsynth.errors import ConfigError, InputError

    (tmp_path / "empty.npz").write_bytes(b"")
    (tmp_path / "garbage.mat").write_text("garbage")
    (tmp_path / "cut.npz").write_bytes(b"PK\x03\x04 truncated")
    (tmp_path / "text.npz").write_text("A = [[0, 1], [0, -0.1]]\n")  # not an archive: numpy spoke of pickled data
    for f in ("empty.npz", "garbage.mat", "cut.npz", "text.npz"):
        with pytest.raises(InputError, match=rf"plant.file: .*{f}: cannot read"):
            lti_plant(_zbp_cfg(plant={"kind": "lti", "file": f}), str(tmp_path))
    with pytest.raises(ConfigError, match=r"plant\.B: required key is missing"):
        _zbp_cfg(plant={"kind": "lti", "A": ZBP_A.tolist()})
    with pytest.raises(ConfigError, match=r"plant\.A: give A and B, or file \(not both\)"):
        _zbp_cfg(plant={"kind": "lti", "A": ZBP_A.tolist(), "file": "p.npz"})


def test_a_plant_too_fast_for_its_sampling_or_empty_is_one_line() -> None:
    """A mode that grows past double precision over the lifted horizon, and a plant without states, are bad
    input (a review found 'SVD did not converge' and 'need at least one array' tracebacks); a fast *stable*
    mode of the same size is accepted, and so is the controllability test of a large A (scaled first)."""
    from robustsynth.errors import InputError

    for big in (1e6, 1e300):
        with pytest.raises(InputError, match=r"plant: e\^\(A t\) of A overflows over the lifted horizon"):
            lti_plant(_zbp_cfg(plant={"kind": "lti", "A": [[0.0, 1.0], [0.0, big]], "B": ZBP_B.tolist()}))
    stiff = lti_plant(_zbp_cfg(plant={"kind": "lti", "A": [[0.0, 1.0], [0.0, -1e6]], "B": ZBP_B.tolist()}))
    assert stiff["controllable"]
    with pytest.raises(InputError, match="at least one state"):
        from robustsynth.model.lti import lti_plant_from

        lti_plant_from(np.zeros((0, 0)), np.zeros((0, 1)))


def test_the_robots_calls_refuse_a_linear_plants_config() -> None:
    from robustsynth.errors import InputError
    from robustsynth.margins import margin
    from robustsynth.model import build_model
    from robustsynth.synthesis import synthesize

    cfg = _zbp_cfg()
    for call in (lambda: build_model(cfg), lambda: synthesize(cfg), lambda: margin(cfg, ZBP_K)):
        with pytest.raises(InputError, match=r"linear plant's .*LinearPlant.from_config\(config\).*robustsynth.margin take"):
            call()
