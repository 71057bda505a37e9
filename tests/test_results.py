"""The result shapes every plant shares (results.py): each says in lines what the CLI prints of it, its failures as
:class:`Err` lines (stderr), and gives the same data back from ``to_dict``."""

from __future__ import annotations

from robustsynth.results import AnalysisResult, CertificateCheck, Err, Verdict, failed_lines

CHECKS = ({"name": "invariance (boundary)", "passed": True, "value": 0.98, "threshold": 1.0, "detail": ""},
          {"name": "outputs", "passed": False, "value": 1.2, "threshold": 1.0, "detail": "angle beyond"})


def test_a_verdict_says_its_failed_checks_on_stderr_and_every_checks_value() -> None:
    v = Verdict(False, CHECKS, {"starts": 8, "families": [1, 2]})
    assert v.lines() == ["FAILED: outputs (value 1.2, threshold 1): angle beyond",
                         "verification FAILED: 2 checks, 8 starts on the set's boundary x 2 delay families; "
                         "invariance 0.98, outputs 1.2"]
    assert [isinstance(line, Err) for line in v.lines()] == [True, False]
    assert Verdict.from_dict(v.to_dict()) == v
    rest = Verdict(True, CHECKS[:1]).lines()
    assert rest == ["verification passed: 1 checks, delay sequences from rest; invariance 0.98"]


def test_failed_lines_say_value_and_threshold_only_where_both_are_numbers() -> None:
    checks = [{"name": "a", "passed": False, "value": 0.05, "threshold": 0.04, "detail": "too far"},
              {"name": "b", "passed": False, "detail": "unstable"}, {"name": "c", "passed": False},
              {"name": "d", "passed": True, "value": 1, "threshold": 2}]
    assert failed_lines(checks) == ["FAILED: a (value 0.05, threshold 0.04): too far", "FAILED: b: unstable",
                                    "FAILED: c"]
    assert all(isinstance(line, Err) for line in failed_lines(checks))


def test_a_certificate_check_says_what_it_proved_or_why_not() -> None:
    fam = ({"name": "decrease", "passed": True, "margin_found": 2e-3}, {"name": "bounds", "passed": True,
                                                                        "margin_found": 5e-4})
    ok = CertificateCheck(True, fam, {"decay": 0.9})
    assert ok.lines() == ["certificate check passed: 2 families of conditions proven in numpy, smallest margin found "
                          "0.0005"]
    bad = CertificateCheck(False, ({**fam[0], "passed": False},), reason="")
    assert bad.lines() == ["certificate check FAILED: decrease"] and isinstance(bad.lines()[0], Err)
    assert CertificateCheck(False, (), reason="vertex block 3 not proven").lines() == [
        "certificate check FAILED: vertex block 3 not proven"]


def test_an_analysis_says_its_status_then_its_check() -> None:
    check = CertificateCheck(True, ({"name": "decrease", "passed": True, "margin_found": 1e-3},))
    found = AnalysisResult(True, "certified", "common", {"P": [[1.0]]}, check, 1.234, ("common",))
    assert found.lines() == ["certificate found (common Lyapunov function) (tried: common), 1.23 s of solves",
                             "certificate check passed: 1 family of conditions proven in numpy, smallest margin "
                             "found 0.001"]
    none = AnalysisResult(False, "infeasible", attempts=("common", "parameter-dependent"))
    assert none.lines() == ["no certificate: infeasible (tried: common, parameter-dependent), 0.00 s of solves"]


def test_an_analysis_is_plain_data() -> None:
    import json

    import numpy as np

    check = CertificateCheck(True, ({"name": "decrease", "passed": True, "margin_found": np.float64(1e-3)},))
    found = AnalysisResult(True, "certified", "common", {"P": np.eye(2), "multipliers": (np.ones(1),)}, check, 0.5)
    d = json.loads(json.dumps(found.to_dict()))
    assert d["certificate"]["P"] == [[1.0, 0.0], [0.0, 1.0]] and d["check"] == json.loads(json.dumps(check.to_dict(),
                                                                                                   default=float))
    assert (d["status"], d["certified"], d["attempts"]) == ("certified", True, [])
