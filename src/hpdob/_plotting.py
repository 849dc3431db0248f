"""Matplotlib figures of simulation results (imported lazily: matplotlib is slow to import)."""

from __future__ import annotations

import numpy as np

__all__ = [
    "Envelope",
    "envelope",
    "label_points",
    "legend_clear_of_data",
    "legends_clear_of_data",
    "mark_clipped",
    "plot_force_result",
    "plot_result",
    "style_axes",
    "time_axis",
]

#: Figure width [inch] of a two-column paper's full text width and line width of traces.
PAPER_WIDTH = 7.0


#: Traces longer than this are drawn as their envelope (:func:`envelope`): 10 000 runs, exact
#: at any width below 10 000 pixels (a figure of PAPER_WIDTH at 300 dpi is 2100 pixels wide).
ENVELOPE_SAMPLES = 20_000


def envelope(t, y, *, samples: int = ENVELOPE_SAMPLES):
    """``(t, y)`` to draw: the trace itself up to ``samples`` points, else its envelope.

    A long trace (a log of 1e7 samples) is cut into ``samples // 2`` runs of consecutive
    samples, and each run is drawn as its minimum and maximum, in the order they occur: the
    line covers exactly the pixels the full trace would at any figure width below
    ``samples / 2`` pixels, and matplotlib does not hold a copy of the whole log. Samples after
    the last full run are kept as they are.
    """
    t, y = np.asarray(t), np.asarray(y)
    if y.size <= samples:
        return t, y
    runs = samples // 2
    width = y.size // runs
    blocks = y[: runs * width].reshape(runs, width)
    first, second = np.empty(runs, dtype=np.intp), np.empty(runs, dtype=np.intp)
    step = max(1, (1 << 20) // width)  # argmin copies what it scans: 8 MB at a time
    for a in range(0, runs, step):
        first[a : a + step] = np.argmin(blocks[a : a + step], axis=1)
        second[a : a + step] = np.argmax(blocks[a : a + step], axis=1)
    lo, hi = np.minimum(first, second), np.maximum(first, second)
    index = (np.arange(runs) * width)[:, None] + np.column_stack([lo, hi])
    index = np.concatenate([index.ravel(), np.arange(runs * width, y.size)])
    return t[index], y[index]


class Envelope:
    """:func:`envelope` of a trace of ``n`` samples that arrives in blocks (a log read piece by
    piece): :meth:`add` each block in order, then :attr:`trace` is exactly what
    ``envelope(t, y, samples=samples)`` gives for the whole trace, while only the extremes of
    each run are held."""

    def __init__(self, n: int, *, samples: int = ENVELOPE_SAMPLES):
        self.n = int(n)
        self.runs = samples // 2 if self.n > samples else 0
        self.width = self.n // self.runs if self.runs else 1
        self._seen = 0
        self._tail: list = []  # (t, y) after the last full run (the whole trace if short)
        # per run: argmin and argmax (global index), their values and times
        self._index = np.zeros((2, self.runs), dtype=np.intp)
        self._value = np.zeros((2, self.runs))
        self._time = np.zeros((2, self.runs))

    def add(self, t, y) -> None:
        """The next block of samples: times ``t`` [s] and values ``y``."""
        t, y = np.asarray(t), np.asarray(y)
        start, m, w = self._seen, y.size, self.width
        self._seen += m
        inside = min(m, self.runs * w - start)  # samples of this block that fall in runs
        if inside > 0:
            head = min(inside, -start % w)  # the end of a run begun in an earlier block
            if head:
                self._part(t, y, 0, head, start)
            full = (inside - head) // w
            step = max(1, (1 << 20) // w)  # argmin copies what it scans: 8 MB at a time
            for a in range(0, full, step):
                b = min(full, a + step)
                blocks = y[head + a * w : head + b * w].reshape(b - a, w)
                runs = (start + head) // w + np.arange(a, b)
                local = head + np.arange(a, b) * w
                for row, found in enumerate((np.argmin(blocks, axis=1),
                                             np.argmax(blocks, axis=1))):  # fmt: skip
                    self._index[row, runs] = start + local + found
                    self._value[row, runs] = y[local + found]
                    self._time[row, runs] = t[local + found]
            rest = head + full * w
            if rest < inside:
                self._part(t, y, rest, inside, start)
        if m > max(inside, 0):
            keep = slice(max(inside, 0), m)
            self._tail.append((np.array(t[keep]), np.array(y[keep])))

    def _part(self, t, y, a: int, b: int, start: int) -> None:
        """Samples ``a:b`` of the block, all in one run: merged with what that run holds (the
        first extreme wins a tie, and a NaN wins, as with ``np.argmin``)."""
        run = (start + a) // self.width
        fresh = run * self.width == start + a
        for row, pick in enumerate((np.argmin, np.argmax)):
            i = a + int(pick(y[a:b]))
            held = self._value[row, run]
            v = y[i]
            better = v < held if row == 0 else v > held
            if fresh or (not np.isnan(held) and (np.isnan(v) or better)):
                self._index[row, run] = start + i
                self._value[row, run] = v
                self._time[row, run] = t[i]

    @property
    def trace(self) -> tuple:
        """``(t, y)`` to draw (see :func:`envelope`)."""
        swap = self._index[0] > self._index[1]  # each run's two extremes in time order
        order = np.where(swap, 1, 0), np.where(swap, 0, 1)
        columns = np.arange(self.runs)
        t = np.column_stack([self._time[order[0], columns], self._time[order[1], columns]])
        y = np.column_stack([self._value[order[0], columns], self._value[order[1], columns]])
        tails_t = [part[0] for part in self._tail]
        tails_y = [part[1] for part in self._tail]
        return np.concatenate([t.ravel(), *tails_t]), np.concatenate([y.ravel(), *tails_y])


def style_axes(ax, *, xlabel: str | None, ylabel: str) -> None:
    """Grid, labels with units, tight x-limits: the house style of hpdob figures."""
    ax.grid(True, linewidth=0.4, alpha=0.5)
    if xlabel:
        ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.margins(x=0)


def time_axis(ax, t, Ts: float) -> None:
    """The x-range of a run's whole duration, ``[t_0, t_0 + n Ts]`` (a 10 s run ends at 10 s,
    not at its last sample 9.999 s, so the axis shows the whole run and its last tick)."""
    ax.set_xlim(float(t[0]), float(t[0]) + len(t) * Ts)


def mark_clipped(ax, series, lo: float, hi: float) -> list[str]:
    """Cut traces at the y-range ``[lo, hi]`` and mark where each leaves it, in its colour.

    ``series`` is a sequence of ``(t, y, line, label)``: the samples, the drawn line and its
    legend label. Every series that leaves the range gets a triangle at the edge where it
    does (one per direction: ``v`` below, ``^`` above, at its extreme), in the colour of its
    line; coincident marks of several series sit side by side. Returns one note per clipped
    series, ``"<label>: <extremes> N m"`` (both directions where it leaves both ways), for a
    caption.
    """
    from matplotlib.patches import Rectangle
    from matplotlib.transforms import ScaledTranslation, blended_transform_factory

    span = blended_transform_factory(ax.transAxes, ax.transData)
    notes = []
    count = len(series)
    for i, (t, y, line, label) in enumerate(series):
        line.set_clip_path(Rectangle((0.0, lo), 1.0, hi - lo, transform=span))
        nudge = ScaledTranslation((i - (count - 1) / 2) * 6 / 72, 0.0, ax.figure.dpi_scale_trans)
        extremes = []
        for k, edge, marker in ((int(y.argmin()), lo, "v"), (int(y.argmax()), hi, "^")):
            if lo <= y[k] <= hi:
                continue
            ax.plot(t[k], edge, marker=marker, color=line.get_color(), markersize=6,
                    clip_on=False, transform=ax.transData + nudge, label="_clipped")  # fmt: skip
            extremes.append(f"{float(y[k]):+.3f}".replace("-", "\N{MINUS SIGN}"))
        if extremes:
            notes.append(f"{label}: {' / '.join(extremes)} N m")
    return notes


def legend_clear_of_data(ax, *, ncol: int, pad: float = 0.03, **kwargs):
    """Legend in one band along the top of ``ax``, the y-range raised so no data lies under it.

    The band's height is measured (a layout pass of the figure), so it holds for any font
    size and figure size; the lower y-limit is kept. Call it when the figure has all its
    labels and titles.
    """
    legend = ax.legend(loc="upper left", ncol=ncol, fontsize="small", **kwargs)
    ax.figure.draw_without_rendering()
    box = legend.get_window_extent().transformed(ax.transAxes.inverted())
    band = min(1.0 - box.y0 + pad, 0.6)  # fraction of the axes' height taken by the legend
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, lo + (hi - lo) / (1.0 - band))
    return legend


def legends_clear_of_data(bands, *, pad: float = 0.03) -> list:
    """:func:`legend_clear_of_data` for several ``(ax, ncol)`` at once: one layout pass per
    figure (not per legend) measures every band of that figure; returns the legends."""
    legends, figures = [], {}
    for ax, ncol in bands:
        legends.append(ax.legend(loc="upper left", ncol=ncol, fontsize="small"))
        figures.setdefault(id(ax.figure), ax.figure)
    for fig in figures.values():
        fig.draw_without_rendering()
    spans = []
    for (ax, _), legend in zip(bands, legends, strict=True):  # measured before any is moved
        box = legend.get_window_extent().transformed(ax.transAxes.inverted())
        spans.append(min(1.0 - box.y0 + pad, 0.6))
    for (ax, _), band in zip(bands, spans, strict=True):
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, lo + (hi - lo) / (1.0 - band))
    return legends


