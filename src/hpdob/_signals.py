r"""Composable time signals for references and disturbances.

Every signal is an immutable, vectorised function of time: ``signal(t)`` returns the value at an
array of times [s] and ``signal.derivative(t, n)`` its ``n``-th time derivative. Signals add
(``a + b``), scale (``2.0 * a``) and negate. A disturbance is any signal (or any callable of an
array of times); a reference for :func:`hpdob.simulate` is a signal wrapped by
:func:`trajectory`, which returns ``(r, r_dot, r_ddot)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._validation import (
    ParameterTypeError,
    ParameterValueError,
    _show,
    as_int,
    as_real,
    numeric_array,
    positive,
)

__all__ = [
    "Chirp",
    "Constant",
    "Noise",
    "Ramp",
    "Signal",
    "Sine",
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
    """Weighted sum of signals, ``sum(w * s(t) for w, s in terms)``; made by ``+`` and ``*``."""

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
        for weight, signal in self.terms:
            total = total + weight * signal.derivative(t, n)
        return total


@dataclass(frozen=True)
class Constant(Signal):
    """``value`` for all t."""

    value: float

    def __post_init__(self):
        object.__setattr__(self, "value", as_real(self.value, "value"))

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        return np.full_like(t, self.value if _check_derivative(n) == 0 else 0.0)


@dataclass(frozen=True)
class Step(Signal):
    """``amplitude`` for t >= ``time``, 0 before. Its derivatives are taken as 0."""

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


@dataclass(frozen=True)
class Ramp(Signal):
    """``slope * (t - start)`` for t >= ``start``, 0 before."""

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


@dataclass(frozen=True)
class SmoothStep(Signal):
    """Quintic step from 0 to ``amplitude`` over ``start <= t <= end``.

    ``amplitude * (10 s^3 - 15 s^4 + 6 s^5)`` with ``s = (t - start) / (end - start)``: zero
    velocity and acceleration at both ends.
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


@dataclass(frozen=True)
class Sine(Signal):
    """``offset + amplitude * sin(2 pi frequency (t - start) + phase)`` for t >= start, 0 before.

    ``frequency`` in Hz, ``phase`` in rad. The canonical tracking reference
    ``0.5 (1 - cos(pi (t - 4)))`` is ``Sine(-0.5, 0.5, start=4, phase=pi/2, offset=0.5)``.
    """

    amplitude: float
    frequency: float
    start: float = 0.0
    phase: float = 0.0
    offset: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "amplitude", as_real(self.amplitude, "amplitude"))
        frequency = positive(self.frequency, "frequency", "a positive finite frequency [Hz]")
        if not math.isfinite(2.0 * math.pi * frequency):
            raise ParameterValueError(
                f"frequency must be a positive frequency [Hz] whose 2 pi frequency [rad/s] is "
                f"finite, got {frequency!r}"
            )
        object.__setattr__(self, "frequency", frequency)
        object.__setattr__(self, "start", as_real(self.start, "start", "a finite time [s]"))
        object.__setattr__(self, "phase", as_real(self.phase, "phase", "a finite phase [rad]"))
        object.__setattr__(self, "offset", as_real(self.offset, "offset"))

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        n = _check_derivative(n)
        w = 2.0 * math.pi * self.frequency
        try:
            gain = self.amplitude * w**n
        except OverflowError:
            gain = math.inf
        if not math.isfinite(gain):
            raise ParameterValueError(
                f"derivative n={_show(n)} of Sine(amplitude={self.amplitude!r}, frequency="
                f"{self.frequency!r} Hz) exceeds the float range: |amplitude| (2 pi frequency)^n "
                f"overflows; lower the frequency or the derivative order"
            )
        out = np.array(t, dtype=float)  # a new array, also for scalar t (0-d)
        out -= self.start  # in-place arithmetic: this runs on every sub-step midpoint
        out *= w
        out += self.phase + (n % 4) * math.pi / 2.0  # d^n/dt^n sin(x) = w^n sin(x + n pi/2)
        np.sin(out, out=out)
        out *= gain
        if n == 0 and self.offset:
            out += self.offset
        np.copyto(out, 0.0, where=t < self.start)
        return out


