r"""Pure functional core of the observer sample loop.

The observer state is a tuple of ``order + 1`` Python floats, :math:`\hat z_k`. Each function
takes a design and a state and returns a new value; nothing is mutated, so the functions can
be used to replay, branch or vectorise a sample loop. :class:`hpdob.DisturbanceObserver` is a
thin stateful wrapper around them.

The hot path uses plain floats and tuples, not numpy: with a state of two or three numbers,
numpy's per-call overhead would cost more than the arithmetic.
"""

from __future__ import annotations

import math

import numpy as np

from .._validation import ParameterValueError, as_real
from ._synthesis import ObserverDesign

__all__ = ["estimate", "initial_state", "update"]

_isfinite = math.isfinite


def read_state_vector(x, name: str = "x") -> tuple[float, float]:
    """Return ``(theta, omega)`` from a length-2 measurement, validated finite."""
    if type(x) is np.ndarray:
        if x.shape != (2,):
            raise ParameterValueError(
                f"{name} must be a measured state [theta (rad), omega (rad/s)] "
                f"of shape (2,), got an array of shape {x.shape}"
            )
        x = x.tolist()
    try:
        theta, omega = x
    except (TypeError, ValueError):
        raise ParameterValueError(
            f"{name} must be a measured state [theta (rad), omega (rad/s)] with "
            f"2 entries, got {x!r}"
        ) from None
    if not (
        type(theta) is float and type(omega) is float and _isfinite(theta) and _isfinite(omega)
    ):
        # Slow path: convert other real types and say exactly what is wrong.
        theta = as_real(theta, f"{name}[0] (theta)", "a finite angle [rad]")
        omega = as_real(omega, f"{name}[1] (omega)", "a finite velocity [rad/s]")
    return theta, omega


def read_control(u, name: str = "u") -> float:
    """Return the control input as a float, validated finite."""
    if type(u) is float and _isfinite(u):
        return u
    return as_real(u, name, "a finite control torque [N m]")


def _check_state(design: ObserverDesign, state) -> None:
    if type(state) is not tuple or len(state) != len(design._k):
        raise ParameterValueError(
            f"state must be a tuple of order + 1 = {len(design._k)} floats "
            f"(from initial_state or update), got {state!r}"
        )


def initial_state(design: ObserverDesign, x0=(0.0, 0.0), tau0: float = 0.0) -> tuple:
    r"""State of an observer that has converged on a constant disturbance ``tau0`` at ``x0``.

    :math:`\hat z_i = \tau_0 + L_i^T x_0` for every ``i`` (the disturbance history is
    constant, so all auxiliary variables see the same :math:`\tau`).

    Parameters
    ----------
    design : ObserverDesign
    x0 : sequence of 2 floats, optional
        Initial state ``[theta (rad), omega (rad/s)]``. Default ``(0, 0)``.
    tau0 : float, optional
        Initial nominal disturbance [N m]. Default 0.

    Returns
    -------
    tuple of float
    """
    theta, omega = read_state_vector(x0, "x0")
    tau0 = as_real(tau0, "tau0", "a finite disturbance torque [N m]")
    return tuple(float(tau0 + g[0] * theta + g[1] * omega) for g in design.gains)


def estimate(design: ObserverDesign, state: tuple, x) -> float:
    r"""Disturbance estimate :math:`\hat\tau_k = \hat z_{m+1,k} - L_{m+1}^T x_k` [N m].

    Eq. (13) for the DOb, eq. (23) for the HPDOb.

    Parameters
    ----------
    design : ObserverDesign
    state : tuple of float
        :math:`\hat z_k`.
    x : sequence of 2 floats
        Measured state ``[theta (rad), omega (rad/s)]`` at sample ``k``.
    """
    theta, omega = read_state_vector(x)
    _check_state(design, state)
    lt, lw = design._last_gain
    return state[-1] - lt * theta - lw * omega


def update(design: ObserverDesign, state: tuple, x, u) -> tuple:
    r"""Next observer state :math:`\hat z_{k+1}` from :math:`\hat z_k`, ``x_k`` and ``u_k``.

    .. math:: \hat z_{k+1} = M \hat z_k + (G A - M G) x_k + G B u_k

    which is eq. (11) for ``order = 0`` and eqs. (20)-(21) for ``order = 1``. ``u`` is the
    torque actually commanded at sample ``k`` (including the disturbance compensation).

    Parameters
    ----------
    design : ObserverDesign
    state : tuple of float
        :math:`\hat z_k`.
    x : sequence of 2 floats
        Measured state ``[theta (rad), omega (rad/s)]`` at sample ``k``.
    u : float
        Control torque applied over sample ``k`` [N m].

    Returns
    -------
    tuple of float
        :math:`\hat z_{k+1}`.

    Raises
    ------
    ValueError
        If ``x`` or ``u`` is not finite, or ``state`` has the wrong length.
    """
    theta, omega = read_state_vector(x)
    u = read_control(u)
    _check_state(design, state)
    k = design._k
    last = state[-1]
    rows = design._rows
    n = len(k)
    out = [
        state[i + 1] - k[i] * last + r[0] * theta + r[1] * omega + r[2] * u
        for i, r in enumerate(rows[: n - 1])
    ]
    r = rows[-1]
    acc = -k[-1] * last + r[0] * theta + r[1] * omega + r[2] * u
    for p, z in zip(design._p, state, strict=True):
        acc += p * z
    out.append(acc)
    return tuple(out)
