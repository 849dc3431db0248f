r"""A disturbance as a coefficient table the compiled loop evaluates at the sub-step midpoints.

The integrator reads the external torque at ``k Ts + (j + 1/2) Ts/S`` for every sub-step: ``S``
values per sample, evaluated in numpy an ``n S`` array (8 values and 64 bytes per sample at the
default sub-steps, more for stiff friction) built before the run and read once. For hpdob's
built-in signals whose numpy evaluation the loop can repeat operation for operation --
:class:`~hpdob.signals.Constant`, :class:`~hpdob.signals.Step`, :class:`~hpdob.signals.Ramp`,
:class:`~hpdob.signals.Sine`, and weighted :class:`~hpdob.signals.Sum`\ s of them (``a + b``,
``2.0 * a``) -- :func:`midpoint_table` gives the signal's *form* (the kinds of its terms: what
the generated code depends on) and its coefficients, and :func:`midpoint_source` the code that
evaluates it inside the sub-step loop, so that no midpoint array exists.

Bit for bit: every operation is the one numpy performs, in its order (``Sine``:
``sin((t - start) w + phase) * gain + offset``, ``Sum``: ``0 + w_1 s_1 + w_2 s_2 ...``), and
the sine is libm's ``sin`` in both (numpy 2.4's float64 ``sin`` and numba's agree on this
machine: 0 differences over 6 million random arguments up to 1e4 rad and on the canonical
time grids, ``tests/simulation/test_signal_table.py``). Not inline, sampled in numpy as
before: :class:`~hpdob.signals.SmoothStep` (numpy's float64 ``s**3`` is not libm's ``pow``:
5 % of arguments differ in the last bit), :class:`~hpdob.signals.Chirp`,
:class:`~hpdob.signals.Noise` (drawn in numpy from its seed), nested sums, signals that could
overflow the float range (their error is reported by the sampled path) and any other callable.
"""

from __future__ import annotations

import math

import numpy as np

from .._signals import Constant, Ramp, Signal, Step, Sum
from .._waveforms import Sine

__all__ = ["midpoint_source", "midpoint_table"]

#: Term kinds of a form, and the number of coefficients each takes from the table.
_WIDTH = {"constant": 1, "step": 2, "ramp": 2, "sine": 5}
#: Values beyond this could overflow in a sum or a product: such a signal is sampled instead.
_LARGE = 1e300


def _term(signal: Signal, duration: float):
    """``(kind, coefficients, bound)`` of one signal (``bound``: a bound on its magnitude over
    ``[0, duration]``), or None if the loop does not evaluate it."""
    if type(signal) is Constant:
        return "constant", (signal.value,), abs(signal.value)
    if type(signal) is Step:
        return "step", (signal.time, signal.amplitude), abs(signal.amplitude)
    if type(signal) is Ramp:
        reach = abs(signal.slope) * (abs(duration) + abs(signal.start))
        return "ramp", (signal.start, signal.slope), reach
    if type(signal) is Sine:  # Sine.derivative at n = 0: phase + 0 * pi / 2, gain = amplitude
        w = 2.0 * math.pi * signal.frequency
        phase = signal.phase + (0 % 4) * math.pi / 2.0
        gain = signal.amplitude * w**0
        values = (signal.start, w, phase, gain, signal.offset)
        return "sine", values, abs(gain) + abs(signal.offset)
    return None


def midpoint_table(disturbance, duration: float):
    """The form and coefficients of ``disturbance`` for the compiled loop, or None.

    Parameters
    ----------
    disturbance : Signal, callable or None
        The run's external torque [N m].
    duration : float
        The run's length [s] (bounds a ramp's values).

    Returns
    -------
    tuple or None
        ``(form, table)``: ``form`` is ``(summed, kinds)`` (``summed``: a :class:`Sum`, whose
        value is ``0 + w_1 s_1 + ...``, else one bare signal), ``table`` a float64 array of the
        weights and the terms' coefficients, in order. None for a disturbance the loop does not
        evaluate (it is sampled in numpy).
    """
    if isinstance(disturbance, Sum):
        summed, terms = True, disturbance.terms
    elif isinstance(disturbance, Signal):
        summed, terms = False, ((1.0, disturbance),)
    else:
        return None
    kinds, values, bound = [], [], 0.0
    for weight, signal in terms:
        term = _term(signal, duration)
        if term is None:
            return None
        kind, coefficients, size = term
        kinds.append(kind)
        values += [weight, *coefficients] if summed else list(coefficients)
        bound += abs(weight) * size
    if not bound < _LARGE or not all(math.isfinite(v) for v in values):
        return None
    return (summed, tuple(kinds)), np.array(values, dtype=np.float64)


def midpoint_source(form, time: str, table: str, result: str, first: int = 1) -> tuple[list, list]:
    """Code evaluating a disturbance of ``form`` at the time named ``time`` into ``result``.

    Returns ``(loads, lines)``: the statements reading the coefficients from the array named
    ``table`` (from entry ``first`` on) into locals (once, before the loop) and those
    evaluating the signal (numpy's operations in numpy's order, see the module's docstring).
    """
    summed, kinds = form
    loads, lines, position = [], [], first

    def local() -> str:
        nonlocal position
        name = f"dt{position}"
        loads.append(f"{name} = {table}[{position}]")
        position += 1
        return name

    if summed:
        lines.append(f"{result} = 0.0")
    for i, kind in enumerate(kinds):
        weight = local() if summed else None
        names = [local() for _ in range(_WIDTH[kind])]
        if kind == "constant":
            value = names[0]
        elif kind == "step":
            value = f"({names[1]} if {time} >= {names[0]} else 0.0)"
        elif kind == "ramp":
            value = f"({names[1]} * ({time} - {names[0]}) if {time} >= {names[0]} else 0.0)"
        else:  # sine: numpy's in-place  t - start, * w, + phase, sin, * gain, + offset
            start, w, phase, gain, offset = names
            lines += [
                f"sine{i} = 0.0",
                f"if {time} >= {start}:",
                f"    sine{i} = math.sin(({time} - {start}) * {w} + {phase}) * {gain}",
                f"    if {offset} != 0.0:",
                f"        sine{i} += {offset}",
            ]
            value = f"sine{i}"
        lines.append(
            f"{result} = {result} + {weight} * {value}" if summed else f"{result} = {value}"
        )
    return loads, lines
