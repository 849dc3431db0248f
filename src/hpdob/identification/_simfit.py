r"""How well a rigid-axis model reproduces a log when simulated on it (MATLAB ``compare``'s fit).

The model is simulated through the logged loop if one is given (the controller closes the loop
around the model, from the logged reference), otherwise in open loop from the logged input.
Its position, and its velocity by the same filtered differentiation as the log's, are compared
with the log's by the normalised root-mean-square fit of MATLAB's ``compare``,

.. math:: \mathrm{fit} = 100\,\Big(1 - \frac{\lVert y - \hat y\rVert}{\lVert y - \bar y\rVert}
          \Big)\ \%,

100 % for a perfect match, 0 % for no better than the mean, negative for worse.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .._validation import ParameterValueError, as_real, require_instance
from ._log import Log
from ._loop import FeedbackLoop, run_simulation
from ._regression import (
    PARAMETERS,
    Settings,
    filtered_velocity,
    resolve_settings,
    velocity_blocks,
)

__all__ = ["MIN_FIT", "SimulationFit", "Validation", "nrmse_fit", "simulate_fit", "validate"]

#: The identified model "does not reproduce the log" when its simulated velocity (and, through
#: a loop, position) fits the log by less than this [%]. Measured with the defaults: 95 % on
#: EMPS (open loop), 97-99.9 % on the synthetic grid logs; the same models with J off by 20 %:
#: 80 %, by a factor 2: 30-55 %, with half the Coulomb friction: 50-60 %.
MIN_FIT = 90.0


def nrmse_fit(measured: np.ndarray, simulated: np.ndarray, *, spread=None, out=None) -> float:
    """``100 (1 - ||y - y_hat|| / ||y - mean(y)||)`` [%] (MATLAB ``compare``); -inf for a
    constant ``y`` that is not matched exactly. ``spread``: ``||y - mean(y)||`` computed
    before; ``out``: an array of ``y``'s size the difference may be written to (the same
    numbers as numpy's temporary)."""
    if spread is None:
        spread = float(np.linalg.norm(measured - measured.mean()))
    return _nrmse(float(np.linalg.norm(np.subtract(measured, simulated, out=out))), spread)


def _nrmse(error: float, spread: float) -> float:
    """:func:`nrmse_fit` of ``error = ||y - y_hat||`` and ``spread = ||y - mean(y)||``."""
    if spread == 0.0:
        return 100.0 if error == 0.0 else -math.inf
    return 100.0 * (1.0 - error / spread)


@dataclass(frozen=True)
class SimulationFit:
    """The model simulated on one log, and its fit."""

    t: np.ndarray
    theta: np.ndarray  # logged position
    theta_simulated: np.ndarray
    velocity: np.ndarray  # logged velocity (filtered differentiation)
    velocity_simulated: np.ndarray  # the same differentiation of the simulated position
    u_simulated: np.ndarray
    closed_loop: bool
    position_fit: float
    velocity_fit: float

    def to_dict(self) -> dict:
        return {
            "mode": "through the logged loop" if self.closed_loop else "open loop from the input",
            "position_fit_percent": self.position_fit,
            "velocity_fit_percent": self.velocity_fit,
        }


def open_loop(u: np.ndarray) -> FeedbackLoop:
    """The logged input applied as it is (no feedback): feed-forward only."""
    return FeedbackLoop(np.zeros(u.size), kp=0.0, kd=0.0, feedforward=u, velocity_filter=None)


