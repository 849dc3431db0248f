"""Matplotlib figures of simulation results (imported lazily: matplotlib is slow to import)."""

from __future__ import annotations

__all__ = ["plot_result", "style_axes"]

#: Figure width [inch] of a two-column paper's full text width and line width of traces.
PAPER_WIDTH = 7.0


def style_axes(ax, *, xlabel: str | None, ylabel: str) -> None:
    """Grid, labels with units, tight x-limits: the house style of hpdob figures."""
    ax.grid(True, linewidth=0.4, alpha=0.5)
    if xlabel:
        ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.margins(x=0)


def plot_result(result, *, title: str | None = None):
    """Three stacked panels: position vs reference, disturbances, estimation error."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(PAPER_WIDTH, 6.5), sharex=True, layout="constrained")
    t = result.t
    ax = axes[0]
    ax.plot(t, result.r, "k--", linewidth=1.0, label="reference $r$")
    ax.plot(t, result.theta, linewidth=1.2, label=r"position $\theta$")
    style_axes(ax, xlabel=None, ylabel="angle [rad]")
    ax.legend(loc="best", fontsize="small")
    ax = axes[1]
    ax.plot(t, result.tau_dn, "k", linewidth=1.0, label=r"nominal disturbance $\tau_{dn}$")
    ax.plot(t, result.tau_ext, color="0.6", linewidth=0.8, label=r"external $\tau_{ext}$")
    if abs(result.tau_hat).max(initial=0.0) > 0:
        ax.plot(t, result.tau_hat, linewidth=1.0, label=r"estimate $\hat\tau_{dn}$")
    style_axes(ax, xlabel=None, ylabel="torque [N m]")
    ax.legend(loc="best", fontsize="small")
    ax = axes[2]
    ax.plot(t, result.estimation_error, linewidth=1.0)
    style_axes(ax, xlabel="time [s]", ylabel=r"$\hat\tau_{dn} - \tau_{dn}$ [N m]")
    fig.suptitle(title or result.label or "hpdob simulation")
    return fig
