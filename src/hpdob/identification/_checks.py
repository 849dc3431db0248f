"""Checks of logged samples shared by :class:`Log` and :func:`identify`.

Every message names the signal, the first offending index and what was expected.
"""

from __future__ import annotations

import numpy as np

from .._validation import ParameterValueError, numeric_array, positive

__all__ = [
    "DEFAULT_TIME_TOLERANCE",
    "UNITS",
    "check_axis",
    "check_lengths",
    "check_time",
    "immutable",
    "non_finite",
    "sample_vector",
    "sample_view",
    "shareable",
    "uniform_steps",
    "units",
]

#: Largest relative deviation of one time step from the median step that still counts as
#: uniform sampling. Logged clocks jitter by rounding: the steps of the EMPS time vector deviate
#: by up to 2.4e-5 relative.
DEFAULT_TIME_TOLERANCE = 1e-3

#: Units of every quantity for a rotary and a linear axis; ``None`` (axis not stated) gives
#: neutral labels that fit both.
UNITS = {
    "rotary": {
        "position": "rad",
        "velocity": "rad/s",
        "acceleration": "rad/s^2",
        "input": "N m",
        "J": "kg m^2",
        "b": "N m s/rad",
        "coulomb": "N m",
        "offset": "N m",
        "kp": "N m/rad",
        "kd": "N m s/rad",
    },
    "linear": {
        "position": "m",
        "velocity": "m/s",
        "acceleration": "m/s^2",
        "input": "N",
        "J": "kg",
        "b": "N s/m",
        "coulomb": "N",
        "offset": "N",
        "kp": "N/m",
        "kd": "N s/m",
    },
}
UNITS[None] = {key: f"{UNITS['rotary'][key]} or {UNITS['linear'][key]}" for key in UNITS["rotary"]}

AXES = ("rotary", "linear")


def check_axis(axis) -> str | None:
    """``axis`` if it is ``"rotary"``, ``"linear"`` or None (not stated)."""
    if axis is not None and axis not in AXES:
        raise ParameterValueError(f"axis must be 'rotary', 'linear' or None; got {axis!r}")
    return axis


def units(axis) -> dict:
    """The unit of each quantity for ``axis`` (see :data:`UNITS`)."""
    return UNITS[check_axis(axis)]


def immutable(array) -> bool:
    """Whether ``array``'s values cannot change: it is read-only, and so is every array it is a
    view of, down to memory it owns or an immutable buffer (pyarrow's, ``bytes``).

    Such an array (a column of a :class:`Log`, of a result, or read from a Parquet file) is
    shared instead of copied: a log of 1e7 samples is not held twice. (Setting it writeable
    again, which numpy allows the owner of the memory, breaks that promise.)
    """
    while isinstance(array, np.ndarray):
        if array.flags.writeable:
            return False
        if array.base is None:
            return True
        array = array.base
    return isinstance(array, bytes) or type(array).__module__.split(".")[0] == "pyarrow"


def shareable(values) -> bool:
    """Whether ``values`` is an :func:`immutable` float64 ndarray, which a result or a log may
    hold as it is instead of a copy."""
    return type(values) is np.ndarray and values.dtype == np.float64 and immutable(values)


def sample_vector(values, name: str, what: str) -> np.ndarray:
    """``values`` as a new 1-D float array of finite samples (an :func:`immutable` float64
    vector is returned as it is: nobody can change it).

    Raises
    ------
    ParameterTypeError
        If ``values`` is not numeric (strings, booleans, objects).
    ParameterValueError
        If it is not 1-D or holds a NaN or infinite sample (the first one is named).
    """
    array = values if shareable(values) else numeric_array(values, name, what)
    if array.ndim == 2 and 1 in array.shape:  # a MATLAB column or row vector
        array = array.ravel()
    if array.ndim != 1:
        raise ParameterValueError(f"{name} must be {what}: a 1-D sequence, got shape {array.shape}")
    bad = np.flatnonzero(~np.isfinite(array))
    if bad.size:
        non_finite(name, what, float(array[bad[0]]), int(bad[0]), bad.size)
    return array


def non_finite(name: str, what: str, value: float, index: int, count: int):
    """Raise the error of a signal ``name`` whose first non-finite sample is ``value`` at
    ``index``, of ``count`` non-finite samples."""
    raise ParameterValueError(
        f"{name} has a non-finite sample {value!r} at index {index} "
        f"({count} non-finite in all); every sample of {what} must be finite"
    )


