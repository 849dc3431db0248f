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
from ..observers._runtime import as_design
from ..observers._synthesis import ObserverDesign, characteristic_polynomial, unit_root_polynomial

__all__ = [
    "estimation_response",
    "estimation_transfer",
    "observer_statespace",
]

#: Input and output names of :func:`observer_statespace`.
OBSERVER_INPUTS = ("theta", "omega", "u")
OBSERVER_OUTPUT = "tau_hat"


def observer_matrices(design: ObserverDesign):
    """``(A, B, C, D)`` numpy arrays of the observer with inputs ``theta, omega, u``."""
    n = design.order + 1
    A = np.array(design.error_matrix, dtype=float)
    B = np.column_stack([design.state_input, design.control_input])
    C = np.zeros((1, n))
    C[0, -1] = 1.0
    D = np.array([[-design.gains[-1, 0], -design.gains[-1, 1], 0.0]])
    return A, B, C, D


def observer_statespace(observer):
    r"""The observer as a discrete python-control ``StateSpace`` (``dt = Ts``).

    State :math:`\hat z` (``z1 ... z{m+1}``), inputs ``theta`` [rad], ``omega`` [rad/s], ``u``
    [N m], output ``tau_hat`` [N m]:

    .. math::

        A = M,\quad B = [K_x,\ K_u],\quad C = e_{m+1}^T,\quad D = [-L_{m+1}^T,\ 0].

    Run from a zero initial state on the sequences ``x_k, u_k`` it returns, sample by sample,
    what :class:`~hpdob.DisturbanceObserver` returns after ``reset()``.

    Parameters
    ----------
    observer : DisturbanceObserver or ObserverDesign

    Returns
    -------
    control.StateSpace

    Raises
    ------
    TypeError
        If ``observer`` is neither a ``DisturbanceObserver`` nor an ``ObserverDesign``.

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
    import control

    design = as_design(observer)
    A, B, C, D = observer_matrices(design)
    return control.ss(
        A,
        B,
        C,
        D,
        design.model.Ts,
        inputs=list(OBSERVER_INPUTS),
        outputs=[OBSERVER_OUTPUT],
        states=[f"z{i + 1}" for i in range(design.order + 1)],
    )


def _polynomials(design: ObserverDesign) -> tuple[np.ndarray, np.ndarray]:
    """``(P, E)``: ``det(zI - M)`` and ``(z - 1)^{m+1}``, highest power first."""
    m = design.order
    P = characteristic_polynomial(design.k)
    E = unit_root_polynomial(m)[::-1]
    return P, E


def estimation_transfer(observer, *, error: bool = False):
    r"""Closed-form disturbance-estimation transfer function of an observer on its nominal plant.

    .. math::

        Q(z) = \frac{\hat\tau(z)}{\tau_{dn}(z)} = \frac{\det(zI-M) - (z-1)^{m+1}}{\det(zI-M)},
        \qquad
        1 - Q(z) = \frac{\tau_{dn}(z) - \hat\tau(z)}{\tau_{dn}(z)} = \frac{(z-1)^{m+1}}{\det(zI-M)}.

    :math:`\tau_{dn}` is the nominal (pseudo-)disturbance of eq. (8), held over each sample; the
    response holds in open and in closed loop, for any control input. ``Q`` is the DOb's
    "Q-filter": strictly proper (the estimate lags the disturbance by at least one sample), unit
    gain at DC, and :math:`1 - Q` has a zero of multiplicity ``m + 1`` at ``z = 1``, so a
    polynomial disturbance of degree ``m`` is estimated without steady-state error. The
    derivation is in ``docs/analysis.md``.

    Parameters
    ----------
    observer : DisturbanceObserver or ObserverDesign
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
        If ``observer`` is neither a ``DisturbanceObserver`` nor an ``ObserverDesign``.

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

    design = as_design(observer)
    if not isinstance(error, bool):
        raise ParameterTypeError(f"error must be True or False, got {error!r}")
    P, E = _polynomials(design)
    if error:
        num, output = E, "tau_error"
    else:
        num = (P - E)[1:]  # the leading z^{m+1} cancels: Q is strictly proper
        output = "tau_hat"
    return control.tf(num, P, design.model.Ts, inputs=["tau_dn"], outputs=[output])


def estimation_response(observer, frequency, *, error: bool = False) -> np.ndarray:
    r"""Complex frequency response of :func:`estimation_transfer` at ``frequency`` [Hz].

    :math:`Q(e^{j 2\pi f T_s})` (or :math:`1 - Q` with ``error=True``), evaluated in closed form
    with numpy in factored form, :math:`1 - Q = (z-1)^{m+1}/\prod_i (z - \lambda_i)` over the
    design's poles :math:`\lambda_i` (the roots of :math:`\det(zI-M)`), which keeps full relative
    accuracy near ``z = 1`` where the error is tiny. No python-control objects: cheap inside
    parameter sweeps. Frequencies above the Nyquist frequency :math:`1/(2 T_s)` alias, as for any
    discrete system.

    Parameters
    ----------
    observer : DisturbanceObserver or ObserverDesign
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
    design = as_design(observer)
    f = as_grid(frequency, "frequency", "non-negative frequencies [Hz]", allow_zero=True)
    z = np.exp(2j * math.pi * f * design.model.Ts)
    # Factored forms: (z - 1)^(m+1) / prod(z - p_i). Expanded polynomials would cancel
    # catastrophically near z = 1, where 1 - Q is tiny.
    ratio = (z - 1.0) ** (design.order + 1)
    for pole in np.atleast_1d(design.poles):
        ratio = ratio / (z - pole)
    return ratio if error else 1.0 - ratio
