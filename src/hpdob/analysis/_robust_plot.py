"""Heat-maps of spectral-radius grids: :class:`hpdob.StabilityMap` and the contact map
(matplotlib is imported when one is drawn)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_radius_map", "plot_stability_map"]

_UNITS = {"J_ratio": "true/nominal inertia J/J_n [-]", "b": "true viscous friction b [N m s/rad]"}


def plot_stability_map(smap, ax=None, *, mark=None, mark_label=None):
    """Draw ``smap`` (see :meth:`hpdob.StabilityMap.plot`); return the figure."""
    if smap.parameter == "J_ratio":
        fixed = f"b = {smap.b:.3g} N m s/rad"
    else:
        fixed = f"J/J_n = {smap.J_ratio:.3g}"
    delay = f"\n{smap.delay_samples}-sample actuator delay" if smap.delay_samples else ""
    return plot_radius_map(
        bandwidths=smap.bandwidths,
        values=smap.values,
        radius=smap.spectral_radius,
        Ts=smap._setting.Ts,
        ylabel=_UNITS[smap.parameter],
        title=f"{smap._setting.name}\n{fixed}{delay}",
        log_values=smap.parameter == "J_ratio" or bool(np.all(smap.values > 0)),
        what="J/J_n" if smap.parameter == "J_ratio" else "b",  # the axis label has its unit
        ax=ax,
        mark=mark,
        mark_label=mark_label,
    )


def plot_radius_map(*, bandwidths, values, radius, Ts, ylabel, title, log_values, what, ax=None,
                    mark=None, mark_label=None,
                    xlabel="observer bandwidth g [rad/s]"):  # fmt: skip
    """Heat-map of a spectral-radius grid ``radius[i, j]`` (``values[i]``, ``bandwidths[j]``)
    with the boundary ``radius = 1``, the legend above the map; return the figure. ``what``
    names the vertical quantity in the mark's legend entry."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import SymLogNorm
    from matplotlib.lines import Line2D

    from .._plotting import PAPER_WIDTH, style_axes

    if ax is None:
        fig, ax = plt.subplots(figsize=(PAPER_WIDTH * 0.62, 3.9), layout="constrained")
    else:
        fig = ax.figure
    rho = radius
    # Slowest decay rate [1/s]: positive stable, negative growing; symmetric log colours.
    rate = -np.log(rho) / Ts
    top = max(float(np.abs(rate).max()), 1.0)
    mesh = ax.pcolormesh(
        bandwidths,
        values,
        rate,
        shading="nearest",
        cmap="RdBu",
        norm=SymLogNorm(linthresh=1.0, vmin=-top, vmax=top),
    )
    handles = []
    if rho.shape[0] > 1 and rho.shape[1] > 1 and rho.min() < 1.0 < rho.max():
        ax.contour(bandwidths, values, rho, levels=[1.0], colors="k", linewidths=1.4)
        handles.append(
            Line2D([], [], color="k", linewidth=1.4, label="stability boundary (radius = 1)")
        )
    ax.set_xscale("log")
    _log_ticks(ax.xaxis, bandwidths)
    if log_values:
        ax.set_yscale("log")
        _log_ticks(ax.yaxis, values)
    if mark is not None:
        g, value = (float(v) for v in mark)
        style = {"marker": "*", "color": "gold", "markeredgecolor": "k", "markersize": 11}
        ax.plot(g, value, linestyle="none", **style)
        label = mark_label or f"design: g = {g:g} rad/s, {what} = {value:.3g}"
        handles.append(Line2D([], [], linestyle="none", label=label, **style))
    cbar = fig.colorbar(mesh, ax=ax)
    cbar.set_label("slowest decay rate -ln(radius)/Ts [1/s]\n(< 0: unstable)")
    style_axes(ax, xlabel=xlabel, ylabel=ylabel)
    pad = 6.0  # [points] matplotlib's default title pad
    if handles:  # above the map (it has no free space), between the map and its title
        legend = ax.legend(
            handles=handles,
            loc="lower left",
            bbox_to_anchor=(0.0, 1.0),
            fontsize="small",
            frameon=False,
            borderaxespad=0.2,
            handlelength=1.6,
        )
        # Its height is reserved by the title's pad; left in the layout, a legend wider than
        # a narrow map (side-by-side panels) would collapse constrained layout.
        legend.set_in_layout(False)
        _fit(legend, legend.get_texts(), ax, cbar)
        pad += legend.get_window_extent().height * 72.0 / fig.dpi
    # The observer, the plant and the delay on lines of their own: short lines that fit the
    # map's width; a narrow map (subplots) gets a smaller font rather than a clipped one.
    title = ax.set_title(title, fontsize="medium", pad=pad)
    _fit(title, [title], ax, cbar)
    return fig


def _fit(artist, texts, ax, cbar) -> None:
    """Smaller fonts for ``texts`` until ``artist`` fits the width of the map's panel (the map
    with its axis labels and colour bar, within the figure): never clipped, never over a
    neighbouring panel of a figure with several maps."""
    from matplotlib.transforms import Bbox

    for size in ("small", "x-small", None):
        ax.figure.draw_without_rendering()
        parts = [ax.get_window_extent(), ax.yaxis.get_tightbbox(), cbar.ax.get_tightbbox()]
        panel = Bbox.union([p for p in parts if p is not None])
        frame = Bbox.intersection(panel, ax.figure.bbox) or ax.figure.bbox
        box = artist.get_window_extent()
        if size is None or (frame.x0 - 0.5 <= box.x0 and box.x1 <= frame.x1 + 0.5):
            return
        for text in texts:
            text.set_fontsize(size)


def _log_ticks(axis, values) -> None:
    """Labelled ticks on a log axis of any span: plain numbers, several per decade if needed.

    Less than a decade (where matplotlib's log ticks leave the axis unlabelled or nearly so):
    evenly spaced ticks; up to 1.5 decades: 1, 2, 5 per decade; up to three: 1, 3 per decade;
    more: one per decade.
    """
    from matplotlib import ticker

    lo, hi = float(np.min(values)), float(np.max(values))
    decades = np.log10(hi / lo) if lo > 0 and hi > lo else 0.0
    if decades < 1.0:
        axis.set_major_locator(ticker.MaxNLocator(nbins=8, steps=[1, 2, 2.5, 5, 10]))
        axis.set_minor_locator(ticker.NullLocator())
    elif decades <= 1.5:
        axis.set_major_locator(ticker.LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
    elif decades <= 3.0:
        axis.set_major_locator(ticker.LogLocator(base=10.0, subs=(1.0, 3.0)))
    else:
        axis.set_major_locator(ticker.LogLocator(base=10.0))
    axis.set_major_formatter(ticker.StrMethodFormatter("{x:g}"))
    axis.set_minor_formatter(ticker.NullFormatter())
