"""The synthesis objectives: what each one proves and what it needs, as data (issue 52, item 5).

An objective is one :class:`Objective` in ``OBJECTIVES`` (:func:`register` adds one) and its code on the two
floors that act on it: the design (``design``, a module of ``robustsynth.synthesis.objectives``, the only
floor that imports the solver) and the certificate's rows (``check``, a module of
``robustsynth.certificate.objectives``, the proof checker, which must not import the solver).  Everything
else (the config's validation, the CLI's choices, the reports, the judges, the diagnosis) reads the
descriptor: what kind of guarantee the objective gives, the figure it optimizes, what it cannot cover and why.
docs/architecture.md, "How to add an objective", is the list a new one follows.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Literal

__all__ = ["Objective", "OBJECTIVES", "register", "unregister", "objective", "names", "choices_text", "listed",
           "certified_keys", "scalar_figures", "labelled_figures", "ROBOT_FIGURES_SHOWN", "PLANTS", "BUILT_IN"]

PLANTS = ("tracked-robot", "lti")  # the plant kinds an objective may serve
# the robot's figures that reports and the console show in lines of their own (the set's and the decay's)
ROBOT_FIGURES_SHOWN = ("robust_stability", "decay_rate", "ultimate_bound", "motor_speed_bound")


@dataclass(frozen=True)
class Objective:
    """What an objective proves and needs.

    Attributes
    ----------
    name : str
        The value of ``synthesis.objective`` and of ``--objective``.
    guarantee : str
        What its certificate proves and the judges check: ``set``, an invariant, attracting set (its bounds,
        its level: the robot's certificate then carries ``alpha`` and ``beta``, ``V+ <= (1 - alpha) V +
        sum beta_i w_i^2``, and its check the figure ``ellipsoid_level``, which the lifted judge and the
        figures read); ``decay``, a decay rate of the disturbance-free state (the certificate's ``r2``, read by
        the lifted judge); ``gain``, an l2 gain.
    figure : str
        The certified figure it optimizes (a key of the tracked robot's gains file's ``certified``; a linear
        plant's gains file names its figures its own way: ``decay``, ``outputs``, ``hinf_gain``).
    text : str
        What it optimizes, in a sentence (the synthesis report's).
    design : str
        The module of its design (``robot`` and ``linear`` functions; see
        ``robustsynth.synthesis.objectives``).
    check : str or None
        The module of its certificate's rows on the robot's vertices (``rows``; see
        ``robustsynth.certificate.objectives``); None for an objective of the linear plant only.
    plants : tuple of str
        The plant kinds it serves (``PLANTS``).
    needs_disturbance : bool
        A linear plant's objective that needs ``plant.disturbance``.
    common_lyapunov_only : bool
        Only one common Lyapunov matrix (``synthesis.lyapunov: common``).
    nonlinear_kinematics : bool
        Its certificate may be written on the nonlinear kinematics (``synthesis.kinematics: nonlinear``);
        otherwise its LMIs are the linearization's, also when the model is built for the nonlinear ones.
    turns : str or None
        Why it cannot certify a turning reference (``reference.turn_radius``); None when it can.
    within_period : str or None
        Why its certificate cannot cover slip changing within a period; None when it can.
    figures : tuple of str
        The keys of the robot's ``certified`` figures its certificate writes (``figure`` among them); the
        gains file's ``certified`` holds every robot objective's (``certified_keys()``).  Each is an upper
        bound (a file claiming a smaller value than the re-check proves fails ``verify``).
    label : str
        Its ``figure`` in words, where reports and the console show a figure they have no line of their own for
        (a scalar figure of a new objective: ``label value``); required for such a figure.
    """

    name: str
    guarantee: Literal["set", "decay", "gain"]
    figure: str
    text: str
    design: str
    check: str | None = None
    plants: tuple[str, ...] = PLANTS
    needs_disturbance: bool = False
    common_lyapunov_only: bool = False
    nonlinear_kinematics: bool = False
    turns: str | None = None
    within_period: str | None = None
    figures: tuple[str, ...] = ()
    label: str = ""

    def __post_init__(self) -> None:
        if self.guarantee not in ("set", "decay", "gain"):
            raise ValueError(f"objective {self.name}: guarantee {self.guarantee!r} is not set, decay or gain")
        if not set(self.plants) <= set(PLANTS):
            raise ValueError(f"objective {self.name}: plants {self.plants} beyond {PLANTS}")
        if "tracked-robot" in self.plants and self.check is None:
            raise ValueError(f"objective {self.name}: an objective of the tracked robot needs its certificate's rows "
                             "(check)")
        if self.figures and self.figure not in self.figures:
            raise ValueError(f"objective {self.name}: its figure {self.figure} is not among the figures it writes")
        if "tracked-robot" in self.plants and self.figure not in ROBOT_FIGURES_SHOWN and not self.label:
            raise ValueError(f"objective {self.name}: its figure {self.figure} needs a label (how reports name it)")


OBJECTIVES: dict[str, Objective] = {o.name: o for o in (
    Objective(
        "ultimate-bound", "set", "ultimate_bound",
        "smallest ellipsoid `xi' P xi <= level` that is invariant and attracting for every admissible delay "
        "sequence and every slip in its box (docs/theory.md §6b), minimizing the weighted squared bounds on "
        "e_x, e_y, e_theta; line search over alpha",
        design="robustsynth.synthesis.objectives.ultimate_bound", check="robustsynth.certificate.objectives.ultimate_bound",
        needs_disturbance=True, nonlinear_kinematics=True, figures=("decay_rate", "ultimate_bound", "motor_speed_bound"),
        label="ultimate bound"),
    Objective(
        "stability", "decay", "decay_rate",
        "robust quadratic stability for all |Delta_k| <= 1 (the paper's stated goal) with the best decay rate r, "
        "`V(xi[k+1]) <= r^2 V(xi[k])` without slip (docs/theory.md §6a); bisection on r",
        design="robustsynth.synthesis.objectives.stability", check="robustsynth.certificate.objectives.stability",
        figures=("decay_rate",), label="decay rate"),
    Objective(
        "hinf", "gain", "hinf_gain",
        "smallest l2 gain gamma from the slip deviation d to the weighted error z = diag(w) e, for every "
        "admissible delay sequence (docs/theory.md §6d)",
        design="robustsynth.synthesis.objectives.hinf", check="robustsynth.certificate.objectives.hinf",
        needs_disturbance=True, common_lyapunov_only=True, turns="hinf bounds the slip input only",
        within_period="the H-infinity gain is stated for the slip input B_d w, which does not describe slip "
                      "changing within a period", figures=("hinf_gain",), label="l2 gain slip -> weighted error"),
)}


BUILT_IN = tuple(OBJECTIVES)  # the registry's own: unregister refuses them


def register(obj: Objective) -> Objective:
    """Add an objective to the registry (``OBJECTIVES``: its one registry line).

    Parameters
    ----------
    obj : Objective
        Its descriptor.

    Returns
    -------
    Objective
        ``obj``.

    Raises
    ------
    ValueError
        The name is taken (``auto`` included: a linear plant's config reads it).
    """
    if obj.name in OBJECTIVES or obj.name == "auto":
        raise ValueError(f"objective {obj.name}: the name is taken")
    OBJECTIVES[obj.name] = obj
    return obj


def unregister(name: str) -> None:
    """Remove an objective added by :func:`register` (a test's toy); nothing when there is none.

    Parameters
    ----------
    name : str
        Its name.

    Raises
    ------
    ValueError
        ``name`` is one of the registry's own (``BUILT_IN``).
    """
    if name in BUILT_IN:
        raise ValueError(f"objective {name}: built in, not removable")
    OBJECTIVES.pop(name, None)


def names(plant: str | None = None) -> tuple[str, ...]:
    """The objectives' names in the registry's order.

    Parameters
    ----------
    plant : str or None
        Only those serving this plant kind (``tracked-robot`` or ``lti``).

    Returns
    -------
    tuple of str
        The names.
    """
    return tuple(n for n, o in OBJECTIVES.items() if plant is None or plant in o.plants)


def choices_text(given: tuple[str, ...]) -> str:
    """The names as a validation message lists them.

    Parameters
    ----------
    given : tuple of str
        The names.

    Returns
    -------
    str
        ``'a', 'b' or 'c'``.
    """
    return _joined([f"'{n}'" for n in given], "or")


def _joined(words: list[str], conj: str) -> str:
    """``a``, ``a or b``, ``a, b or c`` (``conj`` before the last word); ``none`` for no words."""
    if not words:
        return "none"
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + f" {conj} " + words[-1]


def listed(where: Callable[[Objective], bool], plant: str = "tracked-robot", conj: str = "or") -> str:
    """The names of ``plant``'s objectives for which ``where`` holds, as a message lists them.

    Parameters
    ----------
    where : callable
        Objective -> bool.
    plant : str
        The plant kind.
    conj : str
        The word before the last name (``or``, ``and``).

    Returns
    -------
    str
        ``a``, ``a or b``, ``a, b or c``.
    """
    return _joined([o.name for o in OBJECTIVES.values() if plant in o.plants and where(o)], conj)


def certified_keys() -> tuple[str, ...]:
    """The keys of the robot's ``certified`` figures, in order: ``robust_stability``, then the figures every
    registered objective writes, each once, in the registry's order.

    Returns
    -------
    tuple of str
        The keys (the built-in objectives': robust_stability, decay_rate, ultimate_bound, motor_speed_bound,
        hinf_gain).
    """
    return tuple(dict.fromkeys(("robust_stability",) + tuple(k for o in OBJECTIVES.values()
                                                             if "tracked-robot" in o.plants for k in o.figures)))


def scalar_figures() -> tuple[str, ...]:
    """The robot's certified figures that are one number each (not ``robust_stability``, a verdict, nor
    ``ultimate_bound``, a bound per error), in :func:`certified_keys`' order: what a comparison of two files'
    figures compares number against number.

    Returns
    -------
    tuple of str
        The keys (the built-in objectives': decay_rate, motor_speed_bound, hinf_gain).
    """
    return tuple(k for k in certified_keys() if k not in ("robust_stability", "ultimate_bound"))


def labelled_figures(shown: tuple[str, ...] = ROBOT_FIGURES_SHOWN) -> list[tuple[str, str]]:
    """The scalar figures a report or the console has no line of its own for: (key, label) of each registered
    objective's ``figure`` not in ``shown``.

    Parameters
    ----------
    shown : tuple of str
        The figures the caller shows its own way (default: the lines reports and the console have).

    Returns
    -------
    list of tuple
        (key, label) in the registry's order.
    """
    out: dict[str, str] = {}
    for o in OBJECTIVES.values():
        if "tracked-robot" in o.plants and o.figure not in shown:
            out.setdefault(o.figure, o.label)
    return list(out.items())


def objective(name: str) -> Objective:
    """The descriptor of an objective.

    Parameters
    ----------
    name : str
        Its name.

    Returns
    -------
    Objective
        Its descriptor.

    Raises
    ------
    KeyError
        No objective has that name (the message names the registered ones).
    """
    try:
        return OBJECTIVES[name]
    except KeyError:
        raise KeyError(f"objective {name!r} is not one of {', '.join(OBJECTIVES)}") from None
