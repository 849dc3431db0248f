"""Offline estimation of a long log a block at a time, its traces written to CSV as they come."""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, as_real, readonly
from ..observers import as_system
from . import _estimate_kernel as kernel
from ._estimate import estimate_figure, observer_label, start_state
from ._log import Log
from ._log_file import LogFile, log_blocks

__all__ = ["LogEstimate", "estimate_log"]


@dataclass(frozen=True, eq=False)
class LogEstimate:
    r"""An observer's estimate over a log read block by block (see :func:`estimate_log`).

    Attributes
    ----------
    tau_hat : ndarray or None
        Estimate of the nominal disturbance :math:`\hat\tau_k` [N m or N] at every sample,
        the values :func:`estimate_disturbance` gives on the whole log (None with
        ``keep=False``).
    Ts : float
        Sampling period [s].
    n : int
        Number of samples (``len()``).
    finite : bool
        Whether every estimate is finite (False: the observer diverged, or the log's values
        overflow it).
    t_first : float
        The log's first sampling instant [s].
    label : str
        Name of the observer.
    mean, std : float
        Of ``tau_hat`` over the samples at or after ``t_first + settle (t_last - t_first)``.
    columns : tuple of str
        The CSV's columns (those of :meth:`EstimationResult.to_csv`).
    """

    tau_hat: np.ndarray | None
    Ts: float
    n: int
    t_first: float
    label: str
    finite: bool
    mean: float
    std: float
    columns: tuple
    _traces: tuple = field(repr=False)  # (t, theta) and (t, tau_hat) envelopes to draw

    def __len__(self) -> int:
        return self.n

    def plot(self, *, title: str | None = None, axis: str | None = None):
        """The figure of :meth:`EstimationResult.plot` (position and estimate, long traces as
        their envelope), drawn from what the run kept.

        Parameters
        ----------
        title : str, optional
            The figure's title. Default none.
        axis : {"rotary", "linear"}, optional
            The units of the labels. Default: both named ("rad or m").

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ParameterValueError
            For an unknown ``axis``.
        """
        theta, tau_hat = self._traces
        return estimate_figure(theta, tau_hat, None, t_first=self.t_first, n=len(self),
                               Ts=self.Ts, label=self.label, title=title, axis=axis)  # fmt: skip