@dataclass(frozen=True)
class Chirp(Signal):
    """Linear chirp ``amplitude * sin(2 pi (f0 tau + (f1 - f0) tau^2 / (2 T)))``, tau = t - start.

    Active for ``start <= t < stop`` (T = stop - start), 0 elsewhere. Frequencies in Hz.
    """

    amplitude: float
    f0: float
    f1: float
    start: float
    stop: float

    def __post_init__(self):
        object.__setattr__(self, "amplitude", as_real(self.amplitude, "amplitude"))
        for name in ("f0", "f1"):
            value = as_real(getattr(self, name), name, "a non-negative finite frequency [Hz]")
            if value < 0:
                raise ParameterValueError(
                    f"{name} must be a non-negative finite frequency [Hz], got {value!r}"
                )
            object.__setattr__(self, name, value)
        start = as_real(self.start, "start", "a finite time [s]")
        stop = as_real(self.stop, "stop", "a finite time [s]")
        if stop <= start:
            raise ParameterValueError(f"stop must be after start={start!r}, got {stop!r}")
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "stop", stop)

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        n = _check_derivative(n)
        tau = t - self.start
        rate = (self.f1 - self.f0) / (self.stop - self.start)  # Hz/s
        phase = 2.0 * math.pi * (self.f0 * tau + 0.5 * rate * tau**2)
        dphase = 2.0 * math.pi * (self.f0 + rate * tau)
        ddphase = 2.0 * math.pi * rate
        if n == 0:
            value = np.sin(phase)
        elif n == 1:
            value = dphase * np.cos(phase)
        elif n == 2:
            value = ddphase * np.cos(phase) - dphase**2 * np.sin(phase)
        else:
            raise ParameterValueError(f"Chirp provides derivatives up to n=2, got n={n}")
        return np.where((t >= self.start) & (t < self.stop), self.amplitude * value, 0.0)


@dataclass(frozen=True)
class Noise(Signal):
    """Seeded Gaussian noise held constant over intervals of ``hold`` seconds.

    Sample ``j`` (``start + j*hold <= t < start + (j+1)*hold``) is ``std * N_j`` with ``N_j``
    the j-th draw of ``numpy.random.default_rng(seed).standard_normal``; 0 outside
    ``[start, stop)``. The value depends only on t, never on where the integrator evaluates it.
    Noise has no derivative, so it can be a disturbance but not a reference.
    """

    std: float
    hold: float
    stop: float
    seed: int = 0
    start: float = 0.0
    _samples: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        std = as_real(self.std, "std", "a non-negative finite standard deviation")
        if std < 0:
            raise ParameterValueError(
                f"std must be a non-negative finite standard deviation, got {std!r}"
            )
        hold = positive(self.hold, "hold", "a positive finite hold time [s]")
        start = as_real(self.start, "start", "a finite time [s]")
        stop = as_real(self.stop, "stop", "a finite time [s]")
        if stop <= start:
            raise ParameterValueError(f"stop must be after start={start!r}, got {stop!r}")
        count = math.ceil((stop - start) / hold)
        if count > 100_000_000:
            raise ParameterValueError(
                f"hold={hold!r} s over [{start}, {stop}) needs {_show(count)} "
                "samples; at most 1e8 are supported"
            )
        seed = as_int(self.seed, "seed", "a non-negative integer seed", minimum=0)
        samples = std * np.random.default_rng(seed).standard_normal(count)
        samples.setflags(write=False)
        for name, value in (
            ("std", std),
            ("hold", hold),
            ("start", start),
            ("stop", stop),
            ("seed", seed),
            ("_samples", samples),
        ):
            object.__setattr__(self, name, value)

    def derivative(self, t, n: int = 0) -> np.ndarray:
        t = _times(t)
        if _check_derivative(n) != 0:
            raise ParameterValueError(
                "Noise has no derivative: use it as a disturbance, not as a reference"
            )
        position = (t - self.start) / self.hold
        inside = (t >= self.start) & (t < self.stop) & (position < self._samples.size)
        index = np.floor(np.where(inside, position, 0.0)).astype(np.int64)  # no NaN/huge casts
        return np.where(inside, self._samples[index], 0.0)


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
