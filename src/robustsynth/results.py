"""The shapes every plant's results share (issue 52: one result schema).

A verdict is a list of :class:`Check`: one claim, the value the tool measured, the threshold it is
held to, and whether it holds.  A gain's margins are a :class:`MarginReport` of :class:`Margin`, each
with ``to_dict()`` (margin.json) and the line the CLI prints.  The robot's ``verify`` and the linear plant's ``verify_lti`` write
their checks in this one form (``to_dict``), so reports, sweeps, the regression and the console read
one key set: ``name``, ``passed``, ``value``, ``threshold``, ``detail``."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

__all__ = ["Err", "Check", "all_passed", "failed_names", "failed_lines", "to_jsonable", "Verdict", "CertificateCheck", "AnalysisResult",
           "Margin", "MarginReport"]


class Err(str):
    """A line for stderr (a warning, a failed check): the CLI shows it also under --quiet; every other line of a
    result's ``lines()`` goes to stdout."""


@dataclass(frozen=True)
class Check:
    """One claim of a verdict: ``value`` measured against ``threshold``; ``passed`` says whether it holds
    (how the two compare is the claim's own rule, stated in its name or detail)."""

    name: str
    passed: bool
    value: Any
    threshold: Any
    detail: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "passed": bool(self.passed), "value": self.value, "threshold": self.threshold,
                "detail": self.detail}


@dataclass(frozen=True)
class Verdict:
    """A gain's verification on a plant: whether every check passed and the checks (``Check.to_dict()``'s keys),
    with the plant's own record of how they were run (``details``: a linear plant's delay families, starts,
    periods, traces).  The robot's ``VerificationResult`` answers ``passed``, ``checks``, ``failed_checks``,
    ``details`` and ``to_dict()`` alike."""

    passed: bool
    checks: tuple[dict[str, Any], ...]
    details: Mapping[str, Any] = field(default_factory=dict)

    @property
    def failed_checks(self) -> list[str]:
        return failed_names(self.checks)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Verdict:
        """A verification's mapping (``passed``, ``checks`` and the rest: a linear plant's ``verify_lti``) as a
        Verdict; ``to_dict()`` gives it back."""
        return cls(bool(data["passed"]), tuple(data["checks"]),
                   {k: v for k, v in data.items() if k not in ("passed", "checks")})

    def to_dict(self) -> dict[str, Any]:
        """``passed``, ``checks`` and the details, as verification.json holds them."""
        return {"passed": bool(self.passed), "checks": list(self.checks), **self.details}

    def lines(self) -> list[str]:
        """What the CLI prints: each failed check (an :class:`Err`), then the verdict with every check's value and
        what it was run on (a linear plant's starts on the set's boundary and delay families)."""
        worst = ", ".join(f"{c['name'].split(' (')[0]} {c['value']:.4g}" for c in self.checks)
        starts, families = self.details.get("starts"), self.details.get("families") or ()
        where = (f"{starts} starts on the set's boundary x {len(families)} delay families" if starts
                 else "delay sequences from rest")
        failed = [Err(f"FAILED: {c['name']} (value {c['value']:.6g}, threshold {c['threshold']:g}): {c['detail']}")
                  for c in self.checks if not c["passed"]]
        return failed + [
            f"verification {'passed' if self.passed else 'FAILED'}: {len(self.checks)} checks, {where}; {worst}"]


