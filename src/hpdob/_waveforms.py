r"""Oscillating and random signals: sine, linear chirp and held Gaussian noise.

Subclasses of :class:`hpdob.signals.Signal` (``_signals.py``), with the same rules: immutable,
vectorised functions of time that add and scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._signals import Signal, _check_derivative, _times
from ._validation import ParameterValueError, _show, as_int, as_real, positive

__all__ = ["Chirp", "Noise", "Sine"]


@dataclass(frozen=True)
class Sine(Signal):
    """``offset + amplitude * sin(2 pi frequency (t - start) + phase)`` for t >= start, 0 before.

    The canonical tracking reference ``0.5 (1 - cos(pi (t - 4)))`` is
    ``Sine(-0.5, 0.5, start=4, phase=pi/2, offset=0.5)``.

    Parameters
    ----------
    amplitude : float
        Amplitude (the signal's unit: rad for a reference, N m for a disturbance).
    frequency : float
        Frequency [Hz], positive.
    start : float, optional
        When it starts [s]; 0 before. Default 0.
    phase : float, optional
        Phase at ``start`` [rad]. Default 0.
    offset : float, optional
        Added from ``start`` on (not to the derivatives). Default 0.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        For a non-finite value or a frequency that is not positive.
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

    def _silent_before(self, n: int) -> float:
        try:  # a derivative whose gain overflows raises: never skipped
            gain = self.amplitude * (2.0 * math.pi * self.frequency) ** n
        except OverflowError:
            return -math.inf
        return self.start if math.isfinite(gain) else -math.inf


@dataclass(frozen=True)
class Chirp(Signal):
    """Linear chirp ``amplitude * sin(2 pi (f0 tau + (f1 - f0) tau^2 / (2 T)))``, tau = t - start.

    Active for ``start <= t < stop`` (T = stop - start), 0 elsewhere.

    Parameters
    ----------
    amplitude : float
        Amplitude (the signal's unit: rad for a reference, N m for a disturbance).
    f0, f1 : float
        Frequencies [Hz] at ``start`` and at ``stop``, >= 0.
    start, stop : float
        The interval [s] it is active on, ``stop > start``.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        For a non-finite value, a negative frequency or ``stop <= start``.
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

    def _silent_before(self, n: int) -> float:
        return self.start if n <= 2 else -math.inf  # above n = 2 it raises


@dataclass(frozen=True)
class Noise(Signal):
    """Seeded Gaussian noise held constant over intervals of ``hold`` seconds.

    Sample ``j`` (``start + j*hold <= t < start + (j+1)*hold``) is ``std * N_j`` with ``N_j``
    the j-th draw of ``numpy.random.default_rng(seed).standard_normal``; 0 outside
    ``[start, stop)``. The value depends only on t, never on where the integrator evaluates it.
    Noise has no derivative, so it can be a disturbance but not a reference.

    Parameters
    ----------
    std : float
        Standard deviation [N m], >= 0.
    hold : float
        How long each sample is held [s], positive.
    stop : float
        End of the noise [s], after ``start``.
    seed : int, optional
        Seed of ``numpy.random.default_rng``, >= 0. Default 0.
    start : float, optional
        Start of the noise [s]. Default 0.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        For a value out of range, or more than 1e8 samples.
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

    def _silent_before(self, n: int) -> float:
        return self.start if n == 0 else -math.inf  # a derivative raises
