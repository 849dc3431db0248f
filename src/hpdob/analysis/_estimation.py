r"""LTI views of an observer: its state-space model and its disturbance-estimation response.

The observer of order ``m`` (``docs/theory.md``) is the discrete LTI system

.. math::

    \hat z_{k+1} = M \hat z_k + K_x x_k + K_u u_k, \qquad
    \hat\tau_k = e_{m+1}^T \hat z_k - L_{m+1}^T x_k,

with inputs ``theta, omega, u`` and output ``tau_hat``. On its nominal plant
:math:`x_{k+1} = A_n x_k + B_n u_k - D_n \tau_k` its estimate answers the nominal disturbance
:math:`\tau_k` through the closed-form transfer function (derived in ``docs/analysis.md``)

.. math::

    Q(z) = \frac{\hat\tau(z)}{\tau(z)} = 1 - \frac{(z-1)^{m+1}}{\det(zI - M)},

whatever the control input ``u`` is: the DOb's "Q-filter". With bandwidth ``g`` every
pole sits at :math:`\lambda = e^{-g T_s}` and :math:`1 - Q = ((z-1)/(z-\lambda))^{m+1}`.

python-control is imported inside the functions that return its objects: ``import hpdob``
stays fast.
"""

from __future__ import annotations

import math

import numpy as np

from .._validation import ParameterTypeError, as_grid
from ..observers import as_system, estimation_frequency_response, nominal_loop, unit_root_polynomial
from ..observers import observer_matrices as _matrices

__all__ = [
    "estimation_response",
    "estimation_transfer",
    "observer_statespace",
]

#: Input and output names of :func:`observer_statespace`.
OBSERVER_INPUTS = ("theta", "omega", "u")
OBSERVER_OUTPUT = "tau_hat"


def observer_matrices(observer):
    """``(A, B, C, D)`` numpy arrays of the observer: ``(F, G, H, E)`` of its system."""
    return _matrices(as_system(observer))


def observer_statespace(observer):
    r"""The observer as a discrete python-control ``StateSpace`` (``dt = Ts``).

    ``A, B, C, D = F, G, H, E`` of its :class:`~hpdob.LinearObserver`: inputs its measured
    signals (``theta`` [rad], and ``omega`` [rad/s] for a state-measuring observer) and ``u``
    [N m]; outputs ``tau_hat`` [N m] (and ``omega_hat`` [rad/s] where the observer has one).
    For the order-m family the state is the auxiliary variables ``z1 ... z{m+1}`` and

    .. math::

        A = M,\quad B = [K_x,\ K_u],\quad C = e_{m+1}^T,\quad D = [-L_{m+1}^T,\ 0].

    Run from a zero initial state on the sequences of measurements and ``u`` it returns,
    sample by sample, what the runtime observer returns after ``reset()``.

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer

    Returns
    -------
    control.StateSpace

    Raises
    ------
    TypeError
        If ``observer`` is not an observer.

    References
    ----------
    Eqs. (11), (13) (DOb) and (20), (21), (23) (HPDOb) of the paper, in the matrix form of
    ``docs/theory.md``, section 4.

    Examples
    --------
    >>> from hpdob import DisturbanceObserver, ServoModel
    >>> obs = DisturbanceObserver(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    >>> sys = obs.to_statespace()
    >>> sys.input_labels, sys.output_labels, sys.dt
    (['theta', 'omega', 'u'], ['tau_hat'], 0.001)
    """
    return as_system(observer).to_statespace()