#: Where a point's label may go, tried in this order: offset [points] and alignment.
_LABEL_OFFSETS = (
    ((3, 3), "left", "bottom"),
    ((-3, -3), "right", "top"),
    ((3, -3), "left", "top"),
    ((-3, 3), "right", "bottom"),
)


def label_points(ax, points, *, fontsize="x-small") -> list:
    """Label points without overlaps: each label takes the first free place around its point.

    ``points`` is a sequence of ``(x, y, text, color)`` in data coordinates, in order of
    priority. A label may not overlap an earlier label, a labelled point's marker, or leave
    the axes; a label that fits nowhere is left out (its point stays marked). Positions are
    measured after a layout pass of the figure. Returns the labels drawn.
    """
    fig = ax.figure
    fig.draw_without_rendering()
    frame = ax.get_window_extent()
    radius = 2.0 * fig.dpi / 72.0  # half the size of a marker [pixels]
    taken = []
    for x, y in ((p[0], p[1]) for p in points):
        px, py = ax.transData.transform((x, y))
        taken.append((px - radius, py - radius, px + radius, py + radius))
    drawn = []
    for x, y, text, color in points:
        for offset, ha, va in _LABEL_OFFSETS:
            label = ax.annotate(
                text,
                (x, y),
                xytext=offset,
                textcoords="offset points",
                ha=ha,
                va=va,
                fontsize=fontsize,
                color=color,
            )
            box = label.get_window_extent()
            inside = frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0
            inside = inside and box.y1 <= frame.y1
            free = all(
                box.x1 <= a or b <= box.x0 or box.y1 <= c or d <= box.y0 for a, c, b, d in taken
            )
            if inside and free:
                taken.append((box.x0, box.y0, box.x1, box.y1))
                drawn.append(label)
                break
            label.remove()
    return drawn


