r"""Pure functional core of the observer sample loop, for any observer of the protocol.

The observer state is a tuple of Python floats, :math:`s_k`. Each function takes an observer
(a :class:`~hpdob.LinearObserver`, a design or a runtime object) and a state and returns a new
value; nothing is mutated, so the functions can be used to replay, branch or vectorise a sample
loop. The runtime objects (:class:`hpdob.Observer`, :class:`hpdob.DisturbanceObserver`) are thin
stateful wrappers around them.

The arithmetic is Python code generated from the observer's program
(:func:`hpdob.observers._system.compile_python`): plain floats and tuples, no numpy (with a
state of two or three numbers numpy's per-call overhead would cost more than the arithmetic),
in exactly the operation order of the compiled kernel and the exported C.
"""

from __future__ import annotations

import math

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, as_real
from ._system import LinearObserver, as_system

__all__ = ["estimate", "initial_state", "outputs", "update"]

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
    elif isinstance(x, (dict, set, frozenset, str, bytes)):
        raise ParameterTypeError(
            f"{name} must be a measured state [theta (rad), omega (rad/s)] (a sequence of 2 "
            f"numbers), got {x!r} of type {type(x).__name__}"
        )
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


def read_angle(theta, name: str = "theta") -> float:
    """Return the measured angle as a float, validated finite (position-only observers)."""
    if type(theta) is float and _isfinite(theta):
        return theta
    if isinstance(theta, np.ndarray) and theta.shape == (1,):
        theta = theta[0]
    if isinstance(theta, (tuple, list, np.ndarray)):
        raise ParameterValueError(
            f"{name} must be one measured angle [rad] (a float) for an observer that measures "
            f"the angle only, got {theta!r}"
        )
    return as_real(theta, name, "a finite measured angle [rad]")


def checked_next_state(system: LinearObserver, state: tuple, values: tuple, u: float) -> tuple:
    """``system``'s next state, refused (ParameterValueError, nothing changed) if it overflows.

    Finite inputs large enough (e.g. 1e308) overflow the state to inf/NaN, which would then
    poison every later estimate silently. The generated ``checked_update`` tests one sum: it is
    non-finite exactly when an element is (or when finite elements near the float range
    overflow it, refused as well).
    """
    new = system.checked_update(state, *values, u)
    if new is None:
        raise overflow_error(system, values, u)
    return new


def overflow_error(system: LinearObserver, values: tuple, u: float) -> ParameterValueError:
    """The refusal of an update whose next state overflows."""
    return ParameterValueError(
        f"update(measurement={_show_values(values)}, u={u!r}) overflows the state of "
        f"{system.name}: the inputs are beyond the observer's float range; the state is "
        "unchanged"
    )


def _show_values(values: tuple) -> str:
    return repr(values[0]) if len(values) == 1 else f"({', '.join(map(repr, values))})"


def read_measurement(system: LinearObserver, value, name: str = "x") -> tuple:
    """The measurement as a tuple of floats in ``system.measures`` order.

    A state-measuring observer takes ``[theta, omega]``, a position-only one the angle alone
    (a float).
    """
    if len(system.measures) == 2:
        if isinstance(value, (int, float, np.floating, np.integer)) or (
            isinstance(value, np.ndarray) and value.ndim == 0
        ):
            raise ParameterValueError(
                f"{name} must be a measured state [theta (rad), omega (rad/s)]: this observer "
                f"measures angle and velocity, got the single number {value!r} (a position-only "
                "observer takes the angle alone: design_observer(..., measurement='position'))"
            )
        return read_state_vector(value, name)
    if isinstance(value, (tuple, list)) or (isinstance(value, np.ndarray) and value.size == 2):
        raise ParameterValueError(
            f"{name} must be one measured angle [rad] (a float): this observer measures the "
            f"angle only, got {value!r}"
        )
    return (read_angle(value, name),)


def read_control(u, name: str = "u") -> float:
    """Return the control input as a float, validated finite."""
    if type(u) is float and _isfinite(u):
        return u
    return as_real(u, name, "a finite control torque [N m]")


def _check_state(system: LinearObserver, state) -> None:
    if type(state) is not tuple or len(state) != system.n_states:
        n = system.n_states
        m = system.truncation_order
        size = f"order + 1 = {n}" if m is not None and n == m + 1 else f"{n}"
        raise ParameterValueError(
            f"state must be a tuple of {size} floats (from initial_state or update), got {state!r}"
        )
    if not all(type(v) is float and _isfinite(v) for v in state):
        raise ParameterValueError(f"state must hold finite floats, got {state!r}")


def initial_state(observer, x0=(0.0, 0.0), tau0: float = 0.0) -> tuple:
    r"""State of an observer that has converged on a constant disturbance ``tau0`` at ``x0``.

    :math:`s_0 = N [\theta_0, \omega_0, \tau_0]`; for the order-m family
    :math:`\hat z_i = \tau_0 + L_i^T x_0` for every ``i`` (the disturbance history is constant,
    so all auxiliary variables see the same :math:`\tau`).

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
    x0 : sequence of 2 floats, optional
        Initial state ``[theta (rad), omega (rad/s)]``. Default ``(0, 0)``.
    tau0 : float, optional
        Initial nominal disturbance [N m]. Default 0.

    Returns
    -------
    tuple of float
        :math:`s_0`, as :func:`update` takes it.

    Raises
    ------
    TypeError, ValueError
        If ``x0`` or ``tau0`` is not finite or of the wrong kind.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer, initial_state
    >>> model = ServoModel(J=2.8e-4).discretize(1e-3)
    >>> design = design_observer(model, order=1, bandwidth=100.0, gain_direction=(0.0, 1.0))
    >>> s0 = initial_state(design, x0=(0.0, 2.0), tau0=0.01)   # z_i = tau0 + L_i^T x0:
    >>> [round(float(z - (0.01 + L[1] * 2.0)), 12) for z, L in zip(s0, design.gains)]
    [0.0, 0.0]
    """
    system = as_system(observer)
    theta, omega = read_state_vector(x0, "x0")
    tau0 = as_real(tau0, "tau0", "a finite disturbance torque [N m]")
    return system.python[0](theta, omega, tau0)


