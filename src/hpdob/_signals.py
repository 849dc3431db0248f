r"""Composable time signals for references and disturbances.

Every signal is an immutable, vectorised function of time: ``signal(t)`` returns the value at an
array of times [s] and ``signal.derivative(t, n)`` its ``n``-th time derivative. Signals add
(``a + b``), scale (``2.0 * a``) and negate. A disturbance is any signal (or any callable of an
array of times); a reference for :func:`hpdob.simulate` is a signal wrapped by
:func:`trajectory`, which returns ``(r, r_dot, r_ddot)``. The sine, chirp and noise signals
are in ``_waveforms.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    as_real,
    numeric_array,
)

__all__ = [
    "Constant",
    "Ramp",
    "Signal",
    "SmoothStep",
    "Step",
    "Sum",
    "trajectory",
]


def _times(t) -> np.ndarray:
    if type(t) is np.ndarray and t.dtype == np.float64:
        return t
    return numeric_array(t, "t", "times [s] (a number or an array of numbers)", dtype=float)


def _check_derivative(n) -> int:
    return as_int(n, "n", "a non-negative integer derivative order", minimum=0)


class Signal:
    """Base class: a deterministic, vectorised function of time.

    Subclasses implement :meth:`derivative`; ``signal(t)`` is ``signal.derivative(t, 0)``.
    """

    def __call__(self, t) -> np.ndarray:
        return self.derivative(t, 0)

    def derivative(self, t, n: int = 0) -> np.ndarray:  # pragma: no cover - abstract
        """The ``n``-th time derivative of the signal at the times ``t``.

        Parameters
        ----------
        t : float or array_like
            Times [s].
        n : int, optional
            Derivative order, ``n >= 0``; 0 (the default) is the value itself. A step's
            derivatives are taken as 0; :class:`Noise` has none (only ``n = 0``).

        Returns
        -------
        ndarray
            Values in the signal's unit per ``s^n``, the shape of ``t``.

        Raises
        ------
        ParameterTypeError, ParameterValueError
            If ``t`` is not numeric or ``n`` is not a non-negative integer (for
            :class:`Noise`: not 0).

        Examples
        --------
        >>> from hpdob.signals import Sine
        >>> s = Sine(2.0, 0.5)          # 2 sin(2 pi 0.5 t) = 2 sin(pi t)
        >>> s.derivative([0.0, 1.0], 1)  # 2 pi cos(pi t)
        array([ 6.28318531, -6.28318531])
        """
        raise NotImplementedError

    def _silent_before(self, n: int) -> float:
        """A time [s] before which ``derivative(t, n)`` is exactly 0 (of either sign) and
        raises nothing, for a valid ``n``; ``-inf`` if none is known (the default: a
        subclass that does not say is always evaluated). :class:`Sum` skips such terms."""
        return -math.inf

    def __add__(self, other):
        if not isinstance(other, Signal):
            return NotImplemented
        return Sum((*_weighted(self), *_weighted(other)))

    def __mul__(self, factor):
        if isinstance(factor, Signal) or not isinstance(factor, (int, float, np.number)):
            return NotImplemented
        factor = as_real(factor, "factor", "a finite real factor")
        return Sum(tuple((w * factor, s) for w, s in _weighted(self)))

    __rmul__ = __mul__

    def __neg__(self):
        return self * -1.0

    def __sub__(self, other):
        if not isinstance(other, Signal):
            return NotImplemented
        return self + (-other)


def _weighted(signal: Signal) -> tuple:
    if isinstance(signal, Sum):
        return signal.terms
    return ((1.0, signal),)


@dataclass(frozen=True, eq=True)
class Sum(Signal):
    """Weighted sum of signals, ``sum(w * s(t) for w, s in terms)``; made by ``+`` and ``*``.

    Parameters
    ----------
    terms : tuple of (float, Signal)
        The weights and the signals.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        If a term is not a ``(finite weight, Signal)`` pair.
    """

    terms: tuple

    def __post_init__(self):
        terms = tuple(self.terms)
        for item in terms:
            if not isinstance(item, tuple) or len(item) != 2 or not isinstance(item[1], Signal):
                raise ParameterTypeError(f"terms must be (weight, Signal) pairs, got {item!r}")
        object.__setattr__(self, "terms", tuple((as_real(w, "weight"), s) for w, s in terms))

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        total = np.zeros_like(t)
        # a term that is 0 over every t is skipped: total starts at +0 and never becomes -0
        # (x + y is -0 only if both are), so total + weight * (+-0) is total, bit for bit;
        # only for a valid order (any other n goes to the terms, which say what is wrong)
        order = _order_or_none(n)
        last = float(t.max()) if t.size else -math.inf
        for weight, signal in self.terms:
            if last < _silent_before(signal, order):
                continue
            total = total + weight * signal.derivative(t, n)
        # at a scalar time adding a term gives a numpy scalar: so does a sum of skipped terms
        return total[()] if self.terms and t.ndim == 0 else total

    def _silent_before(self, n: int) -> float:
        return min((_silent_before(signal, n) for _, signal in self.terms), default=math.inf)


def _order_or_none(n):
    """``n`` as a derivative order, or None if it is not one."""
    try:
        return _check_derivative(n)
    except (TypeError, ValueError):
        return None


def _says_where_silent(cls: type) -> bool:
    """Whether the class that gives ``cls`` its ``derivative`` also gives its
    ``_silent_before`` (a subclass that changes the one without the other is evaluated)."""
    for klass in cls.__mro__:
        if "derivative" in vars(klass):
            return "_silent_before" in vars(klass)
    return False


def _silent_before(signal: Signal, n) -> float:
    """``signal._silent_before(n)`` if ``signal`` says it and ``n`` is an order, else -inf."""
    if n is None or not _says_where_silent(type(signal)):
        return -math.inf
    return signal._silent_before(n)


@dataclass(frozen=True)
class Constant(Signal):
    """``value`` for all t.

    Parameters
    ----------
    value : float
        The constant (the signal's unit: rad for a reference, N m for a disturbance).
    """

    value: float

    def __post_init__(self):
        object.__setattr__(self, "value", as_real(self.value, "value"))

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        return np.full_like(t, self.value if _check_derivative(n) == 0 else 0.0)

    def _silent_before(self, n: int) -> float:
        return math.inf if n > 0 or self.value == 0.0 else -math.inf


@dataclass(frozen=True)
class Step(Signal):
    """``amplitude`` for t >= ``time``, 0 before. Its derivatives are taken as 0.

    Parameters
    ----------
    time : float
        When it steps [s].
    amplitude : float
        The height of the step (the signal's unit: rad for a reference, N m for a disturbance).
    """

    time: float
    amplitude: float

    def __post_init__(self):
        object.__setattr__(self, "time", as_real(self.time, "time", "a finite time [s]"))
        object.__setattr__(self, "amplitude", as_real(self.amplitude, "amplitude"))

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        if _check_derivative(n) > 0:
            return np.zeros_like(t)
        return np.where(t >= self.time, self.amplitude, 0.0)

    def _silent_before(self, n: int) -> float:
        return math.inf if n > 0 else self.time


@dataclass(frozen=True)
class Ramp(Signal):
    """``slope * (t - start)`` for t >= ``start``, 0 before.

    Parameters
    ----------
    start : float
        When it starts [s].
    slope : float
        Its rate per second (rad/s for a reference, N m/s for a disturbance).
    """

    start: float
    slope: float

    def __post_init__(self):
        object.__setattr__(self, "start", as_real(self.start, "start", "a finite time [s]"))
        object.__setattr__(self, "slope", as_real(self.slope, "slope"))

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        n = _check_derivative(n)
        on = t >= self.start
        if n == 0:
            return np.where(on, self.slope * (t - self.start), 0.0)
        if n == 1:
            return np.where(on, self.slope, 0.0)
        return np.zeros_like(t)

    def _silent_before(self, n: int) -> float:
        return math.inf if n > 1 else self.start


@dataclass(frozen=True)
class SmoothStep(Signal):
    """Quintic step from 0 to ``amplitude`` over ``start <= t <= end``.

    ``amplitude * (10 s^3 - 15 s^4 + 6 s^5)`` with ``s = (t - start) / (end - start)``: zero
    velocity and acceleration at both ends.

    Parameters
    ----------
    start, end : float
        Where the transition starts and ends [s], ``end > start``.
    amplitude : float
        The final value (the signal's unit: rad for a reference, N m for a disturbance).

    Raises
    ------
    ParameterTypeError, ParameterValueError
        For a non-finite value or ``end <= start``.
    """

    start: float
    end: float
    amplitude: float

    def __post_init__(self):
        start = as_real(self.start, "start", "a finite time [s]")
        end = as_real(self.end, "end", "a finite time [s]")
        if end <= start:
            raise ParameterValueError(f"end must be after start={start!r}, got {end!r}")
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "end", end)
        object.__setattr__(self, "amplitude", as_real(self.amplitude, "amplitude"))

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        n = _check_derivative(n)
        T = self.end - self.start
        s = np.clip((t - self.start) / T, 0.0, 1.0)
        inside = (t > self.start) & (t < self.end)
        if n == 0:
            return self.amplitude * s**3 * (10.0 - 15.0 * s + 6.0 * s**2)
        if n == 1:
            value = 30.0 * s**2 * (1.0 - s) ** 2 / T
        elif n == 2:
            value = 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s) / T**2
        elif n == 3:
            value = 60.0 * (1.0 - 6.0 * s + 6.0 * s**2) / T**3
        else:
            value = np.zeros_like(t)
        return np.where(inside, self.amplitude * value, 0.0)

    def _silent_before(self, n: int) -> float:
        return self.start  # s = 0 there: amplitude * 0 for the value, 0.0 for a derivative


class _Trajectory:
    """Callable ``t -> (r, r_dot, r_ddot)`` built from a signal's derivatives."""

    __slots__ = ("signal",)

    def __init__(self, signal: Signal):
        self.signal = signal

    def __call__(self, t):
        return (
            self.signal.derivative(t, 0),
            self.signal.derivative(t, 1),
            self.signal.derivative(t, 2),
        )

    def __repr__(self) -> str:
        return f"trajectory({self.signal!r})"

    def __eq__(self, other) -> bool:
        return isinstance(other, _Trajectory) and other.signal == self.signal

    __hash__ = None


def trajectory(signal: Signal):
    """Reference callable ``t -> (r, r_dot, r_ddot)`` from a :class:`Signal` [rad, rad/s, rad/s^2].

    Parameters
    ----------
    signal : Signal
        The reference angle [rad] as a function of time.

    Returns
    -------
    callable
        ``f(t)`` returning the tuple ``(r, r_dot, r_ddot)`` of arrays at the times ``t`` [s]:
        the signal and its first two derivatives (:meth:`Signal.derivative`), what
        :func:`hpdob.simulate` takes as ``reference``.

    Raises
    ------
    ParameterTypeError
        If ``signal`` is not a :class:`Signal`.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob.signals import SmoothStep, trajectory
    >>> r, r_dot, r_ddot = trajectory(SmoothStep(0.0, 1.0, 2.0))(np.array([0.5]))
    >>> float(r[0]), float(r_dot[0])
    (1.0, 3.75)
    """
    if not isinstance(signal, Signal):
        raise ParameterTypeError(f"signal must be an hpdob Signal, got {type(signal).__name__}")
    return _Trajectory(signal)
