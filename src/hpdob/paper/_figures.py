"""The paper's Figs. 2-5 drawn from canonical simulation results."""

from __future__ import annotations

from .._plotting import (
    PAPER_WIDTH,
    legends_clear_of_data,
    mark_clipped,
    style_axes,
    time_axis,
)

__all__ = ["paper_figures"]

#: Zoom window [s] of the insets: the disturbance step and the start of the sine.
ZOOM = (1.3, 3.2)
#: The disturbance step of the canonical scenario [s] and the transient after it [s] that the
#: estimation-error panels leave off scale (each observer's error is back within its
#: steady-state range 50 ms after the step, for every canonical run).
STEP_TIME, TRANSIENT = 1.5005, 0.05
COLORS = {
    "DOb-50": "tab:orange",
    "DOb-100": "tab:green",
    "DOb-200": "tab:purple",
    "HPDOb-100": "tab:blue",
    "PD": "tab:red",
    "virtual-experiment": "tab:blue",
    "virtual-experiment-position": "tab:orange",
}
#: Legend labels where the run name alone does not say what was run.
LABELS = {
    "virtual-experiment": "HPDOb-100, differenced velocity",
    "virtual-experiment-position": "position-only order 2, 150 rad/s",
}


def _position(ax, results, names, *, inset=True):
    first = results[names[0]]
    ax.plot(first.t, first.r, "k--", linewidth=1.0, label="reference")
    for name in names:
        res = results[name]
        ax.plot(res.t, res.theta, color=COLORS[name], linewidth=1.1, label=LABELS.get(name, name))
    style_axes(ax, xlabel="time [s]", ylabel=r"position $\theta$ [rad]")
    ax.legend(loc="upper left", fontsize="small", ncol=2)
    if inset:
        # Below the traces, between the step and the sine; its tick labels and title (which
        # carries the units: no room for axis labels) stay inside the panel, off the data.
        box = ax.inset_axes([0.36, 0.12, 0.38, 0.25])
        mask = (first.t >= ZOOM[0]) & (first.t <= ZOOM[1])
        box.plot(first.t[mask], first.r[mask], "k--", linewidth=0.8)
        for name in names:
            res = results[name]
            box.plot(res.t[mask], res.theta[mask], color=COLORS[name], linewidth=0.9)
        box.set_title(r"zoom: $\theta$ [rad] against time [s]", fontsize="x-small", pad=2.0)
        box.tick_params(labelsize="x-small", pad=1.5)
        box.grid(True, linewidth=0.3, alpha=0.5)


def _letter(ax, text):
    ax.set_title(text, loc="left", fontsize="medium")


def _error_panel(ax, results, names):
    """Estimation errors with the y-range of the steady state; the step's spike off scale.

    At the 1.5 s disturbance step every observer's error spikes to several times its
    steady-state error for a few samples; a y-range that includes the spike squashes the
    rest. The range is set by the error outside ``[STEP_TIME, STEP_TIME + TRANSIENT]``; the
    traces are cut at that range (so nothing runs into the legend band above it), a
    triangle marks where a spike leaves it, and the largest peak is printed above the panel.
    """
    lo, hi, series = 0.0, 0.0, []
    for name in names:
        res = results[name]
        e = res.estimation_error
        label = LABELS.get(name, name)
        (line,) = ax.plot(res.t, e, color=COLORS[name], linewidth=0.9, label=label)
        series.append((res.t, e, line, label))
        steady = (res.t < STEP_TIME) | (res.t > STEP_TIME + TRANSIENT)
        lo, hi = min(lo, float(e[steady].min())), max(hi, float(e[steady].max()))
    margin = 0.08 * (hi - lo)
    lo, hi = lo - margin, hi + margin
    ax.set_ylim(lo, hi)
    notes = mark_clipped(ax, series, lo, hi)  # every clipped series, in its colour
    if notes:
        ax.set_title("y-range clipped (triangles):\n" + "\n".join(notes), loc="right",
                     fontsize="x-small")  # fmt: skip
    style_axes(ax, xlabel="time [s]", ylabel=r"$\hat\tau_{dn} - \tau_{dn}$ [N m]")


