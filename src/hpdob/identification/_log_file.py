"""A logged run read a block at a time: :func:`open_log` checks a file as :func:`read_log` does
and then hands out its samples block by block, so a long Parquet log is never held whole."""

from __future__ import annotations

import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._validation import ParameterValueError, as_real, positive, readonly
from ._checks import DEFAULT_TIME_TOLERANCE, check_time, non_finite, uniform_steps, units
from ._log import MIN_LOG_SAMPLES, Log, _request, read_log, signal_kinds
from ._readers import FORMATS, parquet_blocks, parquet_rows, read_columns, scalar

__all__ = ["BLOCK", "LogFile", "open_log"]

#: Samples per block of a log held in memory (a Parquet file's blocks are its row groups).
BLOCK = 1 << 20


@dataclass(frozen=True, eq=False)
class LogFile:
    """A checked log file whose samples are read a block at a time (see :func:`open_log`).

    Attributes
    ----------
    n : int
        Number of samples (``len(log)``).
    Ts : float
        Sampling period [s], the mean step ``(t[-1] - t[0]) / (n - 1)`` as for a :class:`Log`.
    t_first, t_last : float
        The first and last sampling instants [s].
    source : str
        The file's name.
    names : mapping
        The columns read (``time``, ``position``, ``input``; ``reference`` None).
    input_gain : float
        The factor the input column is multiplied by.
    axis : str or None
        ``"rotary"``, ``"linear"`` or None (units not stated).
    time_tolerance : float
        Relative tolerance of the uniform-sampling check.
    """

    n: int
    Ts: float
    t_first: float
    t_last: float
    source: str
    names: Mapping
    input_gain: float
    axis: str | None
    time_tolerance: float
    _read: object = field(repr=False)  # () -> iterator of {role: float64 block}
    _log: Log | None = field(default=None, repr=False)  # the whole log, if it was read whole

    def __len__(self) -> int:
        return self.n

    @property
    def units(self) -> dict:
        """Unit of each quantity on this log's axis (neutral "rad or m" if not stated)."""
        return dict(units(self.axis))

    def blocks(self):
        """The samples, a block at a time, in order.

        Yields
        ------
        tuple of ndarray
            ``(t, theta, u)`` of consecutive samples (read-only float64): the values a
            :class:`Log` of the whole file holds, ``u`` including ``input_gain``.
        """
        if self._log is not None:
            yield from log_blocks(self._log)
            return
        start = 0
        for block in self._read():
            theta, logged = block["position"], block["input"]
            stop = start + theta.size
            t = block["time"] if "time" in block else np.arange(start, stop) * self.Ts
            u = logged if self.input_gain == 1.0 else self.input_gain * logged
            start = stop
            yield readonly(t), readonly(theta), readonly(u)

    def read(self) -> Log:
        """The whole log in memory.

        Returns
        -------
        Log
        """
        if self._log is not None:
            return self._log
        t, theta, u = (np.concatenate(parts) for parts in zip(*self.blocks(), strict=True))
        return Log(t, theta, u, source=self.source, names=self.names,
                   input_gain=self.input_gain, axis=self.axis,
                   time_tolerance=self.time_tolerance)  # fmt: skip


def log_blocks(log: Log, size: int | None = None):
    """``(t, theta, u)`` of a :class:`Log` in blocks of ``size`` samples (views; default
    :data:`BLOCK`, read when called)."""
    size = BLOCK if size is None else size
    for start in range(0, len(log), size):
        stop = start + size
        yield log.t[start:stop], log.theta[start:stop], log.u[start:stop]


