r"""The linear extended state observer (ESO) of active disturbance rejection control.

ADRC (Gao 2003) writes the servo as :math:`\ddot\theta = f + b_0 u` with :math:`b_0 = 1/J_n` and
lumps everything else -- friction, load, model error -- into the "total disturbance" ``f``,
which it extends the state with. With ``extended_order = m`` the disturbance model is
:math:`f^{(m+1)} = 0` (``m = 0``: the classical ESO, ``f`` constant; ``m >= 1``: the
generalised ESO of Miklosovic, Radke & Gao 2006), so the state is
:math:`x = [\theta, \omega, f, \dot f, \dots, f^{(m)}]` (``n = m + 3`` entries) and

.. math::

    \dot x = A_c x + B_c u, \qquad \theta = C x,

a chain of integrators with ``u`` entering the velocity. It is discretised by zero-order hold
(:math:`\Phi = e^{A_c T_s}`, :math:`\Gamma = \int_0^{T_s} e^{A_c s} B_c\,ds`) and observed from
the angle alone, with all ``n`` discrete poles at :math:`\beta = e^{-\omega_o T_s}` (one
bandwidth ``omega_o``), in the *current* form

.. math::

    \hat x_k = \bar x_k + L(\theta_k - C\bar x_k),\qquad
    \bar x_{k+1} = \Phi\hat x_k + \Gamma u_k

(the estimate uses :math:`\theta_k`; error poles :math:`\mathrm{eig}(\Phi - \Phi L C)`) or the
*predictive* form

.. math:: \hat x_{k+1} = \Phi\hat x_k + \Gamma u_k + L_p(\theta_k - C\hat x_k)

(the estimate of sample ``k`` uses measurements up to ``k - 1``; poles
:math:`\mathrm{eig}(\Phi - L_p C)`), as in Miklosovic, Radke & Gao. The gains come from
Ackermann's formula with the characteristic polynomial :math:`(z - \beta)^n` (exact for the
repeated pole). Its estimate is reported as the DOb's nominal disturbance,
:math:`\hat\tau = -J_n\hat f - b_n\hat\omega` [N m], comparable with :math:`\tau_{dn}` of eq. (3),
since the nominal model :math:`J_n\ddot\theta = u - b_n\omega - \tau_{dn}` gives
:math:`f = -(\tau_{dn} + b_n\omega)/J_n`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._validation import (
    ParameterValueError,
    as_int,
    check_choice,
    nonnegative,
    positive,
    readonly,
)
from ..models import DiscreteServoModel, as_discrete_model
from ._error_dynamics import schur_cohn_stable
from ._realised import POLE_TOLERANCE, check_realised, matrix_characteristic_polynomial
from ._runtime import _DesignedObserver
from ._system import LinearObserver, _Designed

__all__ = ["ESO_FORMS", "ESODesign", "ExtendedStateObserver", "design_eso", "observer_gain", "zoh"]

#: The two discrete implementations of Miklosovic, Radke & Gao (2006).
ESO_FORMS = ("current", "predictive")
#: Largest extended order: Ackermann's formula loses accuracy on longer integrator chains.
MAX_EXTENDED_ORDER = 4


def zoh(A: np.ndarray, B: np.ndarray, Ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation ``(Phi, Gamma)`` of ``x' = A x + B u`` (``B`` a
    column), from the matrix exponential of the augmented matrix."""
    from scipy.linalg import expm

    n = A.shape[0]
    augmented = np.zeros((n + 1, n + 1))
    augmented[:n, :n] = A
    augmented[:n, n] = B
    E = expm(augmented * Ts)
    return E[:n, :n], E[:n, n]