@dataclass(frozen=True)
class CertificateCheck:
    """A certificate re-checked in numpy, any plant: ``passed`` when every family of conditions was proven,
    ``checks`` one item per family (``name``, ``max_eig``, ``threshold``, ``margin_found``, ``passed``,
    ``verified``, ...: the largest eigenvalue of -L against its threshold), ``figures`` what it proves
    (decay rate, bounds, gains, in the plant's units), ``reason`` why it failed."""

    passed: bool
    checks: tuple[dict[str, Any], ...]
    figures: dict[str, Any] = field(default_factory=dict)
    reason: str = ""

    @property
    def min_eig_margin(self) -> float:
        """Smallest margin lambda_min(L) over the LMIs (the margin actually found)."""
        vals = [c["margin_found"] for c in self.checks if c.get("margin_found") is not None]
        return float(min(vals)) if vals else float("nan")

    def to_dict(self) -> dict[str, Any]:
        return {"passed": bool(self.passed), "checks": [dict(c) for c in self.checks], "figures": dict(self.figures),
                "reason": self.reason}

    def lines(self) -> list[str]:
        """One line: proven (how many families, the smallest margin found) or not, and why (an :class:`Err`)."""
        if not self.passed:
            return [Err(f"certificate check FAILED: {self.reason or ', '.join(failed_names(self.checks))}")]
        n = len(self.checks)
        return [f"certificate check passed: {n} {'family' if n == 1 else 'families'} of conditions proven in numpy, "
                f"smallest margin found {self.min_eig_margin:.3g}"]


@dataclass(frozen=True)
class AnalysisResult:
    """A given gain's certificate searched, any plant (``robustsynth.synthesis.analysis.analyze_stability`` for the
    robot, ``robustsynth.synthesis.lti.analyze_lti`` for a linear plant): ``certified`` when a certificate was found
    and passed its numpy re-check (``check``, ``certificate``: P, the multipliers, ...); ``status`` 'certified',
    'infeasible' (no Lyapunov function of the kinds tried), 'rejected' (the re-check refused the solver's point) or
    'failed' (the solvers)."""

    certified: bool
    status: str
    lyapunov: str | None = None
    certificate: dict[str, Any] | None = None
    check: CertificateCheck | None = None
    solve_time_s: float = 0.0
    attempts: tuple[str, ...] = field(default_factory=tuple)

    @property
    def P(self) -> Any:
        """The certified set's matrix (None without a certificate)."""
        return None if self.certificate is None else self.certificate.get("P")

    def to_dict(self) -> dict[str, Any]:
        """The search's outcome as plain data (arrays as lists): status, the certificate and its check."""
        return to_jsonable({"certified": bool(self.certified), "status": self.status, "lyapunov": self.lyapunov,
                            "certificate": self.certificate,
                            "check": None if self.check is None else self.check.to_dict(),
                            "solve_time_s": self.solve_time_s, "attempts": list(self.attempts)})

    def lines(self) -> list[str]:
        """One line: the status, the Lyapunov function kinds tried and the solve time, then the check's line."""
        tried = f" (tried: {', '.join(self.attempts)})" if self.attempts else ""
        head = (f"certificate found ({self.lyapunov} Lyapunov function)" if self.certified
                else f"no certificate: {self.status}") + f"{tried}, {self.solve_time_s:.2f} s of solves"
        return [head] + (self.check.lines() if self.check is not None else [])


def to_jsonable(obj: Any) -> Any:
    """numpy arrays -> lists of rows, numpy scalars -> Python numbers, tuples -> lists, non-finite floats -> None
    (what every result's ``to_dict`` and the files hold).  The plain types first, and a numeric array with no
    non-finite entry or a list's finite floats taken as they are: a gains.json of 1.4 MB (the default robot's
    certificate) went through this in 0.3 s, one call per number."""
    t = type(obj)
    if t is float:
        return obj if math.isfinite(obj) else None
    if t is str or t is int or t is bool or obj is None:
        return obj
    if t is list or t is tuple:  # a finite float is kept as it is (v - v is 0.0 only for one)
        return [v if type(v) is float and v - v == 0.0 else to_jsonable(v) for v in obj]
    if t is dict:
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        if obj.dtype in _PLAIN_DTYPES and (obj.dtype.kind != "f" or bool(np.isfinite(obj).all())):
            return obj.tolist()  # Python ints, bools or finite floats already
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


_PLAIN_DTYPES = tuple(np.dtype(x) for x in ("float64", "float32", "int64", "int32", "bool"))


def all_passed(checks: Iterable[Mapping[str, Any]]) -> bool:
    """Whether every check (as written by :meth:`Check.to_dict`) passed."""
    return all(c["passed"] for c in checks)


