"""Every figure ``hpdob`` writes, rendered by its command and checked for what a script can see.

Each command runs once (small settings); every figure it saves is caught at ``savefig`` and
measured after matplotlib's layout pass: axis labels carry units, no text lies outside the
canvas, a legend covers at most a small share of the plotted samples, and wherever a trace
leaves the drawn y-range a clipping mark of its colour says so (``v`` below, ``^`` above).
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure

from hpdob import paper
from hpdob._files import TEMPORARY_PREFIX
from hpdob.cli import main

ROOT = Path(__file__).resolve().parents[1]
UNITS = re.compile(r"\[[^\]]+\]")
#: The largest share of a panel's plotted samples a legend may cover.
LEGEND_SHARE = 0.02


def _log(tmp_path) -> Path:
    result = paper.run("virtual-experiment", duration=1.0)
    columns = (result.t.tolist(), result.theta_measured.tolist(), result.u.tolist())
    rows = ["t,q,u"] + [f"{t!r},{q!r},{u!r}" for t, q, u in zip(*columns, strict=True)]
    path = tmp_path / "log.csv"
    path.write_text("\n".join(rows) + "\n")
    return path


def _commands(tmp_path):
    log = _log(tmp_path)
    out = lambda name: ["--out", str(tmp_path / name)]  # noqa: E731
    return {
        "reproduce": ["reproduce", *out("reproduce")],
        "simulate": ["simulate", str(ROOT / "examples" / "canonical_hpdob.toml"), *out("sim")],
        "simulate arm": ["simulate", str(ROOT / "examples" / "two_link_observers.toml"),
                         *out("arm")],
        "simulate panda": ["simulate", str(ROOT / "examples" / "panda_joint_observers.toml"),
                           *out("panda")],
        "tune": ["tune", "--J-range", "0.9,1.1", "--families", "position", "--frequency", "2",
                 "--counts-per-rev", "16384", *out("tune")],
        "estimate": ["estimate", str(log), "--time", "t", "--position", "q", "--input", "u",
                     "--axis", "rotary", "--J-n", "2.8e-4", "--order", "1", "--bandwidth", "100",
                     *out("est")],
        "identify": ["identify", "--emps", *out("ident")],
        "analyze bode": ["analyze", "bode", "--orders", "0,1", *out("bode")],
        "analyze noise": ["analyze", "noise", "--orders", "1", "--bandwidths", "50,200",
                          *out("noise")],
        "analyze tradeoff": ["analyze", "tradeoff", "--orders", "0,1", "--bandwidths",
                             "20:800:5", "--frequency", "2", *out("tradeoff")],
        "analyze stability": ["analyze", "stability", "--orders", "1", "--values", "0.05:2:7",
                              "--bandwidths", "100,400", *out("stability")],
        "compare": ["compare", "--sensor", "ideal", "--noise-gain", "20", *out("compare")],
    }  # fmt: skip


@pytest.fixture(scope="module")
def figures(tmp_path_factory):
    """``{(command, file name): Figure}`` of every figure the commands save."""
    tmp = tmp_path_factory.mktemp("figures")
    caught = {}
    original = Figure.savefig

    def catch(self, fname, *args, **kwargs):
        # written atomically: "<prefix><name>.png.<random>.png" beside the target
        name = Path(str(fname)).name.removeprefix(TEMPORARY_PREFIX).split(".")[0]
        caught.setdefault((command, name), self)
        return original(self, fname, *args, **kwargs)

    mp = pytest.MonkeyPatch()
    mp.setattr(Figure, "savefig", catch)
    try:
        for command, argv in _commands(tmp).items():
            assert main(argv) == 0, command
    finally:
        mp.undo()
    yield caught
    plt.close("all")


def test_every_command_that_draws_was_caught(figures):
    commands = {command for command, _ in figures}
    assert commands == {"reproduce", "simulate", "tune", "estimate", "identify", "analyze bode",
                        "analyze noise", "analyze tradeoff", "analyze stability",
                        "compare", "simulate arm", "simulate panda"}  # fmt: skip
    assert {name for command, name in figures if command == "reproduce"} >= {
        "fig2", "fig3", "fig4", "fig5"}  # fmt: skip


def _data_axes(fig):
    return [ax for ax in fig.axes if ax.get_label() != "<colorbar>" and
            (ax.get_lines() or ax.collections or ax.images)]  # fmt: skip


def _has_xlabel(ax, fig) -> bool:
    siblings = ax.get_shared_x_axes().get_siblings(ax)
    return any(UNITS.search(a.get_xlabel()) for a in siblings if a in fig.axes)


def test_axis_labels_carry_units(figures):
    for key, fig in figures.items():
        for ax in _data_axes(fig):
            assert UNITS.search(ax.get_ylabel()), f"{key}: y label {ax.get_ylabel()!r}"
            assert _has_xlabel(ax, fig), f"{key}: x label {ax.get_xlabel()!r}"


def _inside(box, frame) -> bool:
    return (frame.x0 - 1 <= box.x0 and box.x1 <= frame.x1 + 1 and frame.y0 - 1 <= box.y0
            and box.y1 <= frame.y1 + 1)  # fmt: skip


def test_no_text_outside_the_canvas(figures):
    for key, fig in figures.items():
        fig.draw_without_rendering()
        renderer = fig._get_renderer()
        frame = fig.bbox
        # Each panel with everything it draws (tick labels in view, labels, titles, legend,
        # annotations, insets), and the figure's own texts and legends.
        for ax in fig.axes:
            box = ax.get_tightbbox(renderer)
            assert _inside(box, frame), f"{key}: a panel's text leaves the figure ({box})"
            for text in ax.texts:
                assert _inside(text.get_window_extent(renderer), frame), f"{key}: {text}"
        for artist in [*fig.texts, *fig.legends, fig._suptitle]:
            if artist is None or not artist.get_visible():
                continue
            box = artist.get_window_extent(renderer)
            assert _inside(box, frame), f"{key}: {getattr(artist, 'get_text', str)()!r} leaves it"


def _drawn_range(ax, line):
    """Display y-range a line is drawn in: the axes, cut by its own clip path if it has one."""
    box = ax.get_window_extent()
    lo, hi = box.y0, box.y1
    path = line.get_clip_path()
    if path is not None:
        extents = path.get_fully_transformed_path().get_extents()
        lo, hi = max(lo, extents.y0), min(hi, extents.y1)
    return box, lo, hi


def _traces(ax):
    drawn = [line for line in ax.get_lines() if len(line.get_xdata()) > 1]
    return [line for line in drawn if line.get_linestyle() not in ("None", "none", "")]


def test_legends_cover_at_most_a_small_share_of_the_data(figures):
    for key, fig in figures.items():
        fig.draw_without_rendering()
        for ax in fig.axes:
            legend = ax.get_legend()
            if legend is None:
                continue
            frame = legend.get_window_extent()
            covered = total = 0
            for line in _traces(ax):
                xy = line.get_transform().transform(line.get_xydata())
                box, lo, hi = _drawn_range(ax, line)
                keep = (xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1) & (xy[:, 1] >= lo)
                keep &= xy[:, 1] <= hi
                xy = xy[keep]
                total += len(xy)
                covered += int(np.sum((xy[:, 0] > frame.x0) & (xy[:, 0] < frame.x1)
                                      & (xy[:, 1] > frame.y0) & (xy[:, 1] < frame.y1)))  # fmt: skip
            assert covered <= LEGEND_SHARE * max(total, 1), (
                f"{key}: the legend covers {covered} of {total} samples"
            )


def test_clipping_marks_where_data_leave_the_range(figures):
    for key, fig in figures.items():
        fig.draw_without_rendering()
        for ax in fig.axes:
            marks = [line for line in ax.get_lines() if line.get_marker() in ("v", "^")
                     and not line.get_clip_on()]  # fmt: skip
            # a mark hidden under another series' mark marks nothing (Fig. 4b's DOb-100 was)
            where = [m.get_transform().transform(m.get_xydata())[0] for m in marks]
            size = 6 * fig.dpi / 72  # the marks' size [pixels]
            for (i, a), (j, b) in itertools.combinations(enumerate(where), 2):
                if to_rgba(marks[i].get_color()) != to_rgba(marks[j].get_color()):
                    assert np.hypot(*(a - b)) >= 0.6 * size, f"{key}: two marks overlap"
            for line in _traces(ax):
                xy = line.get_transform().transform(line.get_xydata())
                box, lo, hi = _drawn_range(ax, line)
                xy = xy[np.isfinite(xy).all(axis=1)]
                xy = xy[(xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1)]
                colour = to_rgba(line.get_color())
                for leaves, marker in ((xy[:, 1] < lo - 1, "v"), (xy[:, 1] > hi + 1, "^")):
                    if not leaves.any():
                        continue
                    assert any(m.get_marker() == marker and to_rgba(m.get_color()) == colour
                               for m in marks), (
                        f"{key}: {line.get_label()!r} leaves the range "
                        f"{'below' if marker == 'v' else 'above'} without a mark of its colour"
                    )  # fmt: skip


def test_paper_figures_show_the_whole_run_and_name_legend_labels(figures):
    for name in ("fig2", "fig3", "fig4", "fig5"):
        fig = figures[("reproduce", name)]
        for ax in fig.axes:
            assert ax.get_xlim() == pytest.approx((0.0, paper.DURATION)), name
        for ax in fig.axes:
            note = ax.get_title(loc="right")
            assert "virtual-experiment" not in note, f"{name}: a run id in {note!r}"
    # Fig. 5b: the references drawn over the noisy differenced-velocity estimate.
    b = figures[("reproduce", "fig5")].axes[1]
    order = {line.get_label(): line.get_zorder() for line in b.get_lines()}
    noisy = next(z for label, z in order.items() if "differenced" in label)
    assert all(order[label] > noisy for label in order if "tau_{ext}" in label
               or "nominal" in label)  # fmt: skip


def test_estimate_rotary_axis_labels_name_one_unit(figures):
    fig = figures[("estimate", "estimate")]
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["position [rad]", "disturbance [N m]"]


def test_mark_clipped_marks_every_series_in_its_colour_both_ways():
    from hpdob._plotting import mark_clipped

    fig, ax = plt.subplots()
    t = np.linspace(0.0, 1.0, 101)
    up_down = np.where(t == 0.5, 5.0, 0.0) - np.where(t == 0.6, 4.0, 0.0)  # leaves both ways
    down = -np.where(t == 0.5, 3.0, 0.0)  # at the same instant as the first's spike
    series = []
    for y, label, colour in ((up_down, "first", "tab:green"), (down, "second", "tab:blue")):
        (line,) = ax.plot(t, y, color=colour, label=label)
        series.append((t, y, line, label))
    ax.set_ylim(-1.0, 1.0)
    notes = mark_clipped(ax, series, -1.0, 1.0)
    assert notes == ["first: \N{MINUS SIGN}4.000 / +5.000 N m", "second: \N{MINUS SIGN}3.000 N m"]
    marks = {(m.get_marker(), m.get_color()) for m in ax.get_lines() if not m.get_clip_on()}
    assert marks == {("v", "tab:green"), ("^", "tab:green"), ("v", "tab:blue")}
    fig.draw_without_rendering()
    at_half = [m.get_transform().transform(m.get_xydata())[0][0] for m in ax.get_lines()
               if not m.get_clip_on() and m.get_xdata()[0] == 0.5]  # fmt: skip
    assert len(at_half) == 2 and abs(at_half[0] - at_half[1]) >= 6 * fig.dpi / 72 - 1e-9
    plt.close(fig)
