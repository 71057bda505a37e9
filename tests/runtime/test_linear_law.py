"""export of a linear plant's gain: the compiled C law and the generated Python module give numpy's
K @ xi bit for bit on random state sequences (the same sums in the same order), with the stored
commands shifted as the lifted model stores them."""

from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess

import numpy as np
import pytest

from robustsynth.errors import InputError
from robustsynth.runtime.export import export_controller

CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
STEPS = 200


def _gains(tmp_path, n=3, m=2, d=2, seed=0):
    rng = np.random.default_rng(seed)
    K = 0.3 * rng.standard_normal((m, n + d * m))  # small: the stored commands' feedback stays bounded
    gd = {"kind": "lti", "K": K.tolist(), "law": "u_k = K xi_k", "lifting": {"n": n, "m": m, "d": d, "states": None},
          "network": {"sampling_time": 0.1}, "certified": {"alpha": 0.9}, "config": {"name": "t"}}
    p = tmp_path / "gains.json"
    p.write_text(json.dumps(gd))
    return p, K


def _reference(K, xs, n, m, d):
    """u_k = K [x_k; u_{k-1}; ...; u_{k-d}] with the same summation order as the generated code."""
    sent = [0.0] * (d * m)
    out = []
    for x in xs:
        u = []
        for i in range(m):
            acc = 0.0
            for j in range(n):
                acc += K[i, j] * x[j]
            for j in range(d * m):
                acc += K[i, n + j] * sent[j]
            u.append(acc)
        sent = (u + sent)[: d * m]
        out.append(u)
    return np.array(out)


def test_python_module_matches_the_lifted_law(tmp_path) -> None:
    p, K = _gains(tmp_path)
    _, files = export_controller(p, "python", tmp_path / "py", allow_unverified=True)  # a made-up gain: the code only
    spec = importlib.util.spec_from_file_location("rs_lti", files[0])
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    xs = np.random.default_rng(1).standard_normal((STEPS, 3))
    ctl = mod.Controller()
    got = np.array([ctl.step(list(x)) for x in xs])
    assert np.array_equal(got, _reference(K, xs, 3, 2, 2))
    # and it is the lifted state's product: xi_k = [x_k; u_{k-1}; u_{k-2}]
    xi = np.concatenate([xs[5], got[4], got[3]])
    assert np.allclose(K @ xi, got[5], rtol=0, atol=1e-12)
    assert "xi_k = [x_k; u_(k-1); u_(k-2)]:" in files[0].read_text()  # as the module's docstring says (d = 2)


def test_the_lifted_state_is_written_as_it_is() -> None:
    """A review found "[x_k; u_(k-1); ...; u_(k-1)]" in the docstring of a d = 1 export."""
    from robustsynth.runtime.linear_law import _lifted

    assert [_lifted(d) for d in (1, 2, 4)] == ["[x_k; u_(k-1)]", "[x_k; u_(k-1); u_(k-2)]", "[x_k; u_(k-1); ...; u_(k-4)]"]


@pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on this machine")
def test_c_law_matches_bit_for_bit(tmp_path) -> None:
    p, K = _gains(tmp_path, n=2, m=1, d=3, seed=2)
    out = tmp_path / "c"
    export_controller(p, "c", out, allow_unverified=True)  # a made-up gain: the code only
    (out / "main.c").write_text("""#include <stdio.h>
#include "rs_lti.h"
int main(void) { rs_lti_state s; rs_lti_reset(&s); double x[RS_LTI_N], u[RS_LTI_M];
  while (scanf("%lf %lf", &x[0], &x[1]) == 2) { rs_lti_step(&s, x, u); printf("%.17g\\n", u[0]); } return 0; }
""")
    flags = ["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Werror"]
    subprocess.run([CC, *flags, "-o", str(out / "h"), str(out / "main.c"), str(out / "rs_lti.c")], check=True)
    xs = np.random.default_rng(3).standard_normal((STEPS, 2))
    text = "\n".join(f"{float(a)!r} {float(b)!r}" for a, b in xs)
    r = subprocess.run([str(out / "h")], input=text, capture_output=True, text=True, check=True)
    got = np.array([float(v) for v in r.stdout.split()])
    assert np.array_equal(got, _reference(K, xs, 2, 1, 3)[:, 0])


def test_robot_only_targets_and_bad_shapes_are_refused(tmp_path) -> None:
    p, _ = _gains(tmp_path)
    with pytest.raises(InputError, match="--to: ros2 is for the robot"):
        export_controller(p, "ros2", tmp_path / "r")
    gd = json.loads(p.read_text())
    gd["K"] = [[1.0, 2.0]]
    p.write_text(json.dumps(gd))
    with pytest.raises(InputError, match="K: must be 2 x 7"):
        export_controller(p, "c", tmp_path / "c2")
    assert not (tmp_path / "c2").exists() or not any((tmp_path / "c2").iterdir())