def failed_names(checks: Iterable[Mapping[str, Any]]) -> list[str]:
    """The names of the checks that failed, in order."""
    return [c["name"] for c in checks if not c["passed"]]


def failed_lines(checks: Iterable[Mapping[str, Any]]) -> list[str]:
    """One :class:`Err` per failed check: its name, value against threshold (where both are numbers) and detail."""
    lines: list[str] = []
    for c in checks:
        if c["passed"]:
            continue
        v, t = c.get("value"), c.get("threshold")
        what = f" (value {v:.4g}, threshold {t:.4g})" if isinstance(v, (int, float)) and isinstance(t, (int, float)) else ""
        lines.append(Err(f"FAILED: {c['name']}{what}" + (f": {c['detail']}" if c.get("detail") else "")))
    return lines


@dataclass(frozen=True)
class Margin:
    """One margin: the configured value, the certified and exhibited ends, the witness.

    ``searched``: the range the instability search covered (its end is where "no instability found" stops);
    ``at_least``: the certificate held up to the end of its own search and nothing destabilized before it,
    so the true margin is at least ``certified``; ``details``: the plant's own figures of the search (how far,
    how long, how many solves), written into ``to_dict()`` beside the common keys; ``families``: the sequences
    the instability search tried (the line says them where it found none)."""

    name: str
    unit: str
    direction: str  # 'max' (larger is better: delay) or 'min' (smaller is better: slip)
    configured: float | None
    certified: float | None
    exhibited: float | None
    witness: dict[str, Any] | None
    searched: tuple[float, float] | None
    note: str = ""
    evaluations: tuple[dict[str, Any], ...] = ()
    at_least: bool = False
    details: Mapping[str, Any] = field(default_factory=dict)
    families: str = ""  # what the instability search tried, said where it found nothing

    @property
    def integer(self) -> bool:
        """A count (lost packets): its ends are whole numbers, and its gap is said in them."""
        return self.unit == "packets"

    @property
    def gap(self) -> float | None:
        """|exhibited - certified| / exhibited: the share of the true margin the certificate may miss.
        None for a count (packets): a share of a few packets says nothing (issue 50: "may miss 75.0 %"
        of 4 packets); :attr:`gap_packets` gives that gap in packets."""
        if self.integer or self.certified is None or self.exhibited is None or self.exhibited == 0:
            return None
        return abs(self.exhibited - self.certified) / abs(self.exhibited)

    @property
    def gap_packets(self) -> int | None:
        """For a count: how many packets the certificate may miss.  The truth is a whole number in
        [certified, exhibited - 1] (exhibited destabilizes), so this is exhibited - 1 - certified, 0
        where the certificate is exact."""
        if not self.integer or self.certified is None or self.exhibited is None:
            return None
        return max(0, int(round(self.exhibited)) - 1 - int(round(self.certified)))

    @classmethod
    def from_record(cls, name: str, record: Mapping[str, Any], delay_min: float = 0.0) -> Margin:
        """A linear plant's margin record (``robustsynth.margins.linear``'s ``delay_margin``, also gains.json's
        ``delay_margin``, or ``loss_margin``) as a Margin: the common keys, the search's own figures in
        ``details`` (``delay_min``: where the delay search started)."""
        if name == "delay_max":
            searched: tuple[float, float] = (delay_min, record["searched_up_to"])
            details = {"families": record["searched"], "searched_periods": record["searched_periods"],
                       "certificate_searched_up_to": record["certificate_searched_up_to"], "solves": record["solves"],
                       "search_s": record["search_s"], "certificate_s": record["certificate_s"]}
            unit = "s"
        else:
            searched, details, unit = (0, record["searched_up_to"]), {"time_s": record["time_s"]}, "packets"
        return cls(name, unit, "max", record["configured"], record["certified"], record["exhibited"], record["witness"],
                   searched, record.get("note", ""), (), bool(record["at_least"]), details,
                   details.get("families", f"periodic delay/loss sequences, up to {record['searched_up_to']} lost in "
                                           "a row"))

    def to_dict(self) -> dict[str, Any]:
        d = {k: v for k, v in asdict(self).items() if k not in {"name", "evaluations", "details", "families"}}
        d["searched"] = list(self.searched) if self.searched is not None else None
        d["gap"] = self.gap
        if self.integer:
            d["gap_packets"] = self.gap_packets
        d["evaluations"] = list(self.evaluations)
        d.update(self.details)
        return d

    def line(self) -> str:
        def f(x: float | None) -> str:
            return "none" if x is None else f"{x:.4g}"

        def u(x: float | None) -> str:  # no unit after "none" (review: "certified none s")
            if x is None or not self.unit:
                return f(x)
            if self.integer:  # "1 packet", "2 packets" (issue 50: "exhibited 1 packets")
                return _packets(x)
            return f"{f(x)} {self.unit}"

        text = (f"{self.name}: configured {u(self.configured)}, certified {'at least ' if self.at_least else ''}"
                f"{u(self.certified)}, exhibited {u(self.exhibited)}")
        if self.gap is not None:  # the share of the exhibited margin the certificate may miss
            text += f" (the certificate may miss {100 * self.gap:.1f} % of the exhibited margin)"
        elif self.gap_packets is not None:  # a count: the gap in packets, never a share
            text += (" (the certificate misses no packet of the exhibited margin)" if self.gap_packets == 0 else
                     f" (the certificate may miss up to {_packets(self.gap_packets)} of the exhibited margin)")
        if self.exhibited is None and self.searched is not None:
            text += (f" (no instability found in [{self.searched[0]:.4g}, {self.searched[1]:.4g}]"
                     + (f" among {self.families}" if self.families else "") + ")")
        if self.witness and "delays" in self.witness:  # the destabilizing sequence, as the report shows it
            delays = ", ".join("lost" if x is None else f"{x:.6g}" for x in self.witness["delays"])
            text += (f" (witness: period {self.witness['period']}, delays [{delays}], spectral radius "
                     f"{self.witness['spectral_radius']:.6f})")
        if self.note and self.certified is None and self.exhibited is None and self.searched is None:
            text += f" ({self.note})"
        return text


