r"""Offline estimation: any observer run over a logged run, compiled."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .._table import columns_to_csv, columns_to_pandas
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_real,
    as_real_vector,
    readonly,
)
from ..observers import as_system, initial_state
from ._checks import check_lengths, check_time, sample_view

__all__ = ["EstimationResult", "estimate_disturbance"]


class _Derive:
    """A recipe for a result's array: the time ``k Ts`` or the backward difference of the
    position, computed when the field is first read (:class:`_OnFirstRead`)."""

    __slots__ = ("Ts", "n", "theta")

    def __init__(self, *, Ts: float, n: int = 0, theta: np.ndarray | None = None):
        self.Ts, self.n, self.theta = Ts, n, theta

    def __call__(self) -> np.ndarray:
        if self.theta is None:  # the loop's k * Ts: the integer k as a float, times Ts
            return readonly(np.arange(self.n) * self.Ts)
        theta = self.theta  # the loop's (theta[k] - theta[k - 1]) / Ts, 0 at k = 0
        omega = np.empty(theta.shape[0])
        omega[:1] = 0.0
        np.subtract(theta[1:], theta[:-1], out=omega[1:])
        np.divide(omega[1:], self.Ts, out=omega[1:])
        return readonly(omega)


class _OnFirstRead:
    """A dataclass field that may be given as a :class:`_Derive` recipe: the array is then
    computed on first read and kept. The time and a differenced velocity cost 8 bytes a
    sample to write and to hold, and many callers read only the estimate: a long log's call
    does not write them (1e7 samples: 160 MB fewer) until they are read."""

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, objtype=None):
        if obj is None:  # the class's attribute: for dataclasses, a field without a default
            raise AttributeError(self.name)
        value = obj.__dict__[self.name]
        if isinstance(value, _Derive):  # two threads may both compute it: the same bits
            value = obj.__dict__[self.name] = value()
        return value

    def __set__(self, obj, value):  # only __init__ gets here: the dataclass is frozen
        obj.__dict__[self.name] = value


@dataclass(frozen=True, eq=False)
class EstimationResult:
    r"""An observer's estimates over a logged run (see :func:`estimate_disturbance`).

    Attributes
    ----------
    t : ndarray
        Sampling instants [s].
    theta : ndarray
        Measured position [rad or m].
    omega : ndarray or None
        The velocity [rad/s or m/s] the observer was given (the log's, or the backward
        difference of ``theta``); None for a position-only observer.
    u : ndarray
        Applied torque or force [N m or N].
    tau_hat : ndarray
        Estimate of the nominal disturbance :math:`\hat\tau_k` [N m or N] at every sample.
    omega_hat : ndarray or None
        The observer's velocity estimate, where it has one.
    Ts : float
        Sampling period [s].
    label : str
        Name of the observer (for plots and tables).
    state : ndarray or None
        The observer's state after the last sample: ``state=result.state`` continues the run
        on the next piece of the log, and the pieces' estimates are the whole run's, bit for
        bit (give the next piece its ``omega``: a differenced velocity restarts at 0).
    """

    t: np.ndarray = _OnFirstRead()
    theta: np.ndarray
    omega: np.ndarray | None = _OnFirstRead()
    u: np.ndarray
    tau_hat: np.ndarray
    omega_hat: np.ndarray | None
    Ts: float
    label: str = ""
    state: np.ndarray | None = None

    def __len__(self) -> int:
        return self.tau_hat.size

    def _repr_markdown_(self) -> str:
        """A compact table for Jupyter: the run and the range of the estimate."""
        from .._repr import markdown_table

        tau = self.tau_hat
        return markdown_table(f"EstimationResult {self.label!r}", [
            ("samples", f"{len(self)} (Ts = {self.Ts:g} s)"),
            ("tau_hat [N m or N]", None if tau.size == 0 else
             f"{tau.min():.4g} to {tau.max():.4g}, last {tau[-1]:.4g}"),
            ("omega_hat", None if self.omega_hat is None else "estimated"),
        ])  # fmt: skip

    def _columns(self) -> dict:
        columns = {"t": self.t, "theta": self.theta}
        if self.omega is not None:
            columns["omega"] = self.omega
        columns.update(u=self.u, tau_hat=self.tau_hat)
        if self.omega_hat is not None:
            columns["omega_hat"] = self.omega_hat
        return columns

    def rms_error(self, reference, *, start: float = 0.0) -> float:
        """RMS of the estimate's deviation from a reference signal.

        Parameters
        ----------
        reference : array_like
            What the estimate should be at each sample [N m or N], e.g. a friction model
            evaluated on the log; the shape of ``tau_hat``.
        start : float, optional
            Only samples with ``t >= start`` [s] count (skip the observer's transient).
            Default 0.

        Returns
        -------
        float
            ``sqrt(mean((tau_hat - reference)**2))`` [N m or N].

        Raises
        ------
        ParameterValueError
            If ``reference`` has the wrong shape or ``start`` leaves no sample.
        """
        reference = np.asarray(reference, dtype=float)
        if reference.shape != self.tau_hat.shape:
            raise ParameterValueError(
                f"reference must have shape {self.tau_hat.shape} like tau_hat, got "
                f"{reference.shape}"
            )
        start = as_real(start, "start", "a finite time [s]")
        keep = self.t >= start
        if not keep.any():
            raise ParameterValueError(
                f"start = {start!r} s leaves no sample (t ends at {float(self.t[-1])!r} s)"
            )
        return float(np.sqrt(np.mean((self.tau_hat[keep] - reference[keep]) ** 2)))

    def to_pandas(self):
        """The signals as a table.

        Returns
        -------
        pandas.DataFrame
            Columns ``t``, ``theta``, ``omega`` (if measured), ``u``, ``tau_hat`` and
            ``omega_hat`` (if the observer estimates it).

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install hpdob[pandas]``).
        """
        return columns_to_pandas(self._columns(), caller="EstimationResult.to_pandas()")

    def to_csv(self, path, *, progress=None):
        """Write the signals to ``path`` as CSV (header row, full precision), atomically.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists); the columns of :meth:`to_pandas`.
        progress : callable, optional
            Called as ``progress(rows written, rows)`` as the file is written: after each
            chunk of 32768 rows (the rows are formatted in chunks), or once for a short
            result. Its return value is ignored. Default: silent.

        Returns
        -------
        str or os.PathLike
            ``path``, as given.
        """
        columns_to_csv(self._columns(), path, progress)  # atomic: no temporary of a temporary
        return path

    def plot(self, *, reference=None, reference_label: str = "reference", title=None, axis=None):
        """Figure: position, and the estimate (with an optional reference such as a friction
        model evaluated on the log).

        Parameters
        ----------
        reference : array_like, optional
            A signal to draw with the estimate [N m or N], one value per sample.
        reference_label : str, optional
            Its legend entry. Default ``"reference"``.
        title : str, optional
            The figure's title. Default none.
        axis : {"rotary", "linear"}, optional
            The units of the labels: rad and N m, or m and N. Default: both named
            ("rad or m").

        Returns
        -------
        matplotlib.figure.Figure
            Traces longer than 20 000 samples are drawn as their envelope (the minimum and
            maximum of each run of samples), which spans what the full trace would.

        Raises
        ------
        ParameterValueError
            For an unknown ``axis``.
        """
        from .._plotting import envelope

        return estimate_figure(
            envelope(self.t, self.theta),
            envelope(self.t, self.tau_hat),
            None if reference is None else envelope(self.t, reference),
            t_first=float(self.t[0]), n=len(self), Ts=self.Ts, label=self.label, title=title,
            axis=axis, reference_label=reference_label,
        )  # fmt: skip


def estimate_figure(theta, tau_hat, reference, *, t_first, n, Ts, label, title, axis,
                    reference_label="reference"):  # fmt: skip
    """The figure of :meth:`EstimationResult.plot` from the traces to draw, ``(t, values)``
    each (already reduced to their envelope), for a run of ``n`` samples from ``t_first``."""
    import matplotlib.pyplot as plt

    from .._plotting import PAPER_WIDTH, style_axes
    from .._validation import check_choice

    position, force = {"rotary": ("rad", "N m"), "linear": ("m", "N"),
                       None: ("rad or m", "N m or N")}[
        None if axis is None else check_choice(axis, "axis", ("rotary", "linear"))
    ]  # fmt: skip

    fig, (top, bottom) = plt.subplots(
        2, 1, figsize=(PAPER_WIDTH, 4.6), sharex=True, layout="constrained"
    )
    top.plot(*theta, color="tab:blue", linewidth=1.0)
    style_axes(top, xlabel=None, ylabel=f"position [{position}]")
    if reference is not None:
        bottom.plot(*reference, color="0.4", linewidth=1.0, label=reference_label)
    bottom.plot(*tau_hat, color="tab:red", linewidth=0.8,
                label=rf"$\hat\tau$ ({label or 'observer'})")  # fmt: skip
    style_axes(bottom, xlabel="time [s]", ylabel=f"disturbance [{force}]")
    bottom.set_xlim(t_first, t_first + n * Ts)  # the whole run, as _plotting.time_axis
    bottom.legend(loc="upper center", bbox_to_anchor=(0.5, -0.28), ncols=2, fontsize="small")
    if title:
        fig.suptitle(title, fontsize="medium")
    return fig


def estimate_disturbance(observer, *, theta, u, omega=None, t=None, tau0: float = 0.0,
                         state=None):  # fmt: skip
    r"""Run an observer of any family over a logged run; return its estimates.

    At every sample ``k`` the observer gives its estimate from the measurement, then is
    updated with the measurement and the logged input ``u_k`` (the torque that was applied),
    exactly as in the sample loop; the loop runs compiled (numba), evaluating the observer's
    program in the same order as the runtime object, which it reproduces bit for bit.

    One rule for where the run starts, whatever form the observer is given in (a design, a
    :class:`~hpdob.LinearObserver`, a runtime object): converged at the log's first sample,
    ``initial_state(observer, (theta[0], omega[0]), tau0)`` (with ``omega[0] = 0`` when the
    velocity is differenced or estimated), unless ``state`` gives the start explicitly, e.g.
    ``state=obs.state`` to continue from a runtime object. The observer passed in is never
    changed.

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
        Designed on the nominal model of the logged axis (e.g. ``identify(...).model()``) at the
        log's sampling period.
    theta : array_like
        Measured position [rad or m], one entry per sample.
    u : array_like
        Applied torque or force [N m or N], same length.
    omega : array_like, optional
        Measured velocity for an observer that measures the state. Without it, such an observer
        gets the backward difference of ``theta``, with 0 at the first sample (at rest before
        the log starts). Not accepted by a position-only observer.
    t : array_like, optional
        Sampling instants [s]; they must be uniform with the observer's ``Ts``. Default
        ``k Ts``.
    tau0 : float, optional
        Initial disturbance of the reset [N m or N]. Default 0.
    state : array_like, optional
        The observer's state at the first sample instead (``n_states`` finite values, e.g. a
        runtime object's ``.state``); not together with a non-zero ``tau0``.

    Returns
    -------
    EstimationResult

    Raises
    ------
    TypeError, ValueError
        For a wrong observer, signals of different lengths or with non-finite samples,
        non-uniform time, a time step other than the observer's ``Ts``, ``omega`` given to a
        position-only observer, or a ``state`` of the wrong size.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import ServoModel, design_observer, estimate_disturbance
    >>> model = ServoModel(2.8e-4).discretize(1e-3)
    >>> theta, u = np.zeros(500), np.full(500, 0.02)  # holding still against 0.02 N m
    >>> result = estimate_disturbance(design_observer(model, order=1, bandwidth=100.0),
    ...                               theta=theta, u=u)
    >>> round(float(result.tau_hat[-1]), 9)
    0.02
    """
    from . import _estimate_kernel as kernel

    system = as_system(observer)
    # Checked without a copy where possible: the loop copies the signals while it reads them.
    theta = sample_view(theta, "theta", "measured positions [rad or m]")
    u = sample_view(u, "u", "applied torques or forces [N m or N]")
    signals = {"theta": theta, "u": u}
    position_only = len(system.measures) == 1
    if omega is not None:
        if position_only:
            raise ParameterValueError(
                "omega must be None for an observer that measures the position only "
                f"(measures {system.measures}); it estimates the velocity itself"
            )
        signals["omega"] = sample_view(omega, "omega", "measured velocities [rad/s or m/s]")
    n = check_lengths(signals)
    Ts = system.Ts
    check = None
    if t is not None:
        t = sample_view(t, "t", "sampling instants [s]")
        check_lengths({**signals, "t": t})
        if n > 1:  # made while a long log's loop runs (an error is raised instead of a result)
            check = functools.partial(_check_steps, t, Ts)
    tau0 = as_real(tau0, "tau0", "a finite initial disturbance [N m or N]")
    if state is not None:
        state = as_real_vector(state, "state", f"the observer's {system.n_states} finite states",
                               length=system.n_states)  # fmt: skip
        if tau0 != 0.0:
            raise ParameterValueError(
                f"give tau0 or state, not both: state sets the start, got tau0={tau0!r}"
            )
    label = observer_label(observer, system)
    if position_only:
        mode = kernel.VELOCITY_NONE
    elif omega is not None:
        mode = kernel.VELOCITY_GIVEN
    else:  # the backward difference, written by the loop (0 at the first sample)
        mode = kernel.VELOCITY_DERIVED
    if state is not None:
        s0 = np.array(state, dtype=float)
    else:  # one rule for every form of observer: converged at the first sample
        omega0 = float(signals["omega"][0]) if mode == kernel.VELOCITY_GIVEN else 0.0
        s0 = start_state(system, float(theta[0]), omega0, tau0)
    theta, velocity, u, tau_hat, omega_hat, t, final = kernel.run(
        system, s0, theta, signals.get("omega"), u, t, mode, check=check
    )
    theta = readonly(theta)
    if velocity is not None:
        velocity = readonly(velocity)
    elif mode == kernel.VELOCITY_DERIVED:  # differenced by the loop, not written: on first read
        velocity = _Derive(Ts=float(Ts), theta=theta)
    return EstimationResult(
        t=_Derive(Ts=float(Ts), n=n) if t is None else readonly(t),  # k Ts, on first read too
        theta=theta,
        omega=velocity,
        u=readonly(u),
        tau_hat=readonly(tau_hat),
        omega_hat=None if omega_hat is None else readonly(omega_hat),
        Ts=Ts,
        label=label,
        state=readonly(final),
    )


def _check_steps(t, Ts) -> None:
    """That the times ``t`` advance uniformly by ``Ts`` [s]."""
    step = check_time(t, "t", 1e-3)
    if not math.isclose(step, Ts, rel_tol=1e-6):
        raise ParameterValueError(
            f"t must advance by the observer's sampling period Ts = {float(Ts)!r} s, got a "
            f"step of {float(step)!r} s"
        )


def observer_label(observer, system) -> str:
    """The name of a run's observer: its ``label``, else its system's name."""
    label = getattr(observer, "label", "") or system.name
    if not isinstance(label, str):
        raise ParameterTypeError(f"the observer's label must be a str, got {label!r}")
    return label


def start_state(system, theta0: float, omega0: float, tau0: float) -> np.ndarray:
    """Where a run starts, whatever form the observer was given in: converged at the first
    sample ``(theta0, omega0)`` with the disturbance ``tau0``."""
    return np.array(initial_state(system, (theta0, omega0), tau0), dtype=float)
