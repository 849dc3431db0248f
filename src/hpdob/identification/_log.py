"""A logged run of one axis (time, position, input) and :func:`read_log` for CSV/Parquet/.mat."""

from __future__ import annotations

import os
import types
from collections.abc import Mapping
from dataclasses import KW_ONLY, dataclass, field
from pathlib import Path

import numpy as np

from .._table import columns_to_pandas
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_real,
    positive,
    readonly,
)
from ._checks import (
    DEFAULT_TIME_TOLERANCE,
    check_axis,
    check_lengths,
    check_time,
    sample_vector,
    units,
)
from ._readers import read_columns, scalar

__all__ = ["MIN_LOG_SAMPLES", "Log", "read_log", "read_logs"]

# ``identify`` is registered here by ``_identify`` when the package is imported: the data class
# does not import the algorithm that takes it (no import cycle between the two modules).
_IDENTIFY: list = []


def register_identify(function) -> None:
    """Make ``function`` the implementation of :meth:`Log.identify` (``_identify`` calls it)."""
    _IDENTIFY[:] = [function]


#: Fewest samples a :class:`Log` may hold (identification needs far more; see identify()).
MIN_LOG_SAMPLES = 10


@dataclass(frozen=True, eq=False)
class Log:
    """A logged run of one axis: sampling instants, measured position and applied input.

    A rotary axis (rad, N m, kg m^2) and a linear one (m, N, kg) obey the same equations, so
    every quantity is in the units of its axis: ``axis="rotary"``, ``"linear"`` or None
    (not stated; labels then read e.g. "position [rad or m]").

    Parameters
    ----------
    t : array_like
        Sampling instants [s], strictly increasing and uniformly spaced (each step within
        ``time_tolerance`` of the median step).
    theta : array_like
        Measured position [rad or m].
    u : array_like
        Applied torque or force [N m or N] (the controller's output times its gain).
    reference : array_like, optional
        Reference position [rad or m] of the loop that produced the log, if logged.
    source : str, optional
        Where the log came from (a file name), for reports.
    names : mapping, optional
        Column names the signals were read from (``time``, ``position``, ``input``,
        ``reference``), for reports.
    input_gain : float, optional
        The factor the logged input column was multiplied by to give ``u``. Default 1.
    axis : {"rotary", "linear"} or None, optional
    time_tolerance : float, optional
        Relative tolerance of the uniform-sampling check. Default 1e-3.
    columns : mapping, optional
        Further logged signals by name (e.g. ``reference_velocity``), one sample each.

    Attributes
    ----------
    Ts : float
        Sampling period [s], the mean step ``(t[-1] - t[0]) / (n - 1)``.

    Raises
    ------
    ParameterTypeError
        If a signal is not numeric.
    ParameterValueError
        If the signals differ in length, hold a non-finite sample (the first is named), the
        time is not strictly increasing or not uniform, or there are fewer than 10 samples.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob.identification import Log
    >>> log = Log(t=np.arange(100) * 1e-3, theta=np.zeros(100), u=np.ones(100), axis="linear")
    >>> log.Ts, len(log), log.units["position"]
    (0.001, 100, 'm')
    """

    t: np.ndarray
    theta: np.ndarray
    u: np.ndarray
    _: KW_ONLY
    reference: np.ndarray | None = None
    source: str = ""
    names: Mapping = field(default_factory=dict)
    input_gain: float = 1.0
    axis: str | None = None
    time_tolerance: float = DEFAULT_TIME_TOLERANCE
    columns: Mapping = field(default_factory=dict)
    Ts: float = field(init=False)

    def __post_init__(self) -> None:
        axis = check_axis(self.axis)
        unit = units(axis)
        signals = {
            "t": sample_vector(self.t, "t", "times [s]"),
            "theta": sample_vector(self.theta, "theta", f"positions [{unit['position']}]"),
            "u": sample_vector(self.u, "u", f"inputs [{unit['input']}]"),
        }
        if self.reference is not None:
            signals["reference"] = sample_vector(
                self.reference, "reference", f"reference positions [{unit['position']}]"
            )
        if not isinstance(self.columns, Mapping):
            raise ParameterTypeError(
                f"columns must be a mapping of names to signals, got {type(self.columns).__name__}"
            )
        extra = {str(k): sample_vector(v, f"columns[{k!r}]", "samples")
                 for k, v in self.columns.items()}  # fmt: skip
        n = check_lengths({**signals, **{f"columns[{k!r}]": v for k, v in extra.items()}})
        if n < MIN_LOG_SAMPLES:
            raise ParameterValueError(
                f"a log must hold at least {MIN_LOG_SAMPLES} samples, got {n}"
            )
        Ts = check_time(signals["t"], "t", self.time_tolerance)
        if not isinstance(self.source, str):
            raise ParameterTypeError(f"source must be a str, got {type(self.source).__name__}")
        if not isinstance(self.names, Mapping):
            raise ParameterTypeError(
                f"names must be a mapping of roles to column names, got {self.names!r}"
            )
        gain = as_real(self.input_gain, "input_gain", "a finite non-zero gain")
        if gain == 0.0:
            raise ParameterValueError("input_gain must be a finite non-zero gain, got 0.0")
        for name, array in signals.items():
            object.__setattr__(self, name, readonly(array))
        object.__setattr__(self, "names", types.MappingProxyType(dict(self.names)))
        object.__setattr__(
            self, "columns", types.MappingProxyType({k: readonly(v) for k, v in extra.items()})
        )
        object.__setattr__(self, "input_gain", gain)
        object.__setattr__(self, "time_tolerance", float(self.time_tolerance))
        object.__setattr__(self, "Ts", Ts)

    def __len__(self) -> int:
        return self.t.size

    @property
    def units(self) -> dict:
        """Unit of each quantity on this log's axis (neutral "rad or m" if not stated)."""
        return dict(units(self.axis))

    def to_pandas(self):
        """The signals as a table.

        Returns
        -------
        pandas.DataFrame
            Columns ``t`` [s], ``theta``, ``u`` and ``reference`` (if the log has one), in the
            log's units.

        Raises
        ------
        ImportError
            If pandas is not installed (``pip install hpdob[pandas]``).
        """
        columns = {"t": self.t, "theta": self.theta, "u": self.u}
        if self.reference is not None:
            columns["reference"] = self.reference
        return columns_to_pandas(columns, caller="Log.to_pandas()")

    def identify(self, **options):
        """:func:`hpdob.identify` on this log (``axis`` and ``time_tolerance`` carried over).

        Parameters
        ----------
        **options
            Keyword arguments of :func:`hpdob.identify` (``method``, ``loop``, filters, ...);
            the log's ``axis`` is the default.

        Returns
        -------
        Identification

        Raises
        ------
        ParameterTypeError, ParameterValueError
            As :func:`hpdob.identify`.

        Examples
        --------
        >>> from hpdob.identification import EMPS_PUBLISHED, EMPS_PUBLISHED_STD, emps
        >>> fit = emps().identify(method="idim-ls")   # as the benchmark's reference script
        >>> all(abs(fit.parameters[k] - EMPS_PUBLISHED[k]) < EMPS_PUBLISHED_STD[k]
        ...     for k in EMPS_PUBLISHED)   # within one published standard deviation
        True
        """
        return _IDENTIFY[0](self, **options)

    def slice(self, start: float | None = None, stop: float | None = None) -> Log:
        """The samples with ``start <= t < stop`` [s] as a new log (e.g. to identify on one
        part and validate on another).

        Parameters
        ----------
        start, stop : float or None
            Bounds [s]; None for the log's first or last sample.

        Returns
        -------
        Log
            The same columns, ``reference`` included, and the same metadata; ``source``
            gains the interval kept, e.g. ``"run.csv (t 0 to 12.4 s)"``.

        Raises
        ------
        ParameterValueError
            If fewer than 10 samples fall in the interval.

        Examples
        --------
        >>> import numpy as np
        >>> from hpdob.identification import Log
        >>> log = Log(t=np.arange(100) * 1e-3, theta=np.zeros(100), u=np.ones(100))
        >>> len(log.slice(0.02, 0.05)), float(log.slice(0.02, 0.05).t[0])
        (30, 0.02)
        """
        lo = -np.inf if start is None else as_real(start, "start", "a time [s] or None")
        hi = np.inf if stop is None else as_real(stop, "stop", "a time [s] or None")
        keep = (self.t >= lo - 1e-9 * self.Ts) & (self.t < hi - 1e-9 * self.Ts)
        if np.count_nonzero(keep) < MIN_LOG_SAMPLES:
            raise ParameterValueError(
                f"log.slice({start!r}, {stop!r}) keeps {np.count_nonzero(keep)} samples of "
                f"t = {self.t[0]:g} .. {self.t[-1]:g} s; a log needs at least {MIN_LOG_SAMPLES}"
            )
        return Log(
            self.t[keep],
            self.theta[keep],
            self.u[keep],
            reference=None if self.reference is None else self.reference[keep],
            source=f"{self.source or 'log'} (t {self.t[keep][0]:g} to {self.t[keep][-1]:g} s)",
            names=self.names,
            input_gain=self.input_gain,
            axis=self.axis,
            time_tolerance=self.time_tolerance,
            columns={name: values[keep] for name, values in self.columns.items()},
        )


