"""What a reader sees in the figures: legends off the data, readable ranges, ticks and titles.

Each test measures the drawn figure (after matplotlib's layout pass) rather than the code
that draws it: a legend must not cover a plotted sample, a title must lie inside its figure,
labels must not overlap, an off-scale spike must be marked and named.
"""

from __future__ import annotations

import itertools

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest

from hpdob import (
    PD,
    ServoModel,
    StabilityMap,
    design_observer,
    noise_tradeoff,
    paper,
    robust_stability_map,
)
from hpdob.cli import main

TS = 1e-3
NOMINAL = ServoModel(2.8e-4)


def visible_points(ax, line) -> np.ndarray:
    """Display coordinates of the samples of ``line`` that are drawn inside ``ax``."""
    xy = line.get_transform().transform(line.get_xydata())
    box = ax.get_window_extent()
    keep = (xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1) & (xy[:, 1] >= box.y0)
    keep &= xy[:, 1] <= box.y1
    clip = line.get_clip_box()  # a trace cut at a range of its own (the clipped error panels)
    if clip is not None:
        keep &= (xy[:, 1] >= clip.y0 - 1e-6) & (xy[:, 1] <= clip.y1 + 1e-6)
    return xy[keep]


def assert_legends_off_the_data(fig, name):
    fig.draw_without_rendering()
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is None:
            continue
        box = legend.get_window_extent()
        for line in ax.get_lines():
            xy = visible_points(ax, line)
            inside = (xy[:, 0] > box.x0) & (xy[:, 0] < box.x1)
            inside &= (xy[:, 1] > box.y0) & (xy[:, 1] < box.y1)
            assert not inside.any(), f"{name}: the legend covers {line.get_label()!r}"


def assert_inside_figure(fig, text):
    fig.draw_without_rendering()
    box, frame = text.get_window_extent(), fig.bbox
    assert frame.x0 - 0.5 <= box.x0 and box.x1 <= frame.x1 + 0.5, text.get_text()
    assert frame.y0 - 0.5 <= box.y0 and box.y1 <= frame.y1 + 0.5, text.get_text()


@pytest.fixture(scope="module")
def results():
    return {name: paper.run(name) for name in paper.RUNS}


@pytest.fixture(scope="module")
def figures(results):
    figs = paper.figures(results)
    yield figs
    for fig in figs.values():
        plt.close(fig)


def test_paper_figures_keep_their_legends_off_the_data(figures):
    assert set(figures) == {"fig2", "fig3", "fig4", "fig5"}
    for name, fig in figures.items():
        assert_legends_off_the_data(fig, name)


@pytest.mark.parametrize(("name", "panel"), [("fig3", 2), ("fig4", 1)])
def test_error_panels_show_the_steady_state_and_name_the_spike(figures, results, name, panel):
    ax = figures[name].axes[panel]
    lo, hi = ax.get_ylim()
    runs = [results[line.get_label()] for line in ax.get_lines() if line.get_label() in results]
    assert runs
    # The disturbance step: the one jump of the external torque (0.05 N m, at 1.5005 s).
    t = runs[0].t
    k = int(np.argmax(np.abs(np.diff(runs[0].tau_ext)))) + 1
    step = t[k]
    assert abs(step - 1.5005) < TS
    spike = min(float(r.estimation_error.min()) for r in runs)
    assert spike < lo, "the spike at the step is off scale"
    for r in runs:
        steady = (r.t < step - TS) | (r.t > step + 0.05)
        e = r.estimation_error[steady]
        assert lo <= e.min() and e.max() <= hi, "the steady-state error sets the range"
    # ... and the range is no wider than the steady state needs (the spike would be 6x).
    largest = max(float(np.abs(r.estimation_error[(r.t > step + 0.05)]).max()) for r in runs)
    assert hi - lo < 4 * largest
    note = ax.get_title(loc="right")
    assert "clipped" in note and f"{spike:.3f}".replace("-", "\N{MINUS SIGN}") in note
    markers = [line for line in ax.get_lines() if line.get_marker() == "v"]
    assert markers and all(abs(m.get_xdata()[0] - step) < 0.01 for m in markers)