def estimate(observer, state: tuple, x) -> float:
    r"""Disturbance estimate :math:`\hat\tau_k` [N m] from the state and the measurement.

    :math:`\hat\tau_k = H_1 s_k + E_1 v_k`: eq. (13) for the DOb, eq. (23) for the HPDOb
    (:math:`\hat z_{m+1,k} - L_{m+1}^T x_k`).

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
    state : tuple of float
        :math:`s_k`.
    x : sequence of 2 floats, or float
        Measurement at sample ``k``: ``[theta (rad), omega (rad/s)]`` for an observer that
        measures the state, the angle [rad] for a position-only one.

    Returns
    -------
    float
        :math:`\hat\tau_k` [N m]; the state is not changed (call :func:`update` next).

    Raises
    ------
    TypeError, ValueError
        If ``x`` is not finite or of the wrong kind, or ``state`` has the wrong length.

    References
    ----------
    Eqs. (13) and (23).

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer, estimate, initial_state
    >>> design = design_observer(ServoModel(J=2.8e-4).discretize(1e-3), order=1,
    ...                          bandwidth=100.0)
    >>> s0 = initial_state(design, x0=(1.0, 0.0), tau0=0.01)  # converged on 0.01 N m
    >>> round(estimate(design, s0, (1.0, 0.0)), 12)
    0.01
    """
    system = as_system(observer)
    values = read_measurement(system, x)
    _check_state(system, state)
    return system.python[2](state, *values)


def outputs(observer, state: tuple, x) -> tuple:
    r"""All outputs ``(tau_hat, [omega_hat])`` of the observer at sample ``k``.

    Like :func:`estimate`, with the velocity estimate [rad/s] as second entry where the
    observer has one (``"omega_hat" in observer.system.outputs``): :math:`H s_k + E v_k`.

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
    state : tuple of float
        :math:`s_k`.
    x : sequence of 2 floats, or float
        Measurement at sample ``k`` (see :func:`estimate`).

    Returns
    -------
    tuple of float
        ``(tau_hat [N m],)``, or ``(tau_hat [N m], omega_hat [rad/s])`` for an observer that
        estimates the velocity (the position-only family, ESO, Kalman).

    Raises
    ------
    TypeError, ValueError
        If ``x`` is not finite or of the wrong kind, or ``state`` has the wrong length.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer, initial_state
    >>> from hpdob.observers import outputs
    >>> model = ServoModel(J=2.8e-4).discretize(1e-3)
    >>> design = design_observer(model, order=1, bandwidth=100.0, measurement="position")
    >>> s0 = initial_state(design, x0=(1.0, 0.5), tau0=0.01)
    >>> tau_hat, omega_hat = outputs(design, s0, 1.0)   # measures the angle only
    >>> round(tau_hat, 12), round(omega_hat, 12)
    (0.01, 0.5)
    """
    system = as_system(observer)
    values = read_measurement(system, x)
    _check_state(system, state)
    return system.python[1](state, *values)


def update(observer, state: tuple, x, u) -> tuple:
    r"""Next observer state :math:`s_{k+1} = F s_k + G [v_k, u_k]`.

    For the order-m family (``docs/theory.md``)
    :math:`\hat z_{k+1} = M \hat z_k + (G A - M G) x_k + G B u_k`, which is eq. (11) for
    ``order = 0`` and eqs. (20)-(21) for ``order = 1``. ``u`` is the torque actually commanded
    at sample ``k`` (including the disturbance compensation).

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
    state : tuple of float
        :math:`s_k`.
    x : sequence of 2 floats, or float
        Measurement at sample ``k`` (see :func:`estimate`).
    u : float
        Control torque applied over sample ``k`` [N m].

    Returns
    -------
    tuple of float
        :math:`s_{k+1}`.

    Raises
    ------
    TypeError, ValueError
        If ``x`` or ``u`` is not finite or of the wrong kind, or ``state`` has the wrong length,
        or the inputs are finite but so large that the next state overflows (never a state of
        inf or NaN that would poison every later estimate).

    Examples
    --------
    The sample loop as pure functions: a DOb with its pole at 0.9 on a constant 0.01 N m load
    (its error shrinks by the pole every sample, eq. 12):

    >>> import numpy as np
    >>> from hpdob import ServoModel, design_observer, estimate, initial_state, update
    >>> model = ServoModel(J=2.8e-4).discretize(1e-3)
    >>> dob = design_observer(model, order=0, poles=[0.9])
    >>> state, x = initial_state(dob), np.zeros(2)
    >>> for k in range(60):
    ...     tau_hat = estimate(dob, state, x)
    ...     state = update(dob, state, x, 0.0)   # no control torque
    ...     x = model.step(x, 0.0, 0.01)         # the load acts on the plant
    >>> bool(abs(tau_hat - 0.01) < 0.01 * 0.9**50)
    True
    """
    system = as_system(observer)
    values = read_measurement(system, x)
    u = read_control(u)
    _check_state(system, state)
    return checked_next_state(system, state, values, u)
