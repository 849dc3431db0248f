"""The result of a closed-loop simulation: sampled traces, metrics, CSV and plots."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._table import columns_to_csv, columns_to_pandas
from .._validation import ParameterValueError, as_real, numeric_array

__all__ = [
    "CANONICAL_WINDOWS",
    "FORCE_SETTLING",
    "SimulationResult",
    "error_metrics",
    "json_ready",
    "max_abs",
    "metric_window",
    "metrics_json",
]

#: Time windows [s] of the canonical position metrics: regulation and tracking.
CANONICAL_WINDOWS = {"regulation": (1.2, 4.0), "tracking": (4.0, math.inf)}

#: The settling time [s] after the first contact that :meth:`SimulationResult.force_metrics`'s
#: steady-state window (``window="steady"``) leaves out: the force step on the paper's motor
#: against the 10 N m/rad wall is within 1 % of tau_ref 0.44-0.55 s after the step
#: (docs/force-control.md, "What is measured").
FORCE_SETTLING = 0.5

#: Columns written by :meth:`SimulationResult.to_csv`, with units.
COLUMNS = {
    "t": "s",
    "theta": "rad",
    "omega": "rad/s",
    "theta_measured": "rad",
    "omega_measured": "rad/s",
    "r": "rad",
    "r_dot": "rad/s",
    "r_ddot": "rad/s^2",
    "u": "N m",
    "tau_hat": "N m",
    "tau_dn": "N m",
    "tau_ext": "N m",
}
#: Optional columns, present when the run has them: the observer's velocity estimate and the
#: load side of a two-mass plant, the contact torque of an environment and its in-contact flag.
OPTIONAL_COLUMNS = {"omega_hat": "rad/s", "theta_load": "rad", "omega_load": "rad/s",
                    "tau_contact": "N m", "in_contact": "1", "tau_reac": "N m"}  # fmt: skip


def json_ready(value):
    """``value`` for strict JSON: numpy scalars become Python ones, non-finite floats None."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, (np.integer, np.bool_)):
        return value.item()
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def metrics_json(metrics: dict) -> str:
    """``{run: {metric: value}}`` as JSON text, NaN written as ``null`` (strict JSON)."""
    return json.dumps(json_ready(metrics), indent=2, allow_nan=False) + "\n"


def metric_window(bounds, name: str) -> tuple[float, float]:
    """``bounds`` as a ``(start, stop)`` window [s] with ``start < stop`` (stop may be inf)."""
    what = "a (start, stop) pair of times [s]"
    if type(bounds) is tuple and len(bounds) == 2 and all(type(b) is float for b in bounds):
        lo, hi = bounds  # already what the generic check below would make of it
    else:
        pair = numeric_array(bounds, name, what)
        if pair.shape != (2,):
            raise ParameterValueError(f"{name} must be {what}, got {bounds!r}")
        lo, hi = float(pair[0]), float(pair[1])
    if not lo < hi:
        raise ParameterValueError(f"{name} must have start < stop [s], got {bounds!r}")
    return lo, hi


def _rms(values: np.ndarray) -> float:
    """Root mean square, scaled so that huge values of a diverged run do not overflow."""
    if not values.size:
        return math.nan
    scale = float(np.max(np.abs(values)))
    if not 0.0 < scale < math.inf:
        return scale  # all zero, or inf/nan in the trace
    scaled = values / scale
    np.square(scaled, out=scaled)  # what ``** 2`` computes, without a second temporary
    # np.mean's own arithmetic (np.add.reduce, then / count) without its Python wrapper
    return scale * math.sqrt(float(np.add.reduce(scaled)) / scaled.size)