def _name(value, role: str, *, optional: bool = False) -> str | None:
    if value is None and optional:
        return None
    if not isinstance(value, str) or not value:
        raise ParameterTypeError(
            f"{role} must be the name of a column or variable of the log (a non-empty str), "
            f"got {value!r}"
        )
    return value


#: Largest log file [bytes], checked before it is read (a 900 MB CSV of 10 million rows took
#: 241 s and 1.4 GB of memory).
MAX_LOG_BYTES = 1 << 28


def read_log(
    path,
    *,
    time: str | None = None,
    position: str,
    input: str,
    input_gain: float | str = 1.0,
    reference: str | None = None,
    Ts: float | None = None,
    axis: str | None = None,
    time_tolerance: float = DEFAULT_TIME_TOLERANCE,
    columns: Mapping | None = None,
    progress=None,
) -> Log:
    """Read a logged run from a CSV, Parquet or MATLAB ``.mat`` file by column names.

    The format follows the file name: ``.csv``/``.txt``/``.tsv`` (a header row of column
    names; comma, semicolon or tab separated), ``.parquet``/``.pq`` (needs pyarrow) or
    ``.mat`` (MATLAB up to v7, read with :func:`scipy.io.loadmat`; vectors may be rows or
    columns).

    Parameters
    ----------
    path : str or path-like
    time : str, optional
        Column of the sampling instants [s]. Without one, give ``Ts``.
    position : str
        Column of the measured position [rad or m].
    input : str
        Column of the logged input; ``u = input_gain * column`` is the torque or force
        [N m or N].
    input_gain : float or str, optional
        Factor from the logged input to torque/force (e.g. 35.15 N/V for a voltage command),
        or the name of a scalar variable of the file holding it (e.g. ``"gtau"``). Default 1.
    reference : str, optional
        Column of the reference position [rad or m] (needed by ``method="idim-iv"``).
    Ts : float, optional
        Sampling period [s] of a log without a time column; samples are at ``k Ts``.
    axis : {"rotary", "linear"} or None, optional
        Units of the log (rad and N m, or m and N); None leaves them unstated.
    time_tolerance : float, optional
        Relative tolerance of the uniform-sampling check of the time column (1e-3).
    columns : mapping, optional
        Further columns to read, ``{name: column}`` (e.g. ``{"reference_velocity":
        "rdot"}``); the log's ``columns`` holds them.
    progress : callable, optional
        Called as ``progress(done, total)`` with the bytes of the file read so far and its
        size: every MiB of a CSV file (counted in characters, the bytes of an ASCII file),
        at the start and the end of a Parquet or MAT file. It sees counts only; a display
        with the time left is the caller's (``hpdob estimate --progress``).

    Returns
    -------
    Log

    Raises
    ------
    ParameterValueError
        If the format is unknown, a column is missing (the message lists the available
        ones), the columns differ in length, a sample is not numeric or not finite (the
        column and first bad index are named), the time is not strictly increasing or not
        uniform, or the log is too short.
    ParameterTypeError
        For arguments of the wrong type.

    Examples
    --------
    The EMPS benchmark's measured run (shipped with hpdob; ``emps()`` does the same):

    >>> from hpdob.identification import EMPS_FILE, read_log
    >>> log = read_log(EMPS_FILE, time="t", position="qm", input="vir", input_gain="gtau",
    ...                reference="qg", axis="linear")
    >>> len(log), log.Ts, round(log.input_gain, 2)
    (24841, 0.001, 35.15)
    """
    logs = _read(path, time=time, position=position, input=input, input_gain=input_gain,
                 reference=reference, Ts=Ts, axis=axis, time_tolerance=time_tolerance,
                 run=None, columns=columns, progress=progress)  # fmt: skip
    return logs[0]