def estimate_log(observer, log, *, csv=None, tau0: float = 0.0, settle: float = 0.0,
                 keep: bool = True, progress=None):  # fmt: skip
    r"""Run an observer over a log a block at a time (:func:`estimate_disturbance`, continued
    from block to block), writing the traces to CSV as it goes.

    The estimate, the velocity (the backward difference of ``theta``, 0 at the first sample)
    and the file are those of ``estimate_disturbance(observer, theta=log.theta, u=log.u,
    t=log.t)`` and its ``to_csv``, bit for bit and byte for byte; only the estimate and the
    envelopes of the figure are held, never a copy of the log (a :class:`LogFile` of 1e7
    samples runs in a few hundred MB).

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
        Designed at the log's sampling period (as for :func:`estimate_disturbance`).
    log : LogFile or Log
        From :func:`open_log` (or :func:`read_log`).
    csv : str or os.PathLike, optional
        Where to write the traces (``t``, ``theta``, ``omega`` for an observer that measures
        the velocity, ``u``, ``tau_hat``, ``omega_hat`` where the observer estimates it);
        written atomically. Default: not written.
    tau0 : float, optional
        Initial disturbance of the reset [N m or N]. Default 0.
    settle : float, optional
        Fraction of the log's duration, from its first sample, left out of ``mean`` and
        ``std`` (the observer's transient), in [0, 1). Default 0.
    keep : bool, optional
        Hold the estimate as ``tau_hat`` (default). False keeps only ``finite``, ``mean``,
        ``std`` and the figure's envelopes (the statistics are computed in the estimate's own
        memory, without a temporary of its size): for a long log written to ``csv``.
    progress : callable, optional
        Called as ``progress(done, n)`` with the rows written to ``csv`` (after each chunk of
        the writer), or the samples estimated without one (after each block).

    Returns
    -------
    LogEstimate

    Raises
    ------
    TypeError, ValueError
        For a ``log`` that is neither a :class:`LogFile` nor a :class:`Log`, a sampling period
        other than the observer's ``Ts``, a ``settle`` outside [0, 1), or as
        :func:`estimate_disturbance`.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import ServoModel, design_observer
    >>> from hpdob.identification import Log, estimate_log
    >>> log = Log(t=np.arange(500) * 1e-3, theta=np.zeros(500), u=np.full(500, 0.02))
    >>> design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    >>> run = estimate_log(design, log, settle=0.5)
    >>> round(float(run.tau_hat[-1]), 9), round(run.mean, 6)
    (0.02, 0.02)
    """
    from .._csv_floats import RowWriter
    from .._files import atomic_path

    if isinstance(log, LogFile):
        blocks, t_first, t_last = log.blocks(), log.t_first, log.t_last
    elif isinstance(log, Log):
        blocks, t_first, t_last = log_blocks(log), float(log.t[0]), float(log.t[-1])
    else:
        raise ParameterTypeError(
            f"log must be a LogFile (open_log) or a Log (read_log), got {type(log).__name__}"
        )
    system = as_system(observer)
    if not math.isclose(log.Ts, system.Ts, rel_tol=1e-6):  # estimate_disturbance's rule
        raise ParameterValueError(
            f"t must advance by the observer's sampling period Ts = {float(system.Ts)!r} s, got "
            f"a step of {float(log.Ts)!r} s"
        )
    if progress is not None and not callable(progress):
        raise ParameterTypeError(
            f"progress must be a callable progress(done, total), got {progress!r}"
        )
    settle = as_real(settle, "settle", "a fraction of the log's duration in [0, 1)")
    if not 0.0 <= settle < 1.0:
        raise ParameterValueError(
            f"settle must be a fraction of the log's duration in [0, 1), got {settle!r}"
        )
    from .._plotting import Envelope

    tau0 = as_real(tau0, "tau0", "a finite initial disturbance [N m or N]")
    label = observer_label(observer, system)
    n, Ts = len(log), float(system.Ts)
    differenced = len(system.measures) > 1  # the velocity: the backward difference of theta
    columns = ("t", "theta", *(("omega",) if differenced else ()), "u", "tau_hat",
               *(("omega_hat",) if system.has_velocity else ()))  # fmt: skip
    threshold = t_first + settle * (t_last - t_first)
    tau_hat = np.empty(n)
    theta_trace, tau_trace = Envelope(n), Envelope(n)
    start, cut, state, previous = 0, n, None, None
    with contextlib.ExitStack() as files:  # on an error: no file, not a truncated one
        writer = None
        if csv is not None:
            handle = files.enter_context(open(files.enter_context(atomic_path(Path(csv))), "wb"))
            handle.write((",".join(columns) + "\r\n").encode())  # the csv module's header row
            writer = files.enter_context(RowWriter(handle, progress=progress, rows=n))
        for t, theta, u in blocks:
            m, stop = theta.size, start + theta.size
            if state is None:  # as estimate_disturbance starts (omega_0 = 0: at rest before)
                state = start_state(system, float(theta[0]), 0.0, tau0)
                previous = theta[0]
            omega = omega_hat = None
            if differenced:  # (theta_k - theta_{k-1}) / Ts, as its loop derives it
                omega = np.empty(m)
                omega[0] = (theta[0] - previous) / Ts
                np.subtract(theta[1:], theta[:-1], out=omega[1:])
                np.divide(omega[1:], Ts, out=omega[1:])
                previous = theta[-1]
            if system.has_velocity:
                omega_hat = np.empty(m)
            kernel.run_block(system, state, theta, omega, u, tau_hat[start:stop], omega_hat)
            if cut == n and t[-1] >= threshold:
                cut = start + int(np.searchsorted(t, threshold))
            theta_trace.add(t, theta)
            tau_trace.add(t, tau_hat[start:stop])
            if writer is not None:
                values = {"t": t, "theta": theta, "omega": omega, "u": u,
                          "tau_hat": tau_hat[start:stop], "omega_hat": omega_hat}  # fmt: skip
                writer.write([values[name] for name in columns])  # new arrays: none reused
            elif progress is not None:
                progress(stop, n)
            start = stop
    finite = bool(np.isfinite(tau_hat).all())
    tail = tau_hat[cut:]
    with np.errstate(all="ignore"):  # a diverged estimate's statistics are not finite
        mean = float(tail.mean())
        std = float(tail.std()) if keep else _std_in_place(tail)
    return LogEstimate(tau_hat=readonly(tau_hat) if keep else None, Ts=log.Ts, n=n,
                       t_first=t_first, label=label, finite=finite, mean=mean, std=std,
                       columns=columns, _traces=(theta_trace.trace, tau_trace.trace))  # fmt: skip


def _std_in_place(x: np.ndarray) -> float:
    """``float(x.std())``, bit for bit, computed in ``x``'s memory (which it overwrites) instead
    of a temporary of its size: numpy's ``_var`` subtracts the mean, squares and sums the same
    contiguous values with the same pairwise summation."""
    n = x.size
    mean = np.add.reduce(x) / n
    np.subtract(x, mean, out=x)
    np.multiply(x, x, out=x)
    return float(np.sqrt(np.add.reduce(x) / n))
