r"""python-control systems in: a servo ``k/(J s^2 + b s)`` read as ``ServoModel`` parameters.

The parameters of a continuous servo (:func:`servo_parameters`) or of its zero-order-hold
sampling (:func:`discrete_servo_parameters`, as ``control.c2d(sys, Ts)`` returns it). The
conversion helpers every model-taking entry point uses, ``as_servo_model`` and
``as_discrete_model``, live beside the classes in ``_servo``.
"""

from __future__ import annotations

import math

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, positive

__all__ = ["discrete_servo_parameters", "is_lti", "servo_parameters"]

_SERVO = "a servo k/(J s^2 + b s) (torque gain k, J > 0, b >= 0)"
#: Relative size below which a leading coefficient counts as round-off of a conversion.
_ROUNDOFF = 1e-12


def is_lti(value) -> bool:
    """Whether ``value`` is a python-control ``TransferFunction`` or ``StateSpace``."""
    module = type(value).__module__ or ""
    if not module.startswith("control."):
        return False
    import control

    return isinstance(value, (control.TransferFunction, control.StateSpace))


def _polynomials(sys, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator of a SISO system, monic denominator, round-off trimmed."""
    import control

    if not is_lti(sys):
        raise ParameterTypeError(
            f"{name} must be a python-control TransferFunction or StateSpace, got "
            f"{type(sys).__name__}"
        )
    if (sys.ninputs, sys.noutputs) != (1, 1):
        raise ParameterValueError(
            f"{name} must have one input (the torque command) and one output (the angle), got "
            f"{sys.ninputs} inputs and {sys.noutputs} outputs; pass the channel, e.g. sys[0, 0]"
        )
    tf = control.tf(sys) if isinstance(sys, control.StateSpace) else sys
    num = np.array(tf.num[0][0], dtype=float)
    den = np.array(tf.den[0][0], dtype=float)
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))) or not np.any(den):
        raise ParameterValueError(f"{name} must have finite coefficients, got {tf.num}/{tf.den}")
    num = _trim(num)
    den = _trim(den)
    return num / den[0], den / den[0]


def _trim(poly: np.ndarray) -> np.ndarray:
    """Drop leading coefficients that are round-off (ss -> tf leaves ~1e-17 relative)."""
    scale = float(np.max(np.abs(poly))) if poly.size else 0.0
    keep = np.flatnonzero(np.abs(poly) > _ROUNDOFF * scale)
    return poly[keep[0] :] if keep.size else np.zeros(1)


def _describe(num: np.ndarray, den: np.ndarray) -> str:
    return f"num {np.round(num, 12).tolist()}, den {np.round(den, 12).tolist()}"


def servo_parameters(sys, *, torque_gain: float = 1.0, name: str = "sys") -> tuple[float, float]:
    r"""``(J, b)`` of a continuous servo ``k/(J s^2 + b s)`` given as a python-control system.

    Parameters
    ----------
    sys : control.TransferFunction or control.StateSpace
        Continuous (``dt = 0``), one input (the command) and one output (the angle [rad]).
    torque_gain : float, optional
        Torque per unit of the input, ``k`` [N m per input unit]. Default 1 (the input is the
        torque [N m]).
    name : str, optional
        Parameter name used in messages.

    Returns
    -------
    tuple of float
        ``J`` [kg m^2] and ``b`` [N m s/rad]: ``sys = k / (J s^2 + b s)``.

    Raises
    ------
    ParameterTypeError
        If ``sys`` is not a python-control system.
    ParameterValueError
        Naming what is not a servo: a discrete system, several inputs or outputs, a zero, a
        number of poles other than two, no pole at the origin, a pole that is not real, a
        pole in the right half-plane, a negative gain.
    """
    k = positive(torque_gain, "torque_gain", "a positive finite torque gain [N m per unit]")
    if is_lti(sys) and sys.isdtime(strict=True):
        raise ParameterValueError(
            f"{name} must be a continuous system (dt = 0), got a discrete one with dt = {sys.dt}; "
            "for a sampled servo use DiscreteServoModel.from_lti"
        )
    num, den = _polynomials(sys, name)
    what = f"{name} is not {_SERVO}"
    if num.size > 1:
        zeros = np.roots(num)
        raise ParameterValueError(
            f"{what}: it has a zero at s = {np.round(zeros, 9).tolist()} ({_describe(num, den)})"
        )
    if den.size != 3:
        raise ParameterValueError(
            f"{what}: it has {den.size - 1} poles, a servo has two (0 and -b/J) "
            f"({_describe(num, den)})"
        )
    a, c = float(den[1]), float(den[2])
    if abs(c) > 1e-9 * a * a:  # no pole at the origin (to round-off of a conversion)
        poles = np.roots(den)
        kind = (
            "poles off the origin that are not real"
            if np.iscomplexobj(poles) and np.any(np.abs(poles.imag) > 0)
            else "no pole at the origin"
        )
        raise ParameterValueError(
            f"{what}: it has {kind}, s = {np.round(poles, 9).tolist()} (a servo's are 0 and "
            f"-b/J) ({_describe(num, den)})"
        )
    if a < 0.0:
        raise ParameterValueError(
            f"{what}: its pole s = {-a!r} is in the right half-plane (b/J = {a!r} < 0)"
        )
    gain = float(num[0])
    if not gain > 0.0:
        raise ParameterValueError(
            f"{what}: its gain {gain!r} must be positive (a torque in the direction of the "
            "angle); negate the system or the torque gain's sign convention"
        )
    J = k / gain
    return J, a * J


def discrete_servo_parameters(sys, *, servo, torque_gain: float = 1.0, name: str = "sys"):
    r"""``(J, b, Ts)`` of the zero-order-hold sampling of a servo (``control.c2d(servo, Ts)``).

    Parameters
    ----------
    sys : control.TransferFunction or control.StateSpace
        Discrete (``dt = Ts > 0``), one input (the command) and one output (the angle [rad]).
    servo : type
        The continuous servo class (``ServoModel``), whose ``discretize`` gives the ZOH shape the
        numerator is checked against (passed in, so that this module does not import it).
    torque_gain : float, optional
        Torque per unit of the input [N m per input unit]. Default 1.
    name : str, optional
        Parameter name used in messages.

    Returns
    -------
    tuple of float
        ``J`` [kg m^2], ``b`` [N m s/rad] and ``Ts`` [s]; ``ServoModel(J, b).discretize(Ts)``
        has the transfer function of ``sys`` (checked to 1e-8 relative).

    Raises
    ------
    ParameterTypeError, ParameterValueError
        If ``sys`` is not the ZOH sampling of a servo, naming what differs.
    """
    k = positive(torque_gain, "torque_gain", "a positive finite torque gain [N m per unit]")
    if is_lti(sys) and not sys.isdtime(strict=True):
        raise ParameterValueError(
            f"{name} must be a discrete system with a sampling period (dt > 0), got dt = "
            f"{sys.dt}; discretise it, e.g. control.c2d(sys, Ts) or "
            "ServoModel.from_lti(sys).discretize(Ts)"
        )
    num, den = _polynomials(sys, name)
    Ts = positive(sys.dt, f"{name}.dt", "a positive finite sampling period [s]")
    what = f"{name} is not the zero-order-hold sampling of {_SERVO}"
    poles = np.roots(den) if den.size == 3 else np.zeros(0)
    at_one = poles.size == 2 and np.min(np.abs(poles - 1.0)) <= 1e-9
    other = poles[np.argmax(np.abs(poles - 1.0))] if at_one else None
    if not at_one or abs(other.imag) > 0 or not 0.0 < other.real <= 1.0 or num.size != 2:
        raise ParameterValueError(
            f"{what}: it needs poles z = 1 and z = exp(-b Ts/J) in (0, 1] and one zero, got "
            f"poles {np.round(poles, 9).tolist()} ({_describe(num, den)})"
        )
    # (z - 1)(z - p) = z^2 - (1 + p) z + p: p is the constant coefficient, more accurate than
    # a root of the nearly double root at 1
    p = float(den[2]) if abs(float(den[2]) - other.real) < 1e-6 else float(other.real)
    alpha = abs(math.log1p(p - 1.0))  # p in (0, 1]: alpha >= 0, never -0.0
    unit = servo(1.0, alpha / Ts).discretize(Ts)  # J = 1: the shape, scaled below
    unit_num = np.array([unit.B[0], unit.A[0, 1] * unit.B[1] - unit.A[1, 1] * unit.B[0]])
    J = float(np.sum(unit_num) / np.sum(num))
    if not (np.isfinite(J) and J > 0.0) or not np.allclose(num * J, unit_num, rtol=1e-8, atol=0):
        raise ParameterValueError(
            f"{what}: its numerator {num.tolist()} is not a ZOH servo's for the poles "
            f"{np.round(poles, 12).tolist()}"
        )
    J *= k
    return J, alpha / Ts * J, Ts