def plot_result(result, *, title: str | None = None):
    """Three stacked panels: position vs reference, disturbances, estimation error."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(PAPER_WIDTH, 6.5), sharex=True, layout="constrained")
    t = result.t
    ax = axes[0]
    ax.plot(t, result.r, "k--", linewidth=1.0, label="reference $r$")
    ax.plot(t, result.theta, linewidth=1.2, label=r"position $\theta$")
    style_axes(ax, xlabel=None, ylabel="angle [rad]")
    ax = axes[1]
    ax.plot(t, result.tau_dn, "k", linewidth=1.0, label=r"nominal disturbance $\tau_{dn}$")
    ax.plot(t, result.tau_ext, color="0.6", linewidth=0.8, label=r"external $\tau_{ext}$")
    if abs(result.tau_hat).max(initial=0.0) > 0:
        ax.plot(t, result.tau_hat, linewidth=1.0, label=r"estimate $\hat\tau_{dn}$")
    style_axes(ax, xlabel=None, ylabel="torque [N m]")
    ax = axes[2]
    ax.plot(t, result.estimation_error, linewidth=1.0)
    style_axes(ax, xlabel="time [s]", ylabel=r"$\hat\tau_{dn} - \tau_{dn}$ [N m]")
    time_axis(axes[-1], t, result.Ts)  # shared x: every panel
    fig.suptitle(title or result.label or "hpdob simulation")
    for ax in axes[:2]:  # legends in a band above the data
        legend_clear_of_data(ax, ncol=len(ax.get_legend_handles_labels()[1]))
    return fig


def plot_force_result(result, *, tau_ref=None, title: str | None = None):
    """Two stacked panels of a force run: torques (contact, estimate, reference), estimate
    error (``docs/force-control.md``)."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(PAPER_WIDTH, 5.0), sharex=True, layout="constrained")
    t = result.t
    ax = axes[0]
    if tau_ref is not None:
        ref = np.broadcast_to(np.asarray(tau_ref, dtype=float), np.shape(t))
        ax.plot(t, ref, "k--", linewidth=1.0, label=r"reference $\tau_{ref}$")
    ax.plot(t, result.tau_contact, linewidth=1.2, label=r"contact $\tau_{contact}$")
    ax.plot(t, result.tau_reac, linewidth=1.0, label=r"estimate $\hat\tau_{reac}$")
    style_axes(ax, xlabel=None, ylabel="torque [N m]")
    ax = axes[1]
    ax.plot(t, result.tau_reac - result.tau_contact, linewidth=1.0)
    style_axes(ax, xlabel="time [s]", ylabel=r"$\hat\tau_{reac} - \tau_{contact}$ [N m]")
    time_axis(axes[-1], t, result.Ts)
    fig.suptitle(title or result.label or "hpdob force run")
    legend_clear_of_data(axes[0], ncol=len(axes[0].get_legend_handles_labels()[1]))
    return fig