def observer_gain(Phi: np.ndarray, C: np.ndarray, poles, *, scale=None) -> np.ndarray:
    r"""Ackermann's formula for the observer gain: :math:`L_p = p(\Phi)\,O^{-1} e_n` places
    :math:`\mathrm{eig}(\Phi - L_p C)` at the roots of ``p`` (``poles``), with ``O`` the
    observability matrix of :math:`(\Phi, C)`. Exact for repeated poles.

    ``scale`` (a vector ``d``) computes it in the coordinates :math:`\tilde x = \mathrm{diag}(d)
    x`, where the integrator chains of a sampled model are well conditioned (with
    :math:`d_i = T_s^i` the ZOH of :math:`i`-fold integration has entries :math:`1/(j-i)!`
    instead of :math:`T_s^{j-i}/(j-i)!`), and maps the gain back.
    """
    if scale is not None:
        d = np.asarray(scale, dtype=float)
        scaled = observer_gain(d[:, None] * Phi / d[None, :], C / d[None, :], poles)
        return scaled / d
    n = Phi.shape[0]
    observability = np.vstack([C @ np.linalg.matrix_power(Phi, i) for i in range(n)])
    coefficients = np.real(np.poly(np.asarray(poles)))  # highest power first
    p_Phi = np.zeros((n, n))
    for c in coefficients:
        p_Phi = p_Phi @ Phi + c * np.eye(n)
    e_n = np.zeros(n)
    e_n[-1] = 1.0
    return p_Phi @ np.linalg.solve(observability, e_n)


@dataclass(frozen=True, eq=False)
class ESODesign(_Designed):
    """A linear extended state observer (immutable); see :func:`design_eso`.

    Attributes
    ----------
    model : DiscreteServoModel
        Nominal model (``J_n`` gives :math:`b_0 = 1/J_n`; ``b_n`` enters the reported estimate).
    bandwidth : float
        Observer bandwidth :math:`\\omega_o` [rad/s]; every pole at ``exp(-bandwidth Ts)``.
    extended_order : int
        ``m``: the disturbance model :math:`f^{(m+1)} = 0`.
    form : {"current", "predictive"}
    Phi, Gamma : ndarray
        ZOH discretisation of the extended model.
    gain : ndarray
        ``L`` (current form) or ``L_p`` (predictive form).
    poles : ndarray
        The ``m + 3`` requested poles.
    realised_poles : ndarray
        The eigenvalues of ``system.F`` as the gains rounded to doubles place them (roots of
        its exact characteristic polynomial), within ``pole_tolerance (1 - |p|)`` of ``poles``.
    system : LinearObserver
        The observer as a linear system (measures ``theta``; outputs ``tau_hat``,
        ``omega_hat``).
    """

    model: DiscreteServoModel
    bandwidth: float
    extended_order: int
    form: str
    Phi: np.ndarray = field(repr=False)
    Gamma: np.ndarray = field(repr=False)
    gain: np.ndarray = field(repr=False)
    poles: np.ndarray = field(repr=False)
    system: LinearObserver = field(repr=False)
    realised_poles: np.ndarray = field(default=None, repr=False)