def estimation_transfer(observer, *, error: bool = False):
    r"""Disturbance-estimation transfer function of an observer on its nominal plant.

    .. math::

        Q(z) = \frac{\hat\tau(z)}{\tau_{dn}(z)},\qquad
        1 - Q(z) = \frac{\tau_{dn}(z) - \hat\tau(z)}{\tau_{dn}(z)}.

    :math:`\tau_{dn}` is the nominal (pseudo-)disturbance of eq. (8), held over each sample.
    For the order-m family the closed form is

    .. math:: Q(z) = \frac{\det(zI-M) - (z-1)^{m+1}}{\det(zI-M)},\qquad
              1 - Q(z) = \frac{(z-1)^{m+1}}{\det(zI-M)},

    which holds in open and in closed loop, for any control input. ``Q`` is the DOb's
    "Q-filter": strictly proper (the estimate lags the disturbance by at least one sample), unit
    gain at DC, and :math:`1 - Q` has a zero of multiplicity ``m + 1`` at ``z = 1``, so a
    polynomial disturbance of degree ``m`` is estimated without steady-state error. The
    derivation is in ``docs/analysis.md``. For an observer without this structure (``Q`` is
    then taken with ``u = 0``) the series connection of the nominal plant and the observer is
    reduced by :func:`control.minreal`.

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
    error : bool, optional
        Return the estimation-error response :math:`1 - Q` instead of ``Q``. Default False.

    Returns
    -------
    control.TransferFunction
        Discrete, ``dt = Ts``, input ``tau_dn``, output ``tau_hat`` (or ``tau_error``,
        :math:`\tau_{dn} - \hat\tau`).

    Raises
    ------
    TypeError
        If ``observer`` is not an observer.

    References
    ----------
    Error dynamics, eqs. (12) and (22) of the paper, generalised in ``docs/theory.md`` (sections
    5-6).

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer, estimation_transfer
    >>> design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=0, poles=[0.9])
    >>> Q = estimation_transfer(design)        # the DOb's Q-filter: k1 / (z - 1 + k1)
    >>> [round(float(c), 12) for c in Q.num[0][0]], [round(float(c), 12) for c in Q.den[0][0]]
    ([0.1], [1.0, -0.9])
    """
    import control

    system = as_system(observer)
    if not isinstance(error, bool):
        raise ParameterTypeError(f"error must be True or False, got {error!r}")
    output = "tau_error" if error else "tau_hat"
    dynamics = system.error_dynamics
    if dynamics is not None:
        P = np.asarray(dynamics.polynomial)
        E = unit_root_polynomial(dynamics.order)[::-1]
        if dynamics.zeros.size:
            E = np.convolve(E, np.real(np.poly(dynamics.zeros)))
        num = E if error else (P - E)[1:]  # the leading z^n cancels: Q is strictly proper
        return control.tf(num, P, system.Ts, inputs=["tau_dn"], outputs=[output])
    A, B, C, D = nominal_loop(system)
    Q = control.ss2tf(control.ss(A, B, C, D, system.Ts)).minreal(tol=1e-9)
    tf = (1 - Q) if error else Q
    return control.tf(tf.num, tf.den, system.Ts, inputs=["tau_dn"], outputs=[output])


def estimation_response(observer, frequency, *, error: bool = False) -> np.ndarray:
    r"""Complex frequency response of :func:`estimation_transfer` at ``frequency`` [Hz].

    :math:`Q(e^{j 2\pi f T_s})` (or :math:`1 - Q` with ``error=True``). For the order-m family it
    is evaluated in closed form in factored form, :math:`1 - Q = (z-1)^{m+1}/\prod_i (z -
    \lambda_i)` over the design's poles :math:`\lambda_i` (the roots of :math:`\det(zI-M)`),
    which keeps full relative accuracy near ``z = 1`` where the error is tiny; for other
    observers from the state-space model of observer and nominal plant (``u = 0``). No
    python-control objects: cheap inside parameter sweeps. Frequencies above the Nyquist
    frequency :math:`1/(2 T_s)` alias, as for any discrete system.

    Parameters
    ----------
    observer : LinearObserver, design or runtime observer
    frequency : float or array_like
        Frequencies [Hz], >= 0.
    error : bool, optional
        Return :math:`1 - Q` instead of ``Q``.

    Returns
    -------
    ndarray of complex, shape of ``numpy.atleast_1d(frequency)``

    Raises
    ------
    TypeError, ValueError
        For a wrong observer or negative, non-finite or no frequencies.

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer, estimation_response
    >>> design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    >>> complex(estimation_response(design, 0.0)[0])      # unit DC gain
    (1+0j)
    """
    system = as_system(observer)
    if not isinstance(error, bool):
        raise ParameterTypeError(f"error must be True or False, got {error!r}")
    f = as_grid(frequency, "frequency", "non-negative frequencies [Hz]", allow_zero=True)
    z = np.exp(2j * math.pi * f * system.Ts)
    return estimation_frequency_response(system, z, error)
