"""Many diagonal multipliers are written compactly (``{"diag": [...]}``) and read back as the same matrices: the
linearized turning model at d_hi 2 wrote a gains.json of 9.2 MB (48 MB at d_hi 3), beyond what ``load_gains`` reads.
Cross-checked on a committed certificate: its compact form is proven by the re-check with the same figures as the
full one, and its .mat variables are the same arrays."""

from __future__ import annotations

import json

import numpy as np

from robustsynth.artifacts.files import to_jsonable
from robustsynth.artifacts.gains import MAX_GAINS_BYTES, gains_mat_vars, load_gains
from robustsynth.certificate import check_certificate, lmis as cert_lmis
from robustsynth.certificate.lmis import COMPACT_ABOVE, compact_multipliers, dense_multiplier

from ..conftest import ROOT, committed_gain


def test_only_many_diagonal_multipliers_are_compacted() -> None:
    small = [np.diag([1.0, 2.0])] * 3
    assert compact_multipliers(small) is small  # few entries: as they are
    n = int(np.sqrt(COMPACT_ABOVE)) + 1
    big = [np.diag(np.arange(1.0, n + 1.0))]
    out = compact_multipliers(big)
    assert out == [{"diag": out[0]["diag"]}] and np.array_equal(dense_multiplier(out[0]), big[0])
    full = big[0].copy()
    full[0, 1] = full[1, 0] = 0.5
    assert compact_multipliers([full]) == [full]  # one not diagonal: every one as it is
    assert dense_multiplier([[1.0]]) == [[1.0]] and dense_multiplier({"diag": [2.0], "x": 1}) == {"diag": [2.0], "x": 1}


def test_a_compact_certificate_is_proven_as_the_full_one_and_read_back(monkeypatch, tmp_path) -> None:
    model, K, cert = committed_gain("default")  # 48 diagonal multipliers of 60 channels: written whole
    Ms = cert["multipliers"]["M"]
    assert all(isinstance(M, list) for M in Ms)
    monkeypatch.setattr(cert_lmis, "COMPACT_ABOVE", 0)
    compact = compact_multipliers(Ms)
    assert all(set(M) == {"diag"} for M in compact)
    full_chk = check_certificate(model, K, cert)
    chk = check_certificate(model, K, dict(cert, multipliers=dict(cert["multipliers"], M=compact)))
    assert full_chk.passed and chk.passed and chk.figures == full_chk.figures
    gd = json.loads((ROOT / "results" / "baselines" / "default" / "gains.json").read_text())
    dense_vars = gains_mat_vars(gd)
    gd["certificate"]["multipliers"]["M"] = compact
    path = tmp_path / "gains.json"
    path.write_text(json.dumps(to_jsonable(gd), indent=2))
    assert path.stat().st_size < (ROOT / "results" / "baselines" / "default" / "gains.json").stat().st_size / 5
    back = load_gains(path)
    assert check_certificate(model, K, back["certificate"]).figures == full_chk.figures
    assert np.array_equal(gains_mat_vars(back)["M"], dense_vars["M"])
    # a malformed compact entry fails the re-check, saying why (not a traceback)
    bad = check_certificate(model, K, dict(cert, multipliers=dict(cert["multipliers"], M=[{"diag": "x"}] + compact[1:])))
    assert not bad.passed and "unreadable" in bad.reason
    assert path.stat().st_size < MAX_GAINS_BYTES