def design_eso(
    model: DiscreteServoModel,
    *,
    bandwidth: float,
    extended_order: int = 0,
    form: str = "current",
    pole_tolerance: float | None = POLE_TOLERANCE,
) -> ESODesign:
    r"""Design the linear ESO of ADRC on a nominal model (Gao 2003; Miklosovic, Radke & Gao
    2006).

    Parameters
    ----------
    model : DiscreteServoModel or control.TransferFunction or control.StateSpace
        Nominal discrete model, ``ServoModel(J_n, b_n).discretize(Ts)``. A sampled python-control
        servo (``control.c2d(sys, Ts)``) is read by :meth:`DiscreteServoModel.from_lti`.
    bandwidth : float
        Observer bandwidth :math:`\omega_o` [rad/s], positive: all ``extended_order + 3``
        discrete poles at :math:`e^{-\omega_o T_s}`.
    extended_order : int, optional
        ``m >= 0``: the total disturbance is extended by ``m + 1`` states with
        :math:`f^{(m+1)} = 0`. 0 (default) is the classical ESO, 1 the generalised ESO with a
        ramp-like disturbance. At most 4.
    form : {"current", "predictive"}, optional
        The discrete implementation (see the module docstring). Default ``"current"``.
    pole_tolerance : float or None, optional
        Refuse a design whose realised poles (the eigenvalues of the observer's state matrix
        as rounded to doubles, from its exact characteristic polynomial) lie further than
        ``pole_tolerance (1 - beta)`` from the requested pole ``beta``. Default 0.05; None
        accepts any design that is stable (decided exactly). The ``m + 3``-fold pole splits by
        about ``eps^(1/(m+3))`` times the conditioning of the chain: at ``Ts = 1 ms``,
        ``extended_order=2`` at 5 rad/s realises ``|z| = 0.9958`` for 0.9950 and is refused,
        ``extended_order=4`` at 5 rad/s is unstable (``|z| = 1.0023``).

    Returns
    -------
    ESODesign

    Raises
    ------
    TypeError, ValueError
        Naming the parameter: a model that is not a ``DiscreteServoModel``, a non-positive or
        non-finite bandwidth, a negative or too large ``extended_order``, an unknown ``form``,
        a bandwidth whose pole rounds to 1 or whose realised poles are off by more than
        ``pole_tolerance`` (or, with None, unstable).

    References
    ----------
    Z. Gao, "Scaling and bandwidth-parameterization based controller tuning", American Control
    Conference, 2003. R. Miklosovic, A. Radke, Z. Gao, "Discrete implementation and
    generalization of the extended state observer", American Control Conference, 2006.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import ServoModel
    >>> from hpdob.observers import design_eso
    >>> eso = design_eso(ServoModel(2.8e-4).discretize(1e-3), bandwidth=200.0)
    >>> bool(np.allclose(np.linalg.eigvals(eso.system.F), np.exp(-0.2), atol=1e-4))
    True
    """
    model = as_discrete_model(model, "model")
    g = positive(bandwidth, "bandwidth", "a positive finite observer bandwidth [rad/s]")
    m = as_int(extended_order, "extended_order", "a non-negative integer", minimum=0)
    if m > MAX_EXTENDED_ORDER:
        raise ParameterValueError(
            f"extended_order must be at most {MAX_EXTENDED_ORDER} (Ackermann's formula on a "
            f"longer integrator chain is ill-conditioned), got {m}"
        )
    form = check_choice(form, "form", ESO_FORMS)
    if pole_tolerance is not None:
        pole_tolerance = nonnegative(pole_tolerance, "pole_tolerance", "a fraction >= 0 or None")
    J_n, b_n, Ts = model.J, model.b, model.Ts
    n = m + 3
    A_c = np.eye(n, k=1)  # theta' = omega, omega' = f (+ b0 u), f' = f', ...
    B_c = np.zeros(n)
    B_c[1] = 1.0 / J_n
    Phi, Gamma = zoh(A_c, B_c, Ts)
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    beta = math.exp(-g * Ts)
    if not beta < 1.0:
        raise ParameterValueError(
            f"bandwidth={g!r} rad/s is too small for Ts={Ts!r} s: the pole exp(-bandwidth Ts) "
            "rounds to 1"
        )
    poles = np.full(n, beta)
    L_p = observer_gain(Phi, C, poles, scale=Ts ** np.arange(n))
    c_tau = np.zeros(n)  # tau_hat = -J_n f_hat - b_n omega_hat
    c_tau[1], c_tau[2] = -b_n, -J_n
    e_omega = np.zeros(n)
    e_omega[1] = 1.0
    outputs = np.vstack([c_tau, e_omega])
    if form == "current":
        L = np.linalg.solve(Phi, L_p)  # Phi (I - L C) = Phi - L_p C: the same poles
        I_LC = np.eye(n) - np.outer(L, C[0])
        F, G_theta = Phi @ I_LC, Phi @ L
        H, E_theta = outputs @ I_LC, outputs @ L
        gain = L
    else:
        F, G_theta = Phi - np.outer(L_p, C[0]), L_p
        H, E_theta = outputs, np.zeros(2)
        gain = L_p
    realised = _realised(F, poles, pole_tolerance, g, m)
    N = np.zeros((n, 3))  # the state of an observer converged on tau0 at (theta0, omega0)
    N[0, 0] = 1.0
    N[1, 1] = 1.0
    N[2, 1], N[2, 2] = -b_n / J_n, -1.0 / J_n  # f0 = -(tau0 + b_n omega0) / J_n
    kind = "ESO" if m == 0 else f"generalised ESO (m={m})"
    system = LinearObserver(
        F=F,
        G=np.column_stack([G_theta, Gamma]),
        H=H,
        E=np.column_stack([E_theta, np.zeros(2)]),
        N=N,
        Ts=Ts,
        measures=("theta",),
        outputs=("tau_hat", "omega_hat"),
        model=model,
        name=f"{kind}, {form} form",
        info=(
            ("observer", f"linear {kind} of ADRC, {form} form (Miklosovic, Radke & Gao 2006)"),
            ("nominal model", f"J_n = {J_n!r} kg m^2 (b0 = 1/J_n), b_n = {b_n!r} N m s/rad"),
            ("sampling period", f"Ts = {Ts!r} s"),
            ("poles", f"{n} x {beta!r} (bandwidth {g!r} rad/s)"),
            ("estimate", "tau_hat = -J_n f_hat - b_n omega_hat [N m]"),
        ),
    )
    return ESODesign(
        model=model,
        bandwidth=g,
        extended_order=m,
        form=form,
        Phi=readonly(Phi),
        Gamma=readonly(Gamma),
        gain=readonly(gain),
        poles=readonly(poles),
        system=system,
        realised_poles=readonly(realised),
    )