def sample_view(values, name: str, what: str) -> np.ndarray:
    """``values`` as a 1-D float array of finite samples, as :func:`sample_vector` checks it,
    but not copied if it already is one (a 1-D float64 ndarray): the caller copies it.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        As :func:`sample_vector`.
    """
    if (
        type(values) is np.ndarray
        and values.dtype == np.float64
        and values.ndim == 1
        and np.isfinite(values).all()
    ):
        return values
    return sample_vector(values, name, what)


def check_lengths(arrays: dict) -> int:
    """The common length of ``{name: array}``; otherwise an error listing every length."""
    lengths = {name: len(array) for name, array in arrays.items()}
    if len(set(lengths.values())) > 1:
        listed = ", ".join(f"{name} has {n}" for name, n in lengths.items())
        raise ParameterValueError(f"the signals must have the same number of samples: {listed}")
    return next(iter(lengths.values()))


def check_time(t: np.ndarray, name: str = "t", tolerance: float = DEFAULT_TIME_TOLERANCE):
    """Sampling period [s] of strictly increasing, uniformly spaced times ``t``.

    Uniform means every step is within ``tolerance`` (relative) of the median step. The
    period returned is the mean step ``(t[-1] - t[0]) / (n - 1)``.
    """
    tolerance = positive(tolerance, "time_tolerance", "a positive relative tolerance")
    if t.size < 2:
        raise ParameterValueError(f"{name} must hold at least 2 samples, got {t.size}")
    low, high = np.inf, -np.inf  # the smallest and largest step, a block at a time
    for lo in range(0, t.size - 1, STEP_BLOCK):
        steps = np.diff(t[lo : lo + STEP_BLOCK + 1])
        low, high = min(low, float(steps.min())), max(high, float(steps.max()))
    if not (_within_half(low, high, tolerance) or _uniform(np.diff(t), low, high, tolerance)):
        _time_error(t, name, tolerance)
    return float((t[-1] - t[0]) / (t.size - 1))


#: Steps of the times taken at a time by :func:`check_time` (0.5 MB of float64).
STEP_BLOCK = 1 << 16


def _within_half(low: float, high: float, tolerance: float) -> bool:
    """Whether steps from ``low`` to ``high`` pass :func:`uniform_steps`'s rule for certain,
    without their median: the median lies between them, so every step is within
    ``(high - low) / low`` of it; half the tolerance leaves the rule's rounding far away."""
    return low > 0.0 and high - low <= 0.5 * tolerance * low


def uniform_steps(steps: np.ndarray, tolerance: float) -> bool:
    """Whether the time ``steps`` are all positive and within ``tolerance`` (relative) of their
    median (:func:`check_time`'s rule); ``steps`` is partitioned in place.

    One array of steps and no other temporaries (logs reach 1e7 samples): the largest deviation
    from the median is at the smallest or the largest step; the index of a bad step is looked
    up again from the times when the error is raised. Steps that spread by less than half the
    tolerance pass without the median (the same answer, for a uniform log a tenth the time).
    """
    return _uniform(steps, float(steps.min()), float(steps.max()), tolerance)


def _uniform(steps: np.ndarray, low: float, high: float, tolerance: float) -> bool:
    """:func:`uniform_steps` of ``steps`` whose smallest and largest are ``low`` and ``high``
    (:func:`check_time` has found them block by block)."""
    if low <= 0.0:
        return False
    if _within_half(low, high, tolerance):
        return True
    median = float(np.median(steps, overwrite_input=True))
    return max(high - median, median - low) / median <= tolerance


def _time_error(t: np.ndarray, name: str, tolerance: float):
    """Raise the error of :func:`check_time` for times that are not uniform."""
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        raise ParameterValueError(
            f"{name} must increase strictly (time [s]), but {name}[{i}] = {float(t[i])!r} s is not "
            f"after {name}[{i - 1}] = {float(t[i - 1])!r} s"
        )
    median = float(np.median(steps))
    deviation = np.abs(steps - median) / median
    worst = int(np.argmax(deviation))
    raise ParameterValueError(
        f"{name} must be uniformly sampled: the step {name}[{worst + 1}] - {name}[{worst}] "
        f"= {steps[worst]:.6g} s differs from the median step {median:.6g} s by "
        f"{100 * deviation[worst]:.3g} % (tolerance {100 * tolerance:.3g} %); resample the "
        "log on a uniform grid first"
    )
