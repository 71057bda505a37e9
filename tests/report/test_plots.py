"""The verification figures (report/plots.py): what their legends name is what they draw."""

from __future__ import annotations

from dataclasses import replace

import pytest

from robustsynth.artifacts.gains import load_gains
from robustsynth.config import config_with
from robustsynth.verification.checks import verify

from ..conftest import ROOT, committed_gain


@pytest.mark.parametrize("name,excludes", [("tracks-box", True), ("turns", False)])
def test_the_excluded_steps_are_named_only_where_there_are_some(name, excludes) -> None:
    """A polyline (the default path) excludes the steps after each waypoint until the robot is back in the
    set, and errors.png and lyapunov.png shade and name them; a path rounded by arcs (configs/turns.yaml)
    excludes nothing, and its figures name no excluded steps (they once had an empty legend entry)."""
    from robustsynth.report.plots import _covered, fig_errors, fig_lyapunov

    m, _, _ = committed_gain(name)
    # the figures read the Monte Carlo runs only: the adversary's searches are left out (25 s of 32 on turns)
    m = replace(m, config=config_with(m.config, {"verification.adversarial_runs": 0}))
    res = verify(m, load_gains(ROOT / "results" / "baselines" / name / "gains.json"), runs=4)
    assert bool((~_covered(res)).any()) == excludes
    for fig in (fig_errors(res, m), fig_lyapunov(res, m)):
        labels = [lab for ax in fig.axes for lab in ax.get_legend_handles_labels()[1]]
        assert any(lab.startswith("excluded") for lab in labels) == excludes, labels
        _titles_fit(fig)


def _titles_fit(fig) -> None:
    """Every axes title lies within the figure's width (lyapunov.png's second title line was cut off)."""
    renderer = fig.canvas.get_renderer()
    fig.canvas.draw()
    width = fig.bbox.width
    for ax in fig.axes:
        box = ax.title.get_window_extent(renderer)
        if ax.get_title():
            assert box.x0 >= 0 and box.x1 <= width, (ax.get_title(), box.x0, box.x1, width)


@pytest.fixture(scope="module")
def polyline():
    """tracks-box's committed gain verified on 4 runs (the adversary left out): a polyline path, whose waypoint
    corners the verdict excludes."""
    m, _, _ = committed_gain("tracks-box")
    m = replace(m, config=config_with(m.config, {"verification.adversarial_runs": 0}))
    return m, verify(m, load_gains(ROOT / "results" / "baselines" / "tracks-box" / "gains.json"), runs=4)


def _figures(res, m) -> dict:
    from robustsynth.report import plots

    return {name: getattr(plots, f"fig_{name}")(res, m) for name in plots.FIGURES}


def _shaded(ax) -> list[tuple[float, float]]:
    """The time intervals an axes shades as excluded (one path per contiguous run of excluded steps)."""
    spans = [(float(p.vertices[:, 0].min()), float(p.vertices[:, 0].max()))
             for c in ax.collections if c.get_label().startswith("excluded") for p in c.get_paths()]
    return sorted(spans)


def test_the_path_figure_shades_the_excluded_corner_steps_as_errors_does(polyline) -> None:
    """Issue 50, item 8: path.png drew e_y through the corners against the certified band, unshaded, while
    errors.png shaded the steps the verdict excludes there: path.png shades the same intervals (one source,
    plots._covered) and names them, so the excursion does not read as a violation."""
    import matplotlib.pyplot as plt

    from robustsynth.report.plots import _covered, fig_errors, fig_path

    m, res = polyline
    assert (~_covered(res)).any()  # the polyline's corners: something to shade
    fp, fe = fig_path(res, m), fig_errors(res, m)
    ey_path = fp.axes[1]
    shaded = _shaded(ey_path)
    assert shaded and shaded == _shaded(fe.axes[1]), (shaded, _shaded(fe.axes[1]))
    assert any(lab.startswith("excluded") for lab in ey_path.get_legend_handles_labels()[1])
    plt.close(fp)
    plt.close(fe)


def test_no_legend_covers_the_plotted_data_and_titles_are_one_line(polyline) -> None:
    """Issue 50, item 8: a legend covered a trace, and lyapunov.png's title took three lines.  Every legend of
    the verification figures lies off every axes' plotting area (beside the axes, or below all of them), so it
    covers no line, band or point; every title and suptitle is one line and fits the figure."""
    import matplotlib.pyplot as plt

    m, res = polyline
    for name, fig in _figures(res, m).items():
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
        assert legends, name
        for leg in legends:
            box = leg.get_window_extent(renderer)
            for ax in fig.axes:
                # the axes' box holds every plotted line, band and point: off it, the legend covers none
                assert not box.overlaps(ax.bbox), (name, [t.get_text() for t in leg.get_texts()], box, ax.bbox)
        titles = [ax.get_title() for ax in fig.axes] + [fig.get_suptitle()]
        assert all("\n" not in t for t in titles), (name, titles)
        _titles_fit(fig)
        plt.close(fig)


def test_a_sweep_figure_marks_the_points_that_failed_verification() -> None:
    """The 1-D sweep figure's title counted a certified point that failed verification, and the figure did not
    show it (review): it is marked on its certified |e_y|."""
    import matplotlib.pyplot as plt

    from robustsynth.report.plots import fig_sweep_1d
    from robustsynth.sweeps.run import SweepResult
    from robustsynth.sweeps.spec import parse_sweep

    spec = parse_sweep("axes:\n  reference.speed: [0.3, 0.5, 0.55]\n")
    rows = tuple({"index": i, "reference.speed": v, "status": "certified", "e_x_m": 0.01 * (i + 1), "e_y_m": 0.02 * (i + 1),
                  "verified": i != 2} for i, v in enumerate((0.3, 0.5, 0.55)))
    fig = fig_sweep_1d(SweepResult(spec, rows, ("reference.speed", "status", "e_x_m", "e_y_m", "verified"), {}))
    ax = fig.axes[0]
    marks = [ln for ln in ax.get_lines() if ln.get_label() == "failed verification"]
    assert len(marks) == 1 and list(marks[0].get_ydata()) == [6.0]  # the third point, 6 cm
    assert "1 failed verification" in ax.get_title()
    plt.close(fig)


def test_write_figures_renders_every_other_figure_beside_and_the_files_are_the_same(polyline, tmp_path,
                                                                                    monkeypatch) -> None:
    """write_figures renders every other figure in a forked child (robustsynth.forked.beside): every figure is
    written, in FIGURES' order, with the same bytes as when all are rendered in this process."""
    from robustsynth import forked
    from robustsynth.report.plots import FIGURES, write_figures

    if not (forked.AVAILABLE and forked.cores() > 1):
        pytest.skip("nothing is forked here")
    returned = []

    class Counted(forked.Forked):
        def result(self):
            value = super().result()  # raises where the child failed (beside then renders here)
            returned.append(sorted(value))
            return value

    monkeypatch.setattr(forked, "Forked", Counted)
    m, res = polyline
    beside = write_figures(res, m, tmp_path / "beside")
    assert returned == [sorted(list(FIGURES)[1::2])]  # the child rendered every other figure
    monkeypatch.setattr(forked, "AVAILABLE", False)
    here = write_figures(res, m, tmp_path / "here")
    assert list(beside) == list(here) == list(FIGURES)
    for name in FIGURES:
        assert beside[name].read_bytes() == here[name].read_bytes(), name