def _realised(F, poles, pole_tolerance, bandwidth, m) -> np.ndarray:
    """The realised poles of the ESO's state matrix ``F`` (checked: see :func:`design_eso`)."""
    numbers, e = matrix_characteristic_polynomial(F)
    asked = f"bandwidth={bandwidth!r} rad/s"
    what = f"an ESO of extended order {m}"
    if pole_tolerance is None and not schur_cohn_stable(numbers):
        raise ParameterValueError(
            f"{asked} cannot be realised for {what} in double precision: with the gains "
            "rounded to doubles the observer is not stable (an eigenvalue has |z| >= 1, exact "
            "Schur-Cohn test); use a lower extended order or a higher bandwidth"
        )
    return check_realised(numbers, e, poles, pole_tolerance, asked=asked, what=what)


class ExtendedStateObserver(_DesignedObserver):
    """The linear ESO of ADRC as a runtime object (see :func:`design_eso`).

    The sample loop is that of the position-only observers::

        tau_hat = obs.estimate(theta_k)      # [N m]; obs.velocity is omega_hat_k [rad/s]
        u_k = u_outer + tau_hat
        obs.update(theta_k, u_k)

    Parameters
    ----------
    model : DiscreteServoModel
        Nominal discrete model.
    bandwidth : float
        Observer bandwidth [rad/s].
    extended_order : int, optional
        ``m`` of :math:`f^{(m+1)} = 0`. Default 0.
    form : {"current", "predictive"}, optional
        Default ``"current"``.
    pole_tolerance : float or None, optional
        As for :func:`design_eso` (default 0.05).

    Attributes
    ----------
    design : ESODesign

    Examples
    --------
    >>> from hpdob import ExtendedStateObserver, ServoModel
    >>> eso = ExtendedStateObserver(ServoModel(2.8e-4).discretize(1e-3), bandwidth=200.0)
    >>> eso.reset(x0=(0.0, 0.0), tau0=0.01)
    >>> round(eso.estimate(0.0), 12), round(eso.velocity, 12)
    (0.01, 0.0)
    """

    __slots__ = ()

    def __init__(
        self, model, *, bandwidth, extended_order=0, form="current", pole_tolerance=POLE_TOLERANCE
    ):
        design = design_eso(
            model,
            bandwidth=bandwidth,
            extended_order=extended_order,
            form=form,
            pole_tolerance=pole_tolerance,
        )
        self._start(design)

    def __repr__(self) -> str:
        d = self._design
        return (
            f"ExtendedStateObserver(bandwidth={d.bandwidth:g}, extended_order={d.extended_order}, "
            f"form={d.form!r}, Ts={d.Ts:g}, J_n={d.model.J:g}, b_n={d.model.b:g})"
        )