def open_log(
    path,
    *,
    time: str | None = None,
    position: str,
    input: str,
    input_gain: float | str = 1.0,
    Ts: float | None = None,
    axis: str | None = None,
    time_tolerance: float = DEFAULT_TIME_TOLERANCE,
) -> LogFile:
    """Check a logged run in a file as :func:`read_log` does; read its samples block by block.

    A Parquet file is read a row group at a time, twice (once to check it, once per
    :meth:`LogFile.blocks`), so a log of 1e7 samples is never held whole (the uniform-time check
    holds its time steps for a moment); CSV and MATLAB files are read whole by
    :func:`read_log`, and their blocks are views of it.

    Parameters
    ----------
    path : str or path-like
        A CSV, Parquet or MATLAB ``.mat`` file (see :func:`read_log`).
    time, position, input, input_gain, Ts, axis, time_tolerance
        As :func:`read_log`.

    Returns
    -------
    LogFile
        ``len()``, ``Ts``, ``t_first``, ``t_last`` and the file's metadata; ``blocks()``
        yields ``(t, theta, u)``, the values :func:`read_log` gives.

    Raises
    ------
    ParameterValueError
        As :func:`read_log`, with the same messages (the first bad sample of a column is
        named with its index in the whole file).
    ParameterTypeError
        For arguments of the wrong type.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> import pyarrow as pa, pyarrow.parquet as pq
    >>> from hpdob.identification import open_log
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "run.parquet"
    >>> t = np.arange(5000) * 1e-3
    >>> pq.write_table(pa.table({"t": t, "q": np.sin(t), "u": np.cos(t)}), path,
    ...                row_group_size=2000)
    >>> log = open_log(path, time="t", position="q", input="u")
    >>> len(log), log.Ts, [len(theta) for _, theta, _ in log.blocks()]
    (5000, 0.001, [2000, 2000, 1000])
    """
    path, wanted, gain, axis = _request(path, time=time, position=position, input=input,
                                        input_gain=input_gain, reference=None, Ts=Ts, axis=axis,
                                        run=None, columns=None)  # fmt: skip
    if FORMATS.get(path.suffix.lower()) != "parquet" or not path.is_file():
        log = read_log(path, time=time, position=position, input=input, input_gain=input_gain,
                       Ts=Ts, axis=axis, time_tolerance=time_tolerance)  # fmt: skip
        return LogFile(n=len(log), Ts=log.Ts, t_first=float(log.t[0]), t_last=float(log.t[-1]),
                       source=log.source, names=log.names, input_gain=log.input_gain,
                       axis=log.axis, time_tolerance=log.time_tolerance, _read=None,
                       _log=log)  # fmt: skip
    tolerance = positive(time_tolerance, "time_tolerance", "a positive relative tolerance")
    if "input_gain" in wanted:
        name = wanted.pop("input_gain")
        gain = scalar(read_columns(path, {"input_gain": name})["input_gain"], "input_gain",
                      name, path)  # fmt: skip
    gain = as_real(gain, "input_gain", "a finite non-zero gain")
    if gain == 0.0:
        raise ParameterValueError("input_gain must be a finite non-zero gain, got 0.0")
    n = parquet_rows(path, wanted)

    def read():
        return parquet_blocks(path, wanted)

    t_first, t_last, Ts = _check(path, read, wanted, n, gain, axis, Ts, tolerance)
    return LogFile(n=n, Ts=Ts, t_first=t_first, t_last=t_last, source=path.name,
                   names=types.MappingProxyType({role: wanted.get(role) for role in
                                                 ("time", "position", "input", "reference")}),
                   input_gain=gain, axis=axis, time_tolerance=tolerance, _read=read)  # fmt: skip


def _check(path: Path, read, wanted: dict, n: int, gain: float, axis, Ts, tolerance: float):
    """One pass over the file's blocks with :func:`read_log`'s checks, in its order: every
    column's samples finite, the time strictly increasing and uniform, the scaled input finite,
    at least 10 samples. Returns ``(t_first, t_last, Ts)``."""
    what = signal_kinds(axis)
    first: dict = {}  # role -> (index, value) of its first non-finite sample
    count = dict.fromkeys(wanted, 0)
    steps = np.empty(max(n - 1, 0)) if "time" in wanted else None
    overflow = False
    start, previous, t_first = 0, None, None
    for block in read():
        size = next(iter(block.values())).size
        for role, values in block.items():
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                count[role] += bad.size
                first.setdefault(role, (start + int(bad[0]), float(values[bad[0]])))
        if steps is not None and size:
            t = block["time"]  # the steps of np.diff(t), block by block
            if previous is None:
                t_first = float(t[0])
            else:
                steps[start - 1] = t[0] - previous
            np.subtract(t[1:], t[:-1], out=steps[start : start + size - 1])
            previous = t[-1]
        if gain != 1.0 and not first:
            overflow = overflow or not np.all(np.isfinite(gain * block["input"]))
        start += size
    for role, name in wanted.items():
        if role in first:
            index, value = first[role]
            non_finite(f"{role} column {name!r}", what.get(role, "samples"), value, index,
                       count[role])  # fmt: skip
    if steps is not None:
        label = f"time column {wanted['time']!r}"
        if n < 2:
            raise ParameterValueError(f"{label} must hold at least 2 samples, got {n}")
        if not uniform_steps(steps, tolerance):
            del steps
            check_time(read_log_time(read), label, tolerance)  # raises the exact message
        t_last = float(previous)
    else:
        Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
        t_first, t_last = 0.0, (n - 1) * Ts  # np.arange(n) * Ts
    Ts = (t_last - t_first) / (n - 1) if n > 1 else Ts  # as check_time gives it
    if overflow:  # pragma: no cover - only for gains near the float limit
        raise ParameterValueError(f"input_gain {gain!r} makes the input overflow")
    if n < MIN_LOG_SAMPLES:
        raise ParameterValueError(f"a log must hold at least {MIN_LOG_SAMPLES} samples, got {n}")
    return t_first, t_last, Ts


def read_log_time(read) -> np.ndarray:
    """The whole time column (only to word the error of a non-uniform one)."""
    return np.concatenate([block["time"] for block in read()])
