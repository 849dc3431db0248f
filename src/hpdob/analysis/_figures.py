"""Figures of the frequency-domain analyses (matplotlib, imported lazily)."""

from __future__ import annotations

import numpy as np

from .._plotting import PAPER_WIDTH, style_axes
from ._estimation import estimation_response

__all__ = ["bode_figure", "noise_figure", "order_name"]


def order_name(order: int) -> str:
    """``"DOb (m=0)"``, ``"HPDOb (m=1)"``, ``"order m=2"``, ..."""
    return {0: "DOb (m=0)", 1: "HPDOb (m=1)"}.get(order, f"order m={order}")


def bode_figure(designs, frequency, *, sensitivities=None, mark_frequency=None, labels=None):
    """Magnitude of ``Q`` and ``1 - Q``, phase of ``Q``, optionally ``|S|`` of the loop.

    Parameters
    ----------
    designs : sequence of ObserverDesign
    frequency : ndarray
        Frequencies [Hz].
    sensitivities : sequence of complex ndarray, optional
        Input sensitivity of each design's closed loop at ``frequency`` (a fourth panel).
    mark_frequency : float, optional
        A disturbance frequency [Hz] to mark with a vertical line.
    labels : sequence of str, optional
        The legend entry of each design. Default: its order and bandwidth (designs of the
        paper's family; any other family's design needs ``labels``).

    Returns
    -------
    matplotlib.figure.Figure
        Stacked panels sharing the frequency axis [Hz]: ``|Q|`` and ``|1 - Q|`` [dB], the
        phase of ``Q`` [deg], and ``|S|`` [dB] if given.

    Examples
    --------
    >>> import matplotlib.pyplot as plt, numpy as np
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.analysis import bode_figure
    >>> model = ServoModel(J=2.8e-4).discretize(1e-3)
    >>> designs = [design_observer(model, order=m, bandwidth=100.0) for m in (0, 1)]
    >>> fig = bode_figure(designs, np.geomspace(0.1, 500.0, 200), mark_frequency=2.0)
    >>> len(fig.axes)
    3
    >>> plt.close(fig)
    """
    import matplotlib.pyplot as plt

    rows = 4 if sensitivities is not None else 3
    fig, axes = plt.subplots(
        rows, 1, figsize=(PAPER_WIDTH, 2.1 * rows + 0.6), sharex=True, layout="constrained"
    )
    for i, design in enumerate(designs):
        q = estimation_response(design, frequency)
        e = estimation_response(design, frequency, error=True)
        if labels is not None:
            label = labels[i]
        else:
            label = f"{order_name(design.order)}, g = {design.bandwidth:g} rad/s"
        axes[0].semilogx(frequency, 20 * np.log10(np.abs(q)), label=label)
        axes[1].semilogx(frequency, np.degrees(np.unwrap(np.angle(q))))
        axes[2].semilogx(frequency, 20 * np.log10(np.abs(e)))
        if sensitivities is not None:
            axes[3].semilogx(frequency, 20 * np.log10(np.abs(sensitivities[i])))
    style_axes(axes[0], xlabel=None, ylabel=r"$|Q|$ = $|\hat\tau/\tau_{dn}|$ [dB]")
    style_axes(axes[1], xlabel=None, ylabel=r"phase of $Q$ [deg]")
    style_axes(axes[2], xlabel=None, ylabel=r"$|1-Q|$ (estimation error) [dB]")
    if sensitivities is not None:
        style_axes(axes[3], xlabel=None, ylabel="input sensitivity |S| [dB]")
    axes[-1].set_xlabel("frequency [Hz]")
    axes[0].legend(loc="lower left", fontsize="small")
    if mark_frequency is not None:
        for ax in axes:
            ax.axvline(mark_frequency, color="0.5", linestyle=":", linewidth=1.0)
    title = "Disturbance-estimation response Q (closed form)"
    if sensitivities is not None:
        title += " and the loop's input sensitivity S"
    fig.suptitle(title, fontsize="medium")  # fits the figure's width (it was clipped at large)
    return fig


def noise_figure(bandwidths, orders, gains, *, labels=None):
    """Noise gains against bandwidth: estimate and command, position and velocity noise.

    Parameters
    ----------
    bandwidths : sequence of float
        Observer bandwidths [rad/s] (the horizontal axis).
    orders : sequence of int
        Truncation orders, one curve each.
    gains : sequence of sequences of NoiseGains
        ``gains[i][j]`` is the :class:`~hpdob.NoiseGains` of ``orders[i]`` at
        ``bandwidths[j]`` (from :func:`hpdob.noise_gains`).
    labels : sequence of str, optional
        The legend entry of each curve. Default: the paper's name of each order.

    Returns
    -------
    matplotlib.figure.Figure
        Four panels: the estimate's and the command's noise gains, per position and per
        velocity noise, against bandwidth [rad/s].

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from hpdob import PD, ServoModel, design_observer, noise_gains
    >>> from hpdob.analysis import noise_figure
    >>> nominal, bandwidths = ServoModel(J=2.8e-4), [50.0, 100.0, 200.0]
    >>> def gains(m, g):
    ...     obs = design_observer(nominal.discretize(1e-3), order=m, bandwidth=g)
    ...     return noise_gains(plant=nominal, nominal=nominal, Ts=1e-3, controller=PD(50, 5),
    ...                        observer=obs)
    >>> fig = noise_figure(bandwidths, (0, 1), [[gains(m, g) for g in bandwidths] for m in (0, 1)])
    >>> len(fig.axes)
    4
    >>> plt.close(fig)
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(PAPER_WIDTH, 5.2), sharex=True, layout="constrained")
    panels = [
        ("tau_hat_position", r"RMS $\hat\tau$ per position noise [N m/rad]"),
        ("tau_hat_velocity", r"RMS $\hat\tau$ per velocity noise [N m/(rad/s)]"),
        ("u_position", "RMS u per position noise [N m/rad]"),
        ("u_velocity", "RMS u per velocity noise [N m/(rad/s)]"),
    ]
    for ax, (name, ylabel) in zip(axes.ravel(), panels, strict=True):
        for i, m in enumerate(orders):
            label = order_name(m) if labels is None else labels[i]
            ax.loglog(bandwidths, [getattr(g, name) for g in gains[i]], label=label)
        style_axes(ax, xlabel=None, ylabel=ylabel)
        ax.yaxis.label.set_fontsize("small")
    for ax in axes[1]:
        ax.set_xlabel("observer bandwidth g [rad/s]")
    axes[0, 0].legend(loc="best", fontsize="small")
    fig.suptitle(
        "Noise gains of the closed loop (exact, discrete Lyapunov equation)", fontsize="medium"
    )
    return fig