def read_logs(
    path,
    *,
    run: str,
    time: str | None = None,
    position: str,
    input: str,
    input_gain: float | str = 1.0,
    reference: str | None = None,
    Ts: float | None = None,
    axis: str | None = None,
    time_tolerance: float = DEFAULT_TIME_TOLERANCE,
    columns: Mapping | None = None,
    progress=None,
) -> list[Log]:
    r"""Read several runs from one file: a column ``run`` tells which run each row belongs to.

    Parameters
    ----------
    path : str or path-like
        A CSV, Parquet or MATLAB ``.mat`` file (see :func:`read_log`).
    run : str
        Column of the run each row belongs to (numbers; rows of one run need not be
        contiguous but keep their order). Each run's time must increase uniformly; it may
        restart from 0.
    time, position, input, input_gain, reference, Ts, axis, time_tolerance, columns, progress
        As :func:`read_log` (``progress`` counts the bytes of the whole file).

    Returns
    -------
    list of Log
        One per run, in the order the runs first appear; ``source`` is
        ``"<file> run <value>"``.

    Raises
    ------
    ParameterValueError
        As :func:`read_log`, naming the run; or if a run has fewer than 10 samples.
    ParameterTypeError
        For arguments of the wrong type.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from hpdob.identification import read_logs
    >>> t = np.arange(20) * 1e-3
    >>> rows = ["run,t,q,u"] + [f"{r},{x},{np.sin(x)},{np.cos(x)}" for r in (1, 2) for x in t]
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "runs.csv"
    >>> _ = path.write_text("\n".join(rows))
    >>> [(log.source, len(log)) for log in read_logs(path, run="run", time="t", position="q",
    ...                                              input="u")]
    [('runs.csv run 1', 20), ('runs.csv run 2', 20)]
    """
    return _read(path, time=time, position=position, input=input, input_gain=input_gain,
                 reference=reference, Ts=Ts, axis=axis, time_tolerance=time_tolerance,
                 run=_name(run, "run"), columns=columns, progress=progress)  # fmt: skip