def simulate_fit(
    parameters,
    t: np.ndarray,
    theta: np.ndarray,
    u: np.ndarray,
    loop,
    settings: Settings,
    *,
    keep: bool = True,
    simulated=None,
) -> SimulationFit:
    """Simulate ``parameters = (J, b, coulomb, offset)`` on a log (through ``loop``, or open
    loop from ``u`` if it is None) from the log's initial position and filtered velocity.
    Negative friction is simulated as 0.

    With ``keep=False`` no trace is kept (None; the fits are the same numbers) and the run
    holds at most two arrays of the log's length at a time beside its result: the simulated
    position and command are handed to ``simulated(position, command, again)`` if given (the
    command None in open loop), which may overwrite the command, call ``again()`` to have the
    same simulation written into both arrays anew, and keep the position (returning True;
    then not overwritten), before the velocities are computed."""
    J, b, coulomb, offset = (float(p) for p in parameters)
    closed = loop is not None
    if not keep:
        return _fit_numbers((J, b, coulomb, offset), t, theta, u, loop, settings, simulated)
    velocity = filtered_velocity(theta, settings)  # np.gradient of sosfiltfilt, bit for bit
    velocity_spread = float(np.linalg.norm(velocity - velocity.mean()))
    # the open loop: the logged input applied as it is (no feedback), feed-forward only; as
    # open_loop(u) without its arrays of zeros
    theta_simulated, u_simulated = run_simulation(
        loop if closed else u.size,
        (J, max(b, 0.0), max(coulomb, 0.0), offset),
        Ts=settings.Ts,
        theta0=float(theta[0]),
        velocity0=float(velocity[0]),
        feedforward=None if closed else u,
    )
    position_fit = nrmse_fit(theta, theta_simulated)
    velocity_simulated = filtered_velocity(theta_simulated, settings)
    return SimulationFit(
        t=t,
        theta=theta,
        theta_simulated=theta_simulated,
        velocity=velocity,
        velocity_simulated=velocity_simulated,
        u_simulated=u_simulated,
        closed_loop=closed,
        position_fit=position_fit,
        velocity_fit=nrmse_fit(velocity, velocity_simulated, spread=velocity_spread),
    )


def _fit_numbers(parameters, t, theta, u, loop, settings, simulated) -> SimulationFit:
    """:func:`simulate_fit` with ``keep=False``: the same numbers in the same operations,
    ordered so that few arrays of the log's length live at once. The log's velocity is
    computed twice (its spread and first sample before the simulation, itself after it)
    rather than held beside the simulated position."""
    J, b, coulomb, offset = parameters
    closed = loop is not None
    velocity = filtered_velocity(theta, settings)
    velocity0 = float(velocity[0])
    velocity_spread = float(np.linalg.norm(velocity - velocity.mean()))
    del velocity
    position_spread = float(np.linalg.norm(theta - theta.mean()))
    run = {"Ts": settings.Ts, "theta0": float(theta[0]), "velocity0": velocity0,
           "feedforward": None if closed else u, "command": closed}  # fmt: skip
    simulation = (loop if closed else u.size, (J, max(b, 0.0), max(coulomb, 0.0), offset))
    position, command = run_simulation(*simulation, **run)
    kept = False
    if simulated is not None:
        # the same simulation again, into the same arrays (the same numbers: a caller that
        # has overwritten the command gets it back without a third array)
        again = functools.partial(run_simulation, *simulation, **run, out=position,
                                  command_out=command)  # fmt: skip
        kept = bool(simulated(position, command, again))
        del again  # not holding the arrays
    # the position's difference over the command, which is no longer needed
    position_fit = nrmse_fit(theta, position, spread=position_spread, out=command)
    del command
    # the velocity of the simulated position, over it unless the caller keeps it
    velocity_simulated = filtered_velocity(position, settings, overwrite=not kept)
    del position
    # nrmse_fit(velocity, velocity_simulated) with the log's velocity taken block by block
    # (not a third array of the log's length beside the kept position): the difference is
    # written over the simulated velocity, sample by sample the same subtraction
    error = velocity_simulated
    for lo, hi, velocity in velocity_blocks(theta, settings):
        np.subtract(velocity, error[lo:hi], out=error[lo:hi])
        del velocity  # not beside the next block
    velocity_fit = _nrmse(float(np.linalg.norm(error)), velocity_spread)
    return SimulationFit(t=t, theta=theta, theta_simulated=None, velocity=None,
                         velocity_simulated=None, u_simulated=None, closed_loop=closed,
                         position_fit=position_fit, velocity_fit=velocity_fit)  # fmt: skip