def test_the_written_mat_reads_as_its_gains_file_and_a_mismatched_config_is_refused(tmp_path) -> None:
    """synthesize writes gains.mat beside gains.json: export and verify read it as the same gains (it
    carries the file it was written with), a .mat whose K was changed is refused (a changed gain has no
    certificate), and export --config must describe the same plant and network."""
    from scipy.io import loadmat, savemat

    from robustsynth.artifacts.gains import load_gains
    from robustsynth.pipeline import plant_of, synthesis_stage

    from pathlib import Path

    from robustsynth.config import load_config

    configs = Path(__file__).resolve().parents[2] / "configs"
    cfg_path = configs / "dc-motor.yaml"

    out = tmp_path / "g"
    synthesis_stage(plant_of(load_config(cfg_path), cfg_path), out)
    assert load_gains(out / "gains.mat") == load_gains(out / "gains.json")
    d, _ = export_controller(out / "gains.mat", "python", tmp_path / "e", allow_unverified=True)  # synthesized only
    assert d["K"] == json.loads((out / "gains.json").read_text())["K"]
    m = loadmat(out / "gains.mat")
    m["K"] = m["K"] * 1.01
    savemat(tmp_path / "changed.mat", {k: v for k, v in m.items() if not k.startswith("__")})
    with pytest.raises(InputError, match="K differs from the gain it was certified as"):
        load_gains(tmp_path / "changed.mat")
    with pytest.raises(InputError, match="zbp.yaml has n = 2 states and m = 1 inputs"):
        export_controller(out / "gains.json", "c", tmp_path / "c", configs / "zbp.yaml")
    with pytest.raises(InputError, match="is the tracked robot's"):
        export_controller(out / "gains.json", "c", tmp_path / "c", configs / "tracks-box.yaml")
    # a gains.json whose K was edited is exported, but not as certified (its gains_id no longer matches)
    gd = json.loads((out / "gains.json").read_text())
    assert "certified law" in (tmp_path / "e" / "rs_lti.py").read_text()
    gd["K"][0][0] *= 1.01
    (tmp_path / "edited.json").write_text(json.dumps(gd))
    d, _ = export_controller(tmp_path / "edited.json", "python", tmp_path / "ed", allow_unverified=True)
    assert not d.get("certified") and "UNCERTIFIED" in (tmp_path / "ed" / "rs_lti.py").read_text()
    # and the other way round: the robot's gains (or a bare K) with a linear plant's config (a traceback before)
    robot = configs.parent / "results" / "baselines" / "tracks-box" / "gains.json"
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps({"K": json.loads(robot.read_text())["K"]}))
    for g in (robot, bare):
        with pytest.raises(InputError, match="dc-motor.yaml is a linear plant's"):
            export_controller(g, "c", tmp_path / "c", cfg_path)
    assert not (tmp_path / "c").exists()


def test_a_linear_plants_gain_is_exported_only_as_verified(tmp_path) -> None:
    """The rule of the robot's export for a linear plant's gain (issue 50): with the verification.json that
    `robustsynth verify` (pipeline.verification_stage) wrote beside it and passed, exported and said so in the files; without one,
    exit 2 (run verify first); a failed one, exit 1; --allow-unverified exports it marked UNVERIFIED."""
    from pathlib import Path

    from click.testing import CliRunner

    from robustsynth.artifacts.gains import gains_id, load_gains
    from robustsynth.cli import main
    from robustsynth.config import load_config
    from robustsynth.errors import VerificationFailed
    from robustsynth.pipeline import plant_of, synthesis_stage, verification_stage

    cfg_path = Path(__file__).resolve().parents[2] / "configs" / "dc-motor.yaml"
    out = tmp_path / "g"
    plant = plant_of(load_config(cfg_path), cfg_path)
    synthesis_stage(plant, out)
    with pytest.raises(InputError, match="no verification of this gain .* run `robustsynth verify --gains"):
        export_controller(out / "gains.json", "c", tmp_path / "none")
    r = CliRunner().invoke(main, ["export", str(out / "gains.json"), "--to", "python", "-o", str(tmp_path / "none")])
    assert r.exit_code == 2 and "robustsynth verify" in r.stderr and not (tmp_path / "none").exists()
    assert verification_stage(plant, out, None, runs=8, plots=False).result.passed
    r = CliRunner().invoke(main, ["export", str(out / "gains.json"), "--to", "c", "-o", str(tmp_path / "c")])
    assert r.exit_code == 0, r.output
    assert "proven: certified for the linear plant (plant: kind: lti)" in r.stdout
    for name in ("rs_lti.h", "rs_lti.c"):
        text = (tmp_path / "c" / name).read_text()
        assert "Verification: passed for exactly this gain (verification.json beside the gains file)." in text
        assert "with delays in [0.005, 0.04] s and no packet losses" in text and "UNVERIFIED" not in text
    d, _ = export_controller(out / "gains.mat", "json", tmp_path / "j")  # the .mat is the same gain
    assert d["proof"]["verification"]["status"] == "passed"
    # a failed verification of this gain (its fields as the verification stage writes them)
    v = json.loads((out / "verification.json").read_text())
    assert v["gains_id"] == gains_id(load_gains(out / "gains.json"))
    (out / "verification.json").write_text(json.dumps(dict(v, passed=False)))
    with pytest.raises(VerificationFailed, match="its verification failed"):
        export_controller(out / "gains.json", "python", tmp_path / "f")
    d, files = export_controller(out / "gains.json", "python", tmp_path / "f", allow_unverified=True)
    assert "rs_lti.py: the UNVERIFIED (its verification FAILED), certified law" in files[0].read_text()