def _read(path, *, time, position, input, input_gain, reference, Ts, axis, time_tolerance, run,
          columns, progress=None):  # fmt: skip
    """The logs of a file: one, or one per value of the ``run`` column."""
    if progress is not None and not callable(progress):
        raise ParameterTypeError(
            f"progress must be a callable progress(done, total), got {progress!r}"
        )
    path, wanted, input_gain, axis = _request(path, time=time, position=position, input=input,
                                              input_gain=input_gain, reference=reference, Ts=Ts,
                                              axis=axis, run=run, columns=columns)  # fmt: skip
    if path.is_file() and path.stat().st_size > MAX_LOG_BYTES:  # checked before reading
        raise ParameterValueError(
            f"log {str(path)!r} has {path.stat().st_size} bytes; at most {MAX_LOG_BYTES} bytes "
            f"(256 MiB, some 5 million CSV rows) are read: decimate or split the log"
        )
    data = read_columns(path, wanted, progress)
    if "input_gain" in wanted:
        input_gain = scalar(data.pop("input_gain"), "input_gain", wanted.pop("input_gain"), path)
    gain = as_real(input_gain, "input_gain", "a finite non-zero gain")
    what = signal_kinds(axis)
    signals = {
        role: sample_vector(data[role], f"{role} column {name!r}", what.get(role, "samples"))
        for role, name in wanted.items()
    }
    check_lengths({f"{role} {wanted[role]!r}": values for role, values in signals.items()})
    del data
    runs = signals.pop("run", None)
    if runs is None:
        return [_build(signals, None, path, wanted, time, Ts, gain, axis, time_tolerance)]
    values = run_values(runs)
    # split column by column, each column of the file let go once split: the file's columns
    # and their runs' copies are not all held at once
    parts = [{} for _ in values]
    for role in list(signals):
        column = signals.pop(role)
        for part, value in zip(parts, values, strict=True):
            part[role] = column[runs == value]
        del column
    return [_build(part, value, path, wanted, time, Ts, gain, axis, time_tolerance)
            for part, value in zip(parts, values, strict=True)]  # fmt: skip