@dataclass(frozen=True, eq=False)
class Validation:
    """An identified model simulated on a log, and how well it fits (see
    :meth:`Identification.validate`).

    Attributes
    ----------
    parameters : dict
        ``J``, ``b``, ``coulomb``, ``offset`` simulated.
    source : str
        The log's name.
    closed_loop : bool
        Simulated through the logged loop (True) or open loop from the logged input.
    position_fit, velocity_fit : float
        NRMSE fit [%] of position and velocity, MATLAB ``compare``'s
        ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)``.
    t, theta, theta_simulated, velocity, velocity_simulated : ndarray
        The traces compared (velocities by the identification's filtered differentiation).
    axis : str or None
        Units of the report.
    """

    parameters: dict
    source: str
    closed_loop: bool
    position_fit: float
    velocity_fit: float
    t: np.ndarray
    theta: np.ndarray
    theta_simulated: np.ndarray
    velocity: np.ndarray
    velocity_simulated: np.ndarray
    axis: str | None = None

    def summary(self) -> str:
        """One line: the log, how it was simulated and the two fits.

        Returns
        -------
        str
        """
        mode = "through its loop" if self.closed_loop else "open loop from its input"
        return (
            f"validation on {self.source or 'the log'} ({mode}): position fit "
            f"{self.position_fit:.2f} %, velocity fit {self.velocity_fit:.2f} % (MATLAB compare)"
        )

    def to_dict(self) -> dict:
        """The validation as plain data.

        Returns
        -------
        dict
            ``source``, ``mode``, ``position_fit_percent``, ``velocity_fit_percent``,
            ``parameters`` (non-finite fits as None).
        """
        fits = {
            "position_fit_percent": self.position_fit,
            "velocity_fit_percent": self.velocity_fit,
        }
        return {
            "source": self.source,
            "mode": "through the logged loop" if self.closed_loop else "open loop from the input",
            **{k: (v if math.isfinite(v) else None) for k, v in fits.items()},
            "parameters": dict(self.parameters),
        }

    def plot(self, *, title: str | None = None):
        """Measured and simulated position and velocity against time.

        Parameters
        ----------
        title : str, optional
            Default: the log and the two fits.

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        from .._plotting import PAPER_WIDTH, legend_clear_of_data, style_axes
        from ._checks import units

        unit = units(self.axis)
        fig, axes = plt.subplots(2, 1, figsize=(PAPER_WIDTH, 5.0), sharex=True,
                                 layout="constrained")  # fmt: skip
        mode = "loop" if self.closed_loop else "open loop"
        for ax, measured, simulated, name, fit in (
            (axes[0], self.theta, self.theta_simulated, "position", self.position_fit),
            (axes[1], self.velocity, self.velocity_simulated, "velocity", self.velocity_fit),
        ):
            ax.plot(self.t, measured, color="0.35", linewidth=1.2, label="measured")
            ax.plot(self.t, simulated, "--", linewidth=1.0,
                    label=f"model simulated ({mode}), fit {fit:.1f} %")  # fmt: skip
            style_axes(ax, xlabel="time [s]" if name == "velocity" else None,
                       ylabel=f"{name} [{unit[name]}]")  # fmt: skip
        fig.suptitle(title or f"validation on {self.source or 'the log'}")
        for ax in axes:
            legend_clear_of_data(ax, ncol=2)
        return fig


def validate(fit, log, *, loop=None, offset=None) -> Validation:
    """:meth:`Identification.validate` (``fit``) on ``log``: see there."""
    log = require_instance(log, Log, "log")
    loop = require_instance(loop, FeedbackLoop, "loop", optional=True)
    if loop is not None and len(loop) != len(log):
        raise ParameterValueError(
            f"loop must have one reference sample per logged sample: the log has "
            f"{len(log)}, loop.reference has {len(loop)}"
        )
    if not fit.J > 0.0:
        raise ParameterValueError(
            f"the identified J = {fit.J:.6g} {fit.units['J']} is not positive: the model "
            "cannot be simulated"
        )
    offset = fit.offset if offset is None else as_real(offset, "offset", "a finite offset")
    cutoff = min(float(fit.settings["cutoff"]), 0.4 / log.Ts)
    settings = resolve_settings(log.Ts, cutoff=cutoff, order=int(fit.settings["order"]),
                                decimation=1, border=0)  # fmt: skip
    parameters = (fit.J, fit.b, fit.coulomb, offset)
    run = simulate_fit(parameters, log.t, log.theta, log.u, loop, settings)
    return Validation(
        parameters=dict(zip(PARAMETERS, (float(p) for p in parameters), strict=True)),
        source=log.source,
        closed_loop=run.closed_loop,
        position_fit=run.position_fit,
        velocity_fit=run.velocity_fit,
        t=run.t,
        theta=run.theta,
        theta_simulated=run.theta_simulated,
        velocity=run.velocity,
        velocity_simulated=run.velocity_simulated,
        axis=fit.axis if fit.axis is not None else log.axis,
    )