def error_metrics(t, estimation_error, position_error, *, regulation, tracking,
                  increasing=False) -> dict:  # fmt: skip
    """:meth:`SimulationResult.metrics` of a run's traces ``t`` [s], ``tau_hat - tau_dn``
    [N m] and ``theta - r`` [rad]: the one computation of both a result and a sweep's row.

    ``increasing``: ``t`` is known to increase (a run's grid ``k Ts``), so each window's
    samples are one slice, found by bisection instead of a mask over the run: the same
    samples in the same order, so the same RMS bit for bit."""

    def window(bounds, name):
        lo, hi = metric_window(bounds, name)
        if increasing:  # t >= lo from index i on, t < hi up to index j (excluded)
            i, j = np.searchsorted(t, (lo, hi), side="left").tolist()
            return _rms(position_error[i:j])
        mask = (t >= lo) & (t < hi)
        return _rms(position_error[mask])

    return {
        "rms_estimation_error": _rms(estimation_error),
        "rms_position_error_regulation": window(regulation, "regulation"),
        "rms_position_error_tracking": window(tracking, "tracking"),
    }


def max_abs(values: np.ndarray) -> float:
    """``max |values|``, NaN for an empty array (as
    :meth:`SimulationResult.max_abs_position_error`)."""
    return float(np.max(np.abs(values))) if len(values) else math.nan


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Sampled traces of one closed-loop run (all arrays have one entry per sample).

    Attributes
    ----------
    t : ndarray
        Sampling instants ``k Ts`` [s].
    theta, omega : ndarray
        True angle [rad] and velocity [rad/s] of the plant at ``t``.
    theta_measured, omega_measured : ndarray
        What the sensor delivered to the controller and observer.
    r, r_dot, r_ddot : ndarray
        Reference and its derivatives [rad, rad/s, rad/s^2].
    u : ndarray
        Torque command [N m] (after the actuator limit; the observer's input).
    tau_hat : ndarray
        Disturbance estimate [N m] (zeros without an observer).
    tau_dn : ndarray
        Ground truth: the nominal disturbance of eq. (3) just after ``u_k`` is applied,
        ``u - b_n omega - J_n theta_ddot(t_k+)`` [N m].
    tau_ext : ndarray
        External disturbance torque at ``t`` [N m].
    omega_hat : ndarray or None
        The observer's velocity estimate [rad/s] (observers that have one; else None).
    theta_load, omega_load : ndarray or None
        Load angle [rad] and velocity [rad/s] of a :class:`~hpdob.TwoMassServo` (else None);
        ``theta`` and ``omega`` are the motor's.
    tau_contact, in_contact : ndarray or None
        Ground truth of a plant with an :class:`~hpdob.Environment` (else None): the contact
        torque at ``t`` [N m] and 1.0 where the environment pushes at ``t`` (else 0.0).
    tau_reac : ndarray or None
        The observer's reaction-torque estimate [N m] (an observer with a ``tau_reac`` output,
        :func:`hpdob.observers.reaction_torque_observer`; else None).
    Ts : float
        Sampling period [s].
    label : str
        Name of the run (used in plots and tables).
    diverged : bool
        True if the run stopped early because the state blew up; the arrays then end there.
    message : str
        Human-readable status.
    """

    t: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    theta_measured: np.ndarray
    omega_measured: np.ndarray
    r: np.ndarray
    r_dot: np.ndarray
    r_ddot: np.ndarray
    u: np.ndarray
    tau_hat: np.ndarray
    tau_dn: np.ndarray
    tau_ext: np.ndarray
    Ts: float
    label: str = ""
    diverged: bool = False
    message: str = "ok"
    omega_hat: np.ndarray | None = None
    theta_load: np.ndarray | None = None
    omega_load: np.ndarray | None = None
    tau_contact: np.ndarray | None = None
    in_contact: np.ndarray | None = None
    tau_reac: np.ndarray | None = None

    def __post_init__(self):
        n = len(self.t)
        for name in (*COLUMNS, *OPTIONAL_COLUMNS):
            if name in OPTIONAL_COLUMNS and getattr(self, name) is None:
                continue
            array = np.array(getattr(self, name), dtype=float)
            if array.shape != (n,):
                raise ParameterValueError(
                    f"{name} must have shape ({n},) like t, got {array.shape}"
                )
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @classmethod
    def _of_arrays(cls, **values) -> SimulationResult:
        """A result of float arrays a run just made (``run_loop``), held as they are, made
        read-only, without the constructor's copies and checks: each is a fresh view with one
        entry per sample whose data nobody else writes (a non-contiguous one, a two-mass
        plant's load column, is copied)."""
        missing = _REQUIRED_FIELDS - values.keys()
        unknown = values.keys() - _DEFAULTS.keys() - _REQUIRED_FIELDS
        if missing or unknown:
            raise TypeError(f"result fields missing {sorted(missing)}, unknown {sorted(unknown)}")
        for name, value in values.items():
            if isinstance(value, np.ndarray):
                if not value.flags.c_contiguous:
                    value = values[name] = np.ascontiguousarray(value)
                value.flags.writeable = False
        result = object.__new__(cls)
        result.__dict__.update(_DEFAULTS, **values)  # a frozen dataclass: filled directly
        return result

    def __len__(self) -> int:
        return len(self.t)

    def _repr_markdown_(self) -> str:
        """A compact table for Jupyter: the run and its metrics."""
        from .._repr import markdown_table

        duration = len(self) * self.Ts
        rows = [("samples", f"{len(self)} (Ts = {self.Ts:g} s, {duration:g} s)"),
                ("status", self.message)]  # fmt: skip
        rows += [(f"{name} [{'N m' if 'estimation' in name else 'rad'}]", value)
                 for name, value in self.metrics().items()]  # fmt: skip
        return markdown_table(f"SimulationResult {self.label!r}", rows)

    @property
    def estimation_error(self) -> np.ndarray:
        """``tau_hat - tau_dn`` [N m]."""
        return self.tau_hat - self.tau_dn

    @property
    def position_error(self) -> np.ndarray:
        """``theta - r`` [rad]."""
        return self.theta - self.r

    def metrics(
        self, *, regulation=CANONICAL_WINDOWS["regulation"], tracking=CANONICAL_WINDOWS["tracking"]
    ) -> dict[str, float]:
        """RMS metrics of the run.

        Parameters
        ----------
        regulation, tracking : (float, float)
            Half-open windows ``[start, stop)`` [s] of the two position metrics. The defaults
            are the canonical scenario's: regulation 1.2 <= t < 4 s, tracking t >= 4 s.

        Returns
        -------
        dict
            ``rms_estimation_error`` [N m] (``tau_hat - tau_dn`` over the whole run),
            ``rms_position_error_regulation`` and ``rms_position_error_tracking`` [rad]
            (``theta - r`` in each window; NaN if the window holds no sample).
        """

        return error_metrics(self.t, self.estimation_error, self.position_error,
                             regulation=regulation, tracking=tracking)  # fmt: skip

    def contact_metrics(self, tau_ref: float | None = None) -> dict[str, float]:
        """The impact of a run against an :class:`~hpdob.Environment`.

        Parameters
        ----------
        tau_ref : float, optional
            The force reference [N m] the overshoot is measured against. Default None: the
            last sample's contact torque (the settled value of a run that settles).

        Returns
        -------
        dict
            ``first_contact`` [s] (the first sample in contact; NaN if never),
            ``impact_peak`` [N m] (the largest contact torque from then on; NaN if never),
            ``overshoot`` [N m] (``impact_peak - tau_ref``) and ``overshoot_ratio``
            (``overshoot / tau_ref``; NaN for ``tau_ref`` 0).

        Raises
        ------
        ParameterValueError
            If the run has no environment (``tau_contact`` is None) or ``tau_ref`` is not
            finite.

        Examples
        --------
        >>> import numpy as np
        >>> from hpdob import (Environment, PD, ServoLoop, ServoModel, design_observer,
        ...                    simulate)
        >>> plant = ServoModel(3.06e-4, 5e-5, environment=Environment(10.0, position=0.01))
        >>> loop = ServoLoop(plant=plant, nominal=ServoModel(2.8e-4), Ts=1e-3,
        ...                  controller=PD(400.0, 40.0))
        >>> result = simulate(loop, reference=lambda t: (0.02 + 0 * t, 0 * t, 0 * t),
        ...                   duration=1.0)
        >>> m = result.contact_metrics()
        >>> bool(m["impact_peak"] >= result.tau_contact[-1] > 0.0)
        True
        """
        if self.tau_contact is None:
            raise ParameterValueError(
                "contact_metrics needs a run against an Environment (tau_contact is None)"
            )
        contact = np.nonzero(self.in_contact > 0.0)[0]
        if tau_ref is None:
            tau_ref = float(self.tau_contact[-1]) if len(self) else math.nan
        else:
            tau_ref = as_real(tau_ref, "tau_ref", "a finite force reference [N m]")
        if contact.size == 0:
            return {"first_contact": math.nan, "impact_peak": math.nan, "overshoot": math.nan,
                    "overshoot_ratio": math.nan}  # fmt: skip
        peak = float(np.max(self.tau_contact[contact[0] :]))
        overshoot = peak - tau_ref
        return {
            "first_contact": float(self.t[contact[0]]),
            "impact_peak": peak,
            "overshoot": overshoot,
            "overshoot_ratio": overshoot / tau_ref if tau_ref != 0.0 else math.nan,
        }

    def force_metrics(self, tau_ref=None, *, window=None) -> dict[str, float]:
        """RMS errors of a force run: the reaction-torque estimate and the force tracking.

        Parameters
        ----------
        tau_ref : float or array_like, optional
            The force reference [N m] at each sample (or one value for all). Default None:
            no ``rms_force_error``.
        window : None, "steady" or (start, stop), optional
            The samples the RMS is taken over. None (default): the whole run, the approach,
            the impact and the step included. ``"steady"``: the steady state, from
            ``FORCE_SETTLING`` = 0.5 s after the first contact to the end (no sample for a
            run that never touches). ``(start, stop)`` [s]: the samples with
            ``start <= t < stop`` (``stop`` may be ``inf``).

        Returns
        -------
        dict
            ``rms_reaction_error`` [N m] (``tau_reac - tau_contact``) and, with ``tau_ref``,
            ``rms_force_error`` [N m] (``tau_contact - tau_ref``) over the window; NaN for a
            window without samples. With a ``window``, also ``window_start`` [s], where it
            starts (NaN for ``"steady"`` without contact).

        Raises
        ------
        ParameterValueError
            If the run has no environment or no reaction-torque estimate (``tau_contact``
            or ``tau_reac`` is None), ``tau_ref`` does not have one value per sample, or
            ``window`` is none of the above.

        Examples
        --------
        >>> import numpy as np
        >>> from hpdob import Environment, ServoLoop, ServoModel, design_observer, simulate
        >>> from hpdob.controllers import ForceControl
        >>> from hpdob.observers import reaction_torque_observer
        >>> nominal = ServoModel(2.8e-4)
        >>> dob = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
        >>> loop = ServoLoop(plant=ServoModel(2.8e-4, environment=Environment(10.0)),
        ...                  nominal=nominal, Ts=1e-3, observer=reaction_torque_observer(dob),
        ...                  controller=ForceControl(1000.0, kv=40.0))
        >>> result = simulate(loop, reference=lambda t: (0.05 + 0 * t, 0 * t, 0 * t),
        ...                   duration=2.0)
        >>> m = result.force_metrics(result.r)
        >>> bool(m["rms_force_error"] < 0.05 and m["rms_reaction_error"] < 0.05)
        True
        >>> steady = result.force_metrics(result.r, window="steady")
        >>> bool(steady["rms_force_error"] < m["rms_force_error"])
        True
        """
        if self.tau_contact is None or self.tau_reac is None:
            raise ParameterValueError(
                "force_metrics needs a run against an Environment with a reaction-torque "
                "observer (tau_contact or tau_reac is None)"
            )
        ref = None
        if tau_ref is not None:
            ref = np.broadcast_to(np.asarray(tau_ref, dtype=float), np.shape(self.t)) \
                if np.ndim(tau_ref) == 0 else np.asarray(tau_ref, dtype=float)  # fmt: skip
            if ref.shape != self.tau_contact.shape:
                raise ParameterValueError(
                    f"tau_ref must have one value per sample ({len(self)}), got shape {ref.shape}"
                )
        extra = {}
        if window is None:
            keep = slice(None)
        else:
            start, stop = self._force_window(window)
            keep = (self.t >= start) & (self.t < stop)
            extra["window_start"] = start
        metrics = {"rms_reaction_error": _rms((self.tau_reac - self.tau_contact)[keep])}
        if ref is not None:
            metrics["rms_force_error"] = _rms((self.tau_contact - ref)[keep])
        return {**metrics, **extra}

    def _force_window(self, window) -> tuple[float, float]:
        """``(start, stop)`` [s] of :meth:`force_metrics`'s ``window`` (not None)."""
        if isinstance(window, str):
            if window != "steady":
                raise ParameterValueError(
                    f"window must be None, 'steady' or a (start, stop) pair [s], got {window!r}"
                )
            contact = np.nonzero(self.in_contact > 0.0)[0]
            if contact.size == 0:
                return math.nan, math.nan  # no sample: NaN metrics
            return float(self.t[contact[0]]) + FORCE_SETTLING, math.inf
        return metric_window(window, "window")

    def plot_force(self, *, tau_ref=None, title: str | None = None):
        """Figure of a force run: contact torque, its estimate and the force reference.

        Parameters
        ----------
        tau_ref : float or array_like, optional
            The force reference [N m] to draw (one value or one per sample). Default None.
        title : str, optional
            The figure's title. Default: the result's label (or ``"hpdob force run"``).

        Returns
        -------
        matplotlib.figure.Figure
            Two panels sharing the time axis [s]: torques [N m] (``tau_contact``,
            ``tau_reac``, ``tau_ref``) and the estimate error ``tau_reac - tau_contact``
            [N m]; the legend above the data.

        Raises
        ------
        ParameterValueError
            If the run has no ``tau_contact`` or ``tau_reac``.
        """
        from .._plotting import plot_force_result

        self.force_metrics(tau_ref)  # the same checks
        return plot_force_result(self, tau_ref=tau_ref, title=title)

    def max_abs_position_error(self) -> float:
        """Largest position error of the run.

        Returns
        -------
        float
            ``max |theta - r|`` [rad]; NaN for an empty result.
        """
        return max_abs(self.position_error)

    # -- export -----------------------------------------------------------------------------
    def to_csv(self, path, *, progress=None) -> Path:
        """Write the traces to ``path`` as CSV (header row, full float precision).

        The file is written atomically (a temporary name in the same directory, then
        renamed): a reader never sees it half written.

        Parameters
        ----------
        path : str or os.PathLike
            The file to write (replaced if it exists).
        progress : callable, optional
            Called as ``progress(rows written, rows)`` as the file is written: after each
            chunk of 32768 rows (the rows are formatted in chunks), or once for a short
            result. Its return value is ignored. Default: silent.

        Returns
        -------
        pathlib.Path
            ``path``. Columns: ``t`` [s], ``theta``, ``omega``, ``theta_measured``,
            ``omega_measured``, ``r``, ``r_dot``, ``r_ddot``, ``u``, ``tau_hat``, ``tau_dn``,
            ``tau_ext`` (SI units), then ``omega_hat``, ``theta_load``, ``omega_load``,
            ``tau_contact``, ``in_contact``, ``tau_reac`` where the run has them.
        """
        return columns_to_csv(self._columns(), path, progress)

    @classmethod
    def from_csv(cls, path, *, label: str = "") -> SimulationResult:
        """Read traces written by :meth:`to_csv` (``Ts`` is taken from the time column).

        Parameters
        ----------
        path : str or os.PathLike
            A file written by :meth:`to_csv` (or ``hpdob simulate``/``reproduce``).
        label : str, optional
            The result's label. Default ``""``.

        Returns
        -------
        SimulationResult
            With the same traces, bit for bit.

        Raises
        ------
        ParameterValueError
            If the header is not that of an hpdob trace file.
        OSError
            If the file cannot be read.

        Examples
        --------
        >>> import tempfile
        >>> from pathlib import Path
        >>> from hpdob import SimulationResult, paper
        >>> result = paper.run("HPDOb-100", duration=1.0)
        >>> with tempfile.TemporaryDirectory() as tmp:
        ...     back = SimulationResult.from_csv(result.to_csv(Path(tmp, "run.csv")))
        >>> bool((back.tau_hat == result.tau_hat).all()), back.Ts
        (True, 0.001)
        """
        path = Path(path)
        with path.open(newline="") as handle:
            reader = csv.reader(handle)
            header = next(reader, None)
            extra = [] if header is None else header[len(COLUMNS) :]
            if (
                header is None
                or header[: len(COLUMNS)] != list(COLUMNS)
                or any(name not in OPTIONAL_COLUMNS for name in extra)
            ):
                raise ParameterValueError(
                    f"{path} does not look like an hpdob trace file: "
                    f"expected columns {list(COLUMNS)} (then any of {list(OPTIONAL_COLUMNS)}), "
                    f"got {header}"
                )
            rows = []
            for line, row in enumerate(reader, start=2):
                try:
                    if len(row) != len(header):  # e.g. a file cut off mid-row
                        raise ValueError
                    rows.append([float(v) for v in row])
                except ValueError:
                    raise ParameterValueError(
                        f"{path} line {line} is not a row of {len(header)} numbers (a truncated "
                        f"or edited trace file?): {','.join(row)[:80]!r}"
                    ) from None
        data = np.array(rows, dtype=float).reshape(-1, len(header))
        t = data[:, 0]
        Ts = float(t[1] - t[0]) if t.size > 1 else math.nan
        return cls(**{name: data[:, i] for i, name in enumerate(header)}, Ts=Ts, label=label)

    def to_pandas(self):
        """The traces as a table.

        Returns
        -------
        pandas.DataFrame
            One row per sample, the columns of :meth:`to_csv`.

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install hpdob[pandas]``).
        """
        return columns_to_pandas(self._columns(), caller="SimulationResult.to_pandas()")

    def _columns(self) -> dict:
        columns = {name: getattr(self, name) for name in COLUMNS}
        columns.update(
            (name, getattr(self, name))
            for name in OPTIONAL_COLUMNS
            if getattr(self, name) is not None
        )
        return columns

    def plot(self, *, title: str | None = None):
        """Figure with position vs reference, disturbance and estimate, and estimation error.

        Parameters
        ----------
        title : str, optional
            The figure's title. Default: the result's label (or ``"hpdob simulation"``).

        Returns
        -------
        matplotlib.figure.Figure
            Three panels sharing the time axis [s]: angle [rad], torques [N m] and the
            estimation error ``tau_hat - tau_dn`` [N m]; the legends above the data.
        """
        from .._plotting import plot_result

        return plot_result(self, title=title)


#: The optional fields of a result and their defaults; the traces and ``Ts`` are required.
_DEFAULTS = {
    f.name: f.default
    for f in dataclasses.fields(SimulationResult)
    if f.default is not dataclasses.MISSING
}
_REQUIRED_FIELDS = frozenset(f.name for f in dataclasses.fields(SimulationResult)).difference(
    _DEFAULTS
)
