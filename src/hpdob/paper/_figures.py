"""The paper's Figs. 2-5 drawn from canonical simulation results."""

from __future__ import annotations

from .._plotting import PAPER_WIDTH, style_axes

__all__ = ["paper_figures"]

#: Zoom window [s] of the insets: the disturbance step and the start of the sine.
ZOOM = (1.3, 3.2)
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
        box = ax.inset_axes([0.40, 0.08, 0.3, 0.38])
        mask = (first.t >= ZOOM[0]) & (first.t <= ZOOM[1])
        box.plot(first.t[mask], first.r[mask], "k--", linewidth=0.8)
        for name in names:
            res = results[name]
            box.plot(res.t[mask], res.theta[mask], color=COLORS[name], linewidth=0.9)
        box.set_title("zoom", fontsize="x-small")
        box.tick_params(labelsize="x-small")
        box.grid(True, linewidth=0.3, alpha=0.5)


def _letter(ax, text):
    ax.set_title(text, loc="left", fontsize="medium")


def paper_figures(results) -> dict:
    """Figures ``fig2`` ... ``fig5`` (matplotlib Figures) keyed by name.

    ``results`` maps the canonical run names to :class:`SimulationResult` objects.
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
    b.legend(loc="upper left", fontsize="small")
    _letter(b, "b) Disturbances acting on the servo system")
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
    b.legend(loc="upper left", fontsize="small", ncol=2)
    _letter(b, "b) Disturbances acting on the servo system and their estimates")
    for name in dobs:
        res = results[name]
        c.plot(res.t, res.estimation_error, color=COLORS[name], linewidth=0.9, label=name)
    style_axes(c, xlabel="time [s]", ylabel=r"$\hat\tau_{dn} - \tau_{dn}$ [N m]")
    c.legend(loc="upper left", fontsize="small", ncol=3)
    _letter(c, "c) Disturbance estimation error")
    fig.suptitle("Fig. 3: PD controller and conventional DObs (simulation)")
    figures["fig3"] = fig

    # Fig. 4: DOb vs HPDOb at 100 rad/s.
    pair = ["DOb-100", "HPDOb-100"]
    fig, (a, b) = plt.subplots(2, 1, figsize=(PAPER_WIDTH, 5.5), layout="constrained")
    _position(a, results, pair)
    _letter(a, "a) Position control of the servo system")
    for name in pair:
        res = results[name]
        b.plot(res.t, res.estimation_error, color=COLORS[name], linewidth=0.9, label=name)
    style_axes(b, xlabel="time [s]", ylabel=r"$\hat\tau_{dn} - \tau_{dn}$ [N m]")
    b.legend(loc="upper left", fontsize="small")
    _letter(b, "b) Disturbance estimation error")
    fig.suptitle("Fig. 4: conventional DOb vs HPDOb, both at 100 rad/s (simulation)")
    figures["fig4"] = fig

    # Fig. 5: the virtual experiments (simulations standing in for the paper's hardware test):
    # the HPDOb on the encoder's differenced velocity and the position-only observer.
    runs = ["virtual-experiment", "virtual-experiment-position"]
    ve, pos = (results[name] for name in runs)
    fig, (a, b, c) = plt.subplots(3, 1, figsize=(PAPER_WIDTH, 8.0), layout="constrained")
    _position(a, results, runs, inset=False)
    _letter(a, "a) Position control of the servo system")
    b.plot(ve.t, ve.tau_ext, color="0.55", linewidth=0.9, label=r"external $\tau_{ext}$")
    b.plot(ve.t, ve.tau_hat, color=COLORS[runs[0]], linewidth=0.7, alpha=0.6,
           label=rf"$\hat\tau_{{dn}}$ {LABELS[runs[0]]}")  # fmt: skip
    b.plot(pos.t, pos.tau_dn, "k", linewidth=0.6, label=r"nominal $\tau_{dn}$ (position-only run)")
    b.plot(pos.t, pos.tau_hat, color=COLORS[runs[1]], linewidth=0.8,
           label=rf"$\hat\tau_{{dn}}$ {LABELS[runs[1]]}")  # fmt: skip
    style_axes(b, xlabel="time [s]", ylabel="torque [N m]")
    b.legend(loc="upper left", fontsize="small", ncol=2)
    _letter(b, "b) Disturbances acting on the servo system and their estimates")
    for name in runs:
        res = results[name]
        c.plot(
            res.t,
            res.estimation_error,
            color=COLORS[name],
            linewidth=0.7,
            alpha=0.6 if name == "virtual-experiment" else 1.0,
            label=LABELS[name],
        )
    style_axes(c, xlabel="time [s]", ylabel=r"$\hat\tau_{dn} - \tau_{dn}$ [N m]")
    c.legend(loc="upper left", fontsize="small")
    _letter(c, "c) Disturbance estimation error")
    fig.suptitle(
        "Fig. 5: virtual experiments, SIMULATIONS (16384-count encoder, "
        "0.444 N m limit, 1-sample delay)",
        fontsize="medium",
    )
    figures["fig5"] = fig
    return figures