def _packets(n: float) -> str:
    """A whole number of packets, singular or plural."""
    k = int(round(n))
    return f"{k} packet" + ("" if k == 1 else "s")


@dataclass(frozen=True)
class MarginReport:
    """A gain's margins, in the order they are shown, with what they were measured on (``meta``);
    ``notes``: lines shown after the margins (what they do not cover); ``warnings``: lines for stderr
    (what may make them meaningless, e.g. an uncontrollable plant)."""

    margins: tuple[Margin, ...]
    meta: dict[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    def __getitem__(self, name: str) -> Margin:
        for m in self.margins:
            if m.name == name:
                return m
        raise KeyError(name)

    def get(self, name: str) -> Margin | None:
        """The margin called ``name``, None if the plant has none of that name (a linear plant: no slip_min)."""
        try:
            return self[name]
        except KeyError:
            return None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.margins)

    @property
    def delay_max(self) -> Margin:
        return self["delay_max"]

    @property
    def dropouts(self) -> Margin:
        return self["dropouts"]

    @property
    def slip_min(self) -> Margin | None:
        return self.get("slip_min")

    @property
    def slip_parameters(self) -> tuple[Margin, ...]:
        """The icr model's other slip parameters' margins (yaw_min, icr_offset_max); () for any other."""
        return tuple(m for m in self.margins if m.name in ("yaw_min", "icr_offset_max"))

    def to_dict(self) -> dict[str, Any]:
        out = {m.name: m.to_dict() for m in self.margins}
        out["meta"] = dict(self.meta)
        return out

    def lines(self) -> list[str]:
        """What the CLI prints: one line per margin, then the notes (the warnings go to stderr)."""
        return [m.line() for m in self.margins] + list(self.notes)