@pytest.mark.parametrize("name", ["fig3", "fig4"])
def test_zoom_insets_name_their_units_and_cover_no_data(figures, name):
    ax = figures[name].axes[0]
    (inset,) = ax.child_axes
    figures[name].draw_without_rendering()
    title = inset.get_title()
    assert "[rad]" in title and "[s]" in title, "the zoom has no axis labels: its title says"
    # The inset with its tick labels and title: inside the panel, over none of its traces.
    box, frame = inset.get_tightbbox(), ax.get_window_extent()
    assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 <= box.y1 <= frame.y1
    for line in ax.get_lines():
        xy = visible_points(ax, line)
        inside = (xy[:, 0] > box.x0) & (xy[:, 0] < box.x1)
        inside &= (xy[:, 1] > box.y0) & (xy[:, 1] < box.y1)
        assert not inside.any(), f"{name}: the zoom covers {line.get_label()!r}"


@pytest.mark.parametrize(("name", "panel"), [("fig3", 2), ("fig4", 1), ("fig5", 2)])
def test_panel_letter_and_clipping_note_do_not_overlap(figures, name, panel):
    ax = figures[name].axes[panel]
    figures[name].draw_without_rendering()
    left, right = ax._left_title.get_window_extent(), ax._right_title.get_window_extent()
    gap = 0.05 * ax.get_window_extent().width  # clear at any dpi (text and axes scale alike)
    assert ax.get_title(loc="right") and left.x1 + gap < right.x0, name
    assert_inside_figure(figures[name], ax._right_title)


def test_simulation_result_plot_keeps_its_legends_off_the_data(results):
    fig = results["virtual-experiment"].plot()
    assert_legends_off_the_data(fig, "SimulationResult.plot")
    plt.close(fig)


def test_bode_title_fits_the_figure():
    from hpdob.analysis import bode_figure

    designs = [design_observer(NOMINAL.discretize(TS), order=m, bandwidth=100.0) for m in (0, 1)]
    f = np.geomspace(0.1, 500.0, 50)
    fig = bode_figure(designs, f, sensitivities=[np.ones(f.size)] * 2)
    title = next(t for t in fig.texts if "Disturbance-estimation response" in t.get_text())
    assert_inside_figure(fig, title)
    plt.close(fig)


def test_tradeoff_labels_do_not_overlap():
    table = noise_tradeoff(
        nominal=NOMINAL, Ts=TS, frequency=2.0, bandwidths=np.geomspace(10.0, 3000.0, 61)
    )
    fig = table.plot()
    ax = fig.axes[0]
    fig.draw_without_rendering()
    labels = [t for t in ax.texts if t.get_text() in {"25", "50", "100", "200", "400", "800"}]
    assert len(labels) >= 20, "most of the 24 bandwidth labels are drawn"
    boxes = [t.get_window_extent() for t in labels]
    frame = ax.get_window_extent()
    for i, a in enumerate(boxes):
        assert frame.x0 <= a.x0 and a.x1 <= frame.x1 and frame.y0 <= a.y0 and a.y1 <= frame.y1
        for b in boxes[i + 1 :]:
            assert a.x1 <= b.x0 or b.x1 <= a.x0 or a.y1 <= b.y0 or b.y1 <= a.y0, (
                f"labels {labels[i].get_text()!r} and another overlap"
            )
    plt.close(fig)


def stability_map(values, *, delay=0):
    return robust_stability_map(
        J_ratio=values,
        bandwidth=np.geomspace(50.0, 1000.0, 9),
        order=1,
        nominal=NOMINAL,
        Ts=TS,
        controller=PD(50.0, 5.0),
        delay_samples=delay,
    )