def paper_figures(results) -> dict:
    """The paper's Figs. 2-5 drawn from the canonical runs.

    Parameters
    ----------
    results : dict
        ``{run name: SimulationResult}`` for every name of :data:`RUNS` (as
        ``{name: run(name) for name in RUNS}`` gives).

    Returns
    -------
    dict
        ``{"fig2": Figure, ..., "fig5": Figure}`` (matplotlib): Fig. 2 the PD alone, Fig. 3
        the DObs at three bandwidths, Fig. 4 DOb vs HPDOb at 100 rad/s, Fig. 5 the virtual
        experiments (simulations standing in for the paper's hardware test).

    Raises
    ------
    KeyError
        If a run is missing from ``results``.

    References
    ----------
    Figs. 2-5 of the paper (section IV).

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from hpdob import paper
    >>> results = {name: paper.run(name, duration=2.0) for name in paper.RUNS}
    >>> figures = paper.figures(results)
    >>> sorted(figures), len(figures["fig3"].axes)   # Fig. 3: panels a), b), c)
    (['fig2', 'fig3', 'fig4', 'fig5'], 3)
    >>> plt.close("all")
    """
    import matplotlib.pyplot as plt

    figures = {}
    # Fig. 2: PD only.
    fig, (a, b) = plt.subplots(2, 1, figsize=(PAPER_WIDTH, 5.5), layout="constrained")
    _position(a, results, ["PD"], inset=False)
    _letter(a, "a) Position control of the servo system (PD)")
    pd = results["PD"]
    b.plot(pd.t, pd.tau_ext, "k", linewidth=1.0, label=r"external $\tau_{ext}$")
    b.plot(
        pd.t,
        pd.tau_dn,
        color="tab:red",
        linewidth=1.0,
        label=r"nominal $\tau_{dn}$ (incl. friction, inertia error)",
    )
    style_axes(b, xlabel="time [s]", ylabel="torque [N m]")
    _letter(b, "b) Disturbances acting on the servo system")
    bands = [(b, 2)]
    fig.suptitle("Fig. 2: position control using a PD controller (simulation)")
    figures["fig2"] = fig

    # Fig. 3: conventional DObs at three bandwidths.
    dobs = ["DOb-50", "DOb-100", "DOb-200"]
    fig, (a, b, c) = plt.subplots(3, 1, figsize=(PAPER_WIDTH, 8.0), layout="constrained")
    _position(a, results, dobs)
    _letter(a, "a) Position control of the servo system")
    ref = results["DOb-100"]
    b.plot(ref.t, ref.tau_dn, "k", linewidth=1.2, label=r"$\tau_{dn}$ (DOb-100 run)")
    for name in dobs:
        res = results[name]
        b.plot(
            res.t,
            res.tau_hat,
            color=COLORS[name],
            linewidth=0.9,
            label=rf"$\hat\tau_{{dn}}$ {name}",
        )
    style_axes(b, xlabel="time [s]", ylabel="torque [N m]")
    _letter(b, "b) Disturbances acting on the servo system and their estimates")
    _error_panel(c, results, dobs)
    _letter(c, "c) Disturbance estimation error")
    bands += [(b, len(dobs) + 1), (c, len(dobs))]
    fig.suptitle("Fig. 3: PD controller and conventional DObs (simulation)")
    figures["fig3"] = fig

    # Fig. 4: DOb vs HPDOb at 100 rad/s.
    pair = ["DOb-100", "HPDOb-100"]
    fig, (a, b) = plt.subplots(2, 1, figsize=(PAPER_WIDTH, 5.5), layout="constrained")
    _position(a, results, pair)
    _letter(a, "a) Position control of the servo system")
    _error_panel(b, results, pair)
    _letter(b, "b) Disturbance estimation error")
    bands.append((b, len(pair)))
    fig.suptitle("Fig. 4: conventional DOb vs HPDOb, both at 100 rad/s (simulation)")
    figures["fig4"] = fig

    # Fig. 5: the virtual experiments (simulations standing in for the paper's hardware test):
    # the HPDOb on the encoder's differenced velocity and the position-only observer.
    runs = ["virtual-experiment", "virtual-experiment-position"]
    ve, pos = (results[name] for name in runs)
    fig, (a, b, c) = plt.subplots(3, 1, figsize=(PAPER_WIDTH, 8.0), layout="constrained")
    _position(a, results, runs, inset=False)
    _letter(a, "a) Position control of the servo system")
    # The noisy differenced-velocity estimate underneath (light), the references on top.
    b.plot(ve.t, ve.tau_hat, color=COLORS[runs[0]], linewidth=0.6, alpha=0.35, zorder=1,
           label=rf"$\hat\tau_{{dn}}$ {LABELS[runs[0]]}")  # fmt: skip
    b.plot(pos.t, pos.tau_hat, color=COLORS[runs[1]], linewidth=0.8, zorder=2,
           label=rf"$\hat\tau_{{dn}}$ {LABELS[runs[1]]}")  # fmt: skip
    b.plot(ve.t, ve.tau_ext, color="0.45", linewidth=1.3, zorder=3, label=r"external $\tau_{ext}$")
    b.plot(pos.t, pos.tau_dn, "k", linewidth=0.8, zorder=4,
           label=r"nominal $\tau_{dn}$ (position-only run)")  # fmt: skip
    style_axes(b, xlabel="time [s]", ylabel="torque [N m]")
    _letter(b, "b) Disturbances acting on the servo system and their estimates")
    _error_panel(c, results, runs)
    _letter(c, "c) Estimation error")  # short: the clipping note shares the line
    fig.suptitle(
        "Fig. 5: virtual experiments, SIMULATIONS\n(16384-count encoder, 0.444 N m torque "
        "limit, 1-sample delay)",
        fontsize="medium",
    )
    bands += [(a, 2), (b, 2), (c, len(runs))]
    figures["fig5"] = fig
    for fig in figures.values():  # every panel shows the whole run (10 s, not to 9.999 s)
        for ax in fig.axes:
            time_axis(ax, pd.t, pd.Ts)
    # The legend bands are measured when each figure has all its labels and titles (one
    # layout pass per figure for all its bands).
    legends_clear_of_data(bands)
    return figures