def run_values(runs: np.ndarray) -> list:
    """The values of a run column in the order they first appear: ``list(dict.fromkeys(
    runs.tolist()))`` (``-0.0`` and ``0.0`` one run, named by the first), block by block
    instead of a Python float per row."""
    first: dict = {}
    for lo in range(0, runs.size, _RUN_BLOCK):
        block = runs[lo : lo + _RUN_BLOCK]
        _, index = np.unique(block, return_index=True)  # first occurrences, stably sorted
        for i in index.tolist():
            first.setdefault(float(block[i]), lo + i)
    return sorted(first, key=first.__getitem__)


#: Rows of a run column looked at a time by :func:`run_values`.
_RUN_BLOCK = 1 << 16


def signal_kinds(axis) -> dict:
    """What each role's samples are, for messages (``"positions [m]"``)."""
    unit = units(axis)
    return {
        "time": "times [s]",
        "position": f"positions [{unit['position']}]",
        "input": "logged inputs",
        "reference": f"reference positions [{unit['position']}]",
        "run": "run numbers",
    }


def _request(path, *, time, position, input, input_gain, reference, Ts, axis, run, columns):
    """The checked arguments of a read: ``(path, {role: column}, input_gain, axis)``; a gain
    given as a variable's name is in the mapping as ``"input_gain"``."""
    if not isinstance(path, (str, os.PathLike)):
        raise ParameterTypeError(
            f"path must be a file path (str or os.PathLike), got {path!r} of type "
            f"{type(path).__name__}"
        )
    path = Path(path)
    wanted = {"position": _name(position, "position"), "input": _name(input, "input")}
    if _name(time, "time", optional=True) is not None:
        wanted["time"] = time
    if _name(reference, "reference", optional=True) is not None:
        wanted["reference"] = reference
    if run is not None:
        wanted["run"] = run
    if columns is not None:
        if not isinstance(columns, Mapping):
            raise ParameterTypeError(
                f"columns must be a mapping of names to columns, got {columns!r}"
            )
        for key, name in columns.items():
            wanted[f"column {key}"] = _name(name, f"columns[{key!r}]")
    if isinstance(input_gain, str):
        wanted["input_gain"] = input_gain
    elif isinstance(input_gain, (bool, np.bool_)) or not isinstance(input_gain, (int, float)):
        raise ParameterTypeError(
            f"input_gain must be a number or the name of a scalar variable, got {input_gain!r}"
        )
    if (time is None) == (Ts is None):
        raise ParameterValueError(
            "give the sampling instants as time='column' or, for a log without a time "
            f"column, the sampling period as Ts=...; got time={time!r} and Ts={Ts!r}"
        )
    return path, wanted, input_gain, check_axis(axis)


def _build(signals, run, path, wanted, time, Ts, gain, axis, time_tolerance) -> Log:
    """One :class:`Log` from validated columns (one run of the file, or all of it)."""
    label = "" if run is None else f" run {run:g}"
    n = signals["position"].size
    if run is not None and n < MIN_LOG_SAMPLES:
        raise ParameterValueError(
            f"{path.name}{label} has {n} samples; a log needs at least {MIN_LOG_SAMPLES}"
        )
    if "time" in signals:
        t = signals["time"]
        check_time(t, f"time column {time!r}{label}", time_tolerance)
    else:
        Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
        t = readonly(np.arange(n) * Ts)
    u = signals["input"] if gain == 1.0 else readonly(gain * signals["input"])
    if not np.all(np.isfinite(u)):  # pragma: no cover - only for gains near the float limit
        raise ParameterValueError(f"input_gain {gain!r} makes the input overflow")
    return Log(
        t=t,
        theta=signals["position"],
        u=u,
        reference=signals.get("reference"),
        source=path.name + label,
        names={role: wanted.get(role) for role in ("time", "position", "input", "reference")},
        input_gain=gain,
        axis=axis,
        time_tolerance=time_tolerance,
        columns={role[7:]: v for role, v in signals.items() if role.startswith("column ")},
    )