def test_stability_map_legend_names_the_boundary_and_the_marked_design():
    smap = stability_map(np.geomspace(0.1, 10.0, 9))
    assert smap.stable.any() and not smap.stable.all()
    fig = smap.plot(mark=(150.0, 1.2))
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("boundary" in t for t in texts)
    assert any("150 rad/s" in t and "1.2" in t for t in texts)
    assert_legends_off_the_data(fig, "stability map")
    stars = [line for line in ax.get_lines() if line.get_marker() == "*"]
    assert len(stars) == 1 and stars[0].get_xdata()[0] == 150.0
    plt.close(fig)
    fig = smap.plot()  # nothing is marked unless a design is passed
    assert not [line for line in fig.axes[0].get_lines() if line.get_marker() == "*"]
    plt.close(fig)


def test_narrow_log_axis_has_tick_labels():
    smap = stability_map(np.geomspace(0.7, 1.3, 7), delay=1)  # J/J_n within +-30 %
    fig = smap.plot()
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    fig.draw_without_rendering()
    lo, hi = ax.get_ylim()
    shown = [
        float(t.get_text())
        for t, v in zip(ax.get_yticklabels(), ax.get_yticks(), strict=True)
        if t.get_text() and lo <= v <= hi
    ]
    assert len(shown) >= 4 and min(shown) <= 0.8 and max(shown) >= 1.2, shown
    title = ax.title
    assert "delay" in title.get_text()
    assert_inside_figure(fig, title)
    plt.close(fig)


@pytest.mark.parametrize("measurement", ["state", "position"])
def test_stability_map_titles_are_short_and_fit_their_panels(measurement):
    """One map alone and three side by side: each title says "position-only" at most once,
    lies inside the figure and keeps off its neighbours; constrained layout holds (a
    collapsed layout would warn, an error here)."""
    common = {"nominal": NOMINAL, "Ts": TS, "controller": PD(50.0, 5.0), "delay_samples": 1}
    common |= {"bandwidth": [50.0, 100.0, 200.0], "measurement": measurement}
    maps = [
        robust_stability_map(order=1, J_ratio=np.geomspace(0.5, 2.0, 5), **common),
        robust_stability_map(order=2, J_ratio=1.2, b=np.geomspace(1e-4, 1.0, 5), **common),
        robust_stability_map(order=3, J_ratio=np.geomspace(0.5, 2.0, 5), **common),
    ]
    single = maps[0].plot(mark=(100.0, 1.2))
    assert_inside_figure(single, single.axes[0].title)
    fig, axes = plt.subplots(1, 3, figsize=(9.0, 3.6), layout="constrained")
    for ax, smap in zip(axes, maps, strict=True):
        smap.plot(ax=ax, mark=(100.0, 1.2 if smap.parameter == "J_ratio" else 1e-3))
    fig.draw_without_rendering()
    boxes = []
    for ax in axes:
        text = ax.title.get_text()
        assert text.count("position-only") == (measurement == "position"), text
        assert "1-sample actuator delay" in text
        assert_inside_figure(fig, ax.title)
        boxes.append(ax.title.get_window_extent())
    assert all(a.x1 <= b.x0 for a, b in itertools.pairwise(boxes))
    plt.close(single)
    plt.close(fig)


@pytest.mark.parametrize(
    ("extra", "expected"), [([], None), (["--bandwidth", "150"], (150.0, 3.0e-4 / 2.8e-4))]
)
def test_cli_stability_marks_only_a_design_the_user_passes(
    monkeypatch, capsys, tmp_path, extra, expected
):
    marks = []
    original = StabilityMap.plot

    def plot(self, ax=None, *, mark=None, mark_label=None):
        marks.append(mark)
        return original(self, ax, mark=mark, mark_label=mark_label)

    monkeypatch.setattr(StabilityMap, "plot", plot)
    argv = ["analyze", "stability", "--J", "3.0e-4", "--values", "0.5,1,2"]
    argv += ["--bandwidths", "50,100,200", "--orders", "1", "--out", str(tmp_path), *extra]
    assert main(argv) == 0
    capsys.readouterr()
    assert len(marks) == 1
    if expected is None:
        assert marks[0] is None
    else:
        assert marks[0] == pytest.approx(expected)
