r"""Position-only disturbance observers of any truncation order: the angle is the only measurement.

The disturbance model is the order-m family's, :math:`\Delta^{m+1}\tau = 0` with :math:`\tau`
held over each sample (eq. 8), on the same exact ZOH model; the velocity is estimated along
with the disturbance. The observer is a full-order estimator of the augmented state

.. math::

    \xi_k = [\theta_k,\ \omega_k,\ \tau_{k-m},\ \dots,\ \tau_k]^T,\qquad
    \xi_{k+1} = A_a \xi_k + B_a u_k + e\,\Delta^{m+1}\tau_{k+1},\qquad \theta_k = c^T \xi_k,

in current form: with the prior :math:`s_k` (the observer's state, from the data up to
``k-1``) the estimate uses the angle of sample ``k``,

.. math::

    \hat\xi_k = s_k + K(\theta_k - s_{1,k}),\qquad
    \hat\tau_k = e^T \hat\xi_k,\quad \hat\omega_k = e_2^T \hat\xi_k,\qquad
    s_{k+1} = A_a \hat\xi_k + B_a u_k = (A_a - L c^T) s_k + L\theta_k + B_a u_k,

``L = A_a K``. The ``m + 3`` eigenvalues of :math:`A_a - L c^T` are placed exactly: its
characteristic polynomial is affine in ``L``, and in the variable :math:`w = z - 1` the gains
follow from a power-series division (``docs/theory.md``, section 9). Why a full-order estimator
and not the auxiliary variables of eq. (9) with the angle in place of the state: an
auxiliary-variable (reduced-order) observer passes the measured angle straight into
:math:`\hat\tau_k` with a large gain, so an encoder's quantisation reaches the estimate
unfiltered, which is the failure of the differenced velocity again; the full-order estimator
filters the angle through two poles of its own (``docs/analysis.md``, section 8).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from .._validation import ParameterValueError, _show, positive, readonly
from ._error_dynamics import (
    characteristic_basis,
    companion,
    extrapolation_weights,
    schur_cohn_stable,
    unit_root_polynomial,
)
from ._poles import fmt_complex as _fmt_complex
from ._poles import fmt_pole as _fmt_pole
from ._poles import validate_poles as _validate_poles
from ._realised import POLE_TOLERANCE, check_realised, polynomial_from_fractions
from ._system import ErrorDynamics, LinearObserver, _Designed

__all__ = ["PositionObserverDesign", "augmented_model", "design_position_observer"]


def augmented_model(model, order: int) -> tuple[np.ndarray, np.ndarray]:
    r"""``(A_a, B_a)`` of the augmented state :math:`[\theta, \omega, \tau_{k-m}..\tau_k]`.

    .. math::

        A_a = \begin{bmatrix} A & -D\,e^T \\ 0 & C_m \end{bmatrix},\qquad
        B_a = \begin{bmatrix} B \\ 0 \end{bmatrix},

    with :math:`A, B, D` the nominal ZOH model (eq. 8), ``e`` the last unit vector (the plant
    sees the newest disturbance :math:`\tau_k`) and :math:`C_m` the companion matrix of
    :math:`(z-1)^{m+1}` (shift of the history, extrapolation weights in its last row).
    """
    n = order + 3
    A, B, D = (np.asarray(a, dtype=float) for a in (model.A, model.B, model.D))
    Aa = np.zeros((n, n))
    Aa[:2, :2] = A
    Aa[:2, -1] = -D
    Aa[2:, 2:] = companion(order)
    Ba = np.zeros(n)
    Ba[:2] = B
    return Aa, Ba


def _shifted_polynomial(poles: np.ndarray, bandwidths) -> np.ndarray:
    r"""Ascending coefficients in :math:`w = z - 1` of :math:`\prod_i (z - p_i)`.

    With ``bandwidths`` (one per pole, or None) the roots :math:`p_i - 1 = \mathrm{expm1}(-g_i
    T_s)` are formed without cancellation.
    """
    roots = np.asarray(bandwidths if bandwidths is not None else poles - 1.0)
    coefficients = np.poly(roots)
    return np.real(coefficients)[::-1].copy()


def _position_gains(model, m: int, shifted: np.ndarray) -> np.ndarray:
    r"""Predictor gain ``L`` (length m + 3) placing the roots of ``shifted`` (ascending in w).

    :math:`\det(zI - A_a + L c^T) = \delta(z) R(z) - n(z) S(z)` with :math:`\delta =
    (z-1)^{m+1}`, :math:`R = (z-1)(z-a_{22}) + L_\theta (z - a_{22}) + a_{12} L_\omega`,
    :math:`n(z) = d_1 z + a_{12} d_2 - a_{22} d_1` (the plant's numerator) and
    :math:`S = \sum_j L_{\tau,j} q_j(z)`. In :math:`w = z - 1` the first ``m + 1``
    coefficients give :math:`S = -P/n \bmod w^{m+1}` and the last two give
    :math:`L_\theta, L_\omega` (``docs/theory.md``, section 9).
    """
    A, D = np.asarray(model.A), np.asarray(model.D)
    a01, a11, d0, d1 = float(A[0, 1]), float(A[1, 1]), float(D[0]), float(D[1])
    beta = 1.0 - a11  # b_n Ts / J_n to first order; exactly 0 for b_n = 0
    nu = d0 * beta + a01 * d1  # n(1) > 0
    S = np.zeros(m + 1)
    previous = 0.0
    for j in range(m + 1):  # power-series division -P(w) / (nu + d0 w)
        previous = (-shifted[j] - d0 * previous) / nu
        S[j] = previous
    L_theta = shifted[m + 2] - beta
    L_omega = (shifted[m + 1] + d0 * S[m] - L_theta * beta) / a01
    # S(z) = S(w = z - 1): Horner in (z - 1), ascending coefficients in z.
    Sz = np.zeros(m + 1)
    for j in range(m, -1, -1):
        Sz = np.concatenate([[0.0], Sz[:-1]]) - Sz  # times (z - 1)
        Sz[0] += S[j]
    L_tau = np.linalg.solve(characteristic_basis(m), Sz)
    return np.concatenate([[L_theta, L_omega], L_tau])


def _current_gain(model, m: int, L: np.ndarray) -> np.ndarray:
    r"""``K`` with :math:`A_a K = L`, solved through the structure of :math:`A_a`."""
    A, D = np.asarray(model.A), np.asarray(model.D)
    p = extrapolation_weights(m)
    L_tau = L[2:]
    K_tau = np.empty(m + 1)
    K_tau[1:] = L_tau[:-1]  # the shift rows of C_m
    K_tau[0] = (L_tau[-1] - float(p[1:] @ K_tau[1:])) / p[0]  # p_1 = (-1)^m
    v = L[:2] + D * K_tau[-1]
    K_omega = v[1] / A[1, 1]
    K_theta = v[0] - A[0, 1] * K_omega
    return np.concatenate([[K_theta, K_omega], K_tau])


def realised_polynomial(F: np.ndarray, m: int) -> list:
    r"""Exact ascending coefficients (Fractions) of :math:`\det(zI - F)` for the double-precision
    state matrix ``F`` of a position-only observer of order ``m``.

    ``F`` equals :math:`A_a` except in its first column, :math:`e_1 - L`, so the affine formula
    :math:`\delta R - n S` holds with the realised :math:`L = e_1 - F e_1` and the realised
    plant entries, all read from ``F`` as exact rationals.
    """
    f = [[Fraction(float(v)) for v in row] for row in F]
    a01, a11 = f[0][1], f[1][1]
    d0, d1 = -f[0][-1], -f[1][-1]
    L_theta, L_omega = 1 - f[0][0], -f[1][0]
    L_tau = [-f[2 + j][0] for j in range(m + 1)]
    delta = [int(c) for c in unit_root_polynomial(m)]
    # R(z) = (z - 1)(z - a11) + L_theta (z - a11) + a01 L_omega, ascending
    R = [a11 - L_theta * a11 + a01 * L_omega, -(1 + a11) + L_theta, Fraction(1)]
    Q = characteristic_basis(m)
    S = [sum((int(Q[i, j]) * L_tau[j] for j in range(m + 1)), Fraction(0)) for i in range(m + 1)]
    n = [a01 * d1 - a11 * d0, d0]
    P = [Fraction(0)] * (m + 4)
    for i, a in enumerate(delta):
        for j, b in enumerate(R):
            P[i + j] += a * b
    for i, a in enumerate(n):
        for j, b in enumerate(S):
            P[i + j] -= a * b
    return P


@dataclass(frozen=True, eq=False)
class PositionObserverDesign(_Designed):
    r"""A synthesised position-only disturbance observer of truncation order ``order``.

    Built by :func:`hpdob.design_observer` with ``measurement="position"``; every array
    attribute is read-only.

    Attributes
    ----------
    model : DiscreteServoModel
        The nominal discrete model (:math:`A_{Dn}, B_{Dn}, D_{Dn}`).
    order : int
        Truncation order ``m`` of the disturbance model :math:`\Delta^{m+1}\tau = 0`.
    poles : ndarray, shape (order + 3,)
        Requested eigenvalues of the estimation-error matrix (float if all real, else
        complex). From bandwidths: the ``m + 1`` disturbance poles, then the two velocity
        poles.
    bandwidth : float or None
        Disturbance bandwidth ``g`` [rad/s] if the poles came from bandwidths.
    velocity_bandwidth : float or None
        Bandwidth ``g_v`` [rad/s] of the two position/velocity poles, if they came from one.
    gains : ndarray, shape (order + 3,)
        Current-form gain ``K``: :math:`\hat\xi_k = s_k + K(\theta_k - s_{1,k})`.
    predictor_gains : ndarray, shape (order + 3,)
        ``L`` with :math:`s_{k+1} = (A_a - L c^T) s_k + L\theta_k + B_a u_k`
        (:math:`L = A_a K` to rounding).
    augmented_matrix : ndarray, shape (order + 3, order + 3)
        :math:`A_a` (:func:`augmented_model`).
    error_matrix : ndarray, shape (order + 3, order + 3)
        :math:`A_a - L c^T`: the prior estimation error obeys
        :math:`\epsilon_{k+1} = (A_a - L c^T)\epsilon_k + e\,\Delta^{m+1}\tau_{k+1}`.
    realised_poles : ndarray, shape (order + 3,)
        The eigenvalues the gains, rounded to doubles, really place (roots of the exact
        characteristic polynomial of ``error_matrix``), paired with ``poles``; within
        ``pole_tolerance (1 - |p|)`` of them (:func:`hpdob.design_observer`).
    system : LinearObserver
        The observer as the linear system every consumer runs: measures ``("theta",)``,
        outputs ``("tau_hat", "omega_hat")``, ``F = A_a - L c^T``, ``G = [L, B_a]``,
        ``H = [e^T - K_\tau c^T; e_2^T - K_\omega c^T]``, ``E = [[K_\tau, 0], [K_\omega, 0]]``,
        ``N`` the constant history ``[\theta_0, \omega_0, \tau_0, \dots, \tau_0]``.
    """

    model: object
    order: int
    poles: np.ndarray
    bandwidth: float | None
    velocity_bandwidth: float | None
    gains: np.ndarray
    predictor_gains: np.ndarray
    augmented_matrix: np.ndarray
    error_matrix: np.ndarray
    system: LinearObserver = field(repr=False)
    realised_poles: np.ndarray = field(default=None, repr=False)

    #: What the observer measures.
    measurement = "position"
    #: Position-only observers have no gain direction (the angle is the only measurement).
    gain_direction = None

    def __repr__(self) -> str:
        poles = ", ".join(_fmt_pole(p) for p in np.atleast_1d(self.poles))
        return (
            f"PositionObserverDesign(order={self.order}, poles=[{poles}], "
            f"Ts={self.model.Ts:g}, J_n={self.model.J:g}, b_n={self.model.b:g})"
        )


_NAMES = {0: "position-only DOb (order 0)", 1: "position-only HPDOb (order 1)"}


def design_position_observer(
    model,
    m: int,
    *,
    poles=None,
    bandwidth=None,
    velocity_bandwidth=None,
    pole_tolerance=POLE_TOLERANCE,
) -> PositionObserverDesign:
    """The position-only observer of order ``m`` (validated arguments; see
    :func:`hpdob.design_observer`, which is the public entry point)."""
    n = m + 3
    Ts = model.Ts
    if (poles is None) == (bandwidth is None):
        given = "both" if poles is not None else "neither"
        raise ParameterValueError(
            f"give exactly one of poles (order + 3 = {n} eigenvalues) or "
            f"bandwidth (rad/s); got {given}"
        )
    if bandwidth is not None:
        g = positive(bandwidth, "bandwidth", "a positive finite observer bandwidth [rad/s]")
        if velocity_bandwidth is None:
            gv = g
        else:
            gv = positive(
                velocity_bandwidth,
                "velocity_bandwidth",
                "a positive finite bandwidth of the velocity poles [rad/s]",
            )
        rates = np.array([g] * (m + 1) + [gv] * 2)
        placed = np.exp(-rates * Ts)
        shifted = _shifted_polynomial(placed, np.expm1(-rates * Ts))
        g_out, gv_out = g, gv
        if not np.all(placed < 1.0):
            raise ParameterValueError(
                f"bandwidth={g!r} and velocity_bandwidth={gv!r} rad/s are too small for "
                f"Ts={Ts!r} s: a pole exp(-g Ts) rounds to 1"
            )
    else:
        if velocity_bandwidth is not None:
            raise ParameterValueError(
                "velocity_bandwidth goes with bandwidth, not with poles (the poles give every "
                f"eigenvalue, order + 3 = {n}); got poles={_show(poles)} and "
                f"velocity_bandwidth={velocity_bandwidth!r}"
            )
        placed = _validate_poles(poles, n, f"order + 3 = {n}", m)
        shifted = _shifted_polynomial(np.asarray(placed), None)
        g_out = gv_out = None
    L = _position_gains(model, m, shifted)
    K = _current_gain(model, m, L)
    Aa, Ba = augmented_model(model, m)
    F = Aa.copy()
    F[:, 0] -= L
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(K))):
        raise ParameterValueError(
            f"the gains of the order-{m} position-only observer overflow for poles "
            f"{_show(np.asarray(placed))}"
        )
    exact = realised_polynomial(F, m)
    asked = (
        f"bandwidth={g_out!r}, velocity_bandwidth={gv_out!r} rad/s"
        if g_out is not None
        else f"poles={_show(poles)}"
    )
    if not schur_cohn_stable(exact):
        raise ParameterValueError(
            f"{asked} cannot be realised for a position-only observer of order {m} in double "
            "precision: with the gains rounded to doubles the error matrix is not stable (an "
            "eigenvalue has |z| >= 1, exact Schur-Cohn test); high orders and repeated poles "
            "near 1 are too ill-conditioned. Use a lower order, a higher bandwidth or distinct "
            "poles"
        )
    numbers, e = polynomial_from_fractions(exact)
    realised = check_realised(
        numbers,
        e,
        np.asarray(placed),
        pole_tolerance,
        asked=asked,
        what=f"a position-only observer of order {m}",
    )
    a01, a11 = float(Aa[0, 1]), float(Aa[1, 1])
    trace = 1.0 - K[0] + a11 - a01 * K[1]
    zeros = np.roots([1.0, -trace, (1.0 - K[0]) * a11])
    if np.all(np.imag(zeros) == 0.0):
        zeros = np.real(zeros)
    H = np.zeros((2, n))
    H[0, -1] = 1.0
    H[0, 0] = -K[-1]
    H[1, 1] = 1.0
    H[1, 0] = -K[1]
    E = np.array([[K[-1], 0.0], [K[1], 0.0]])
    N = np.zeros((n, 3))
    N[0, 0] = N[1, 1] = 1.0
    N[2:, 2] = 1.0
    poles_out = readonly(np.array(placed))
    text = ", ".join(_fmt_complex(p) for p in poles_out)
    if g_out is not None:
        text += f" (bandwidth {g_out!r} rad/s, velocity bandwidth {gv_out!r} rad/s)"
    info = (
        ("nominal model", f"J_n = {model.J!r} kg m^2, b_n = {model.b!r} N m s/rad"),
        ("sampling period", f"Ts = {Ts!r} s"),
        ("order", f"{m} (position-only, Delta^(m+1) tau = 0, docs/theory.md section 9)"),
        ("measurement", "the angle only; the velocity is estimated (omega_hat)"),
        ("poles", text),
        ("state", "prior estimate of [theta, omega, tau_(k-m), ..., tau_k]"),
    )
    system = LinearObserver(
        F=F,
        G=np.column_stack([L, Ba]),
        H=H,
        E=E,
        N=N,
        Ts=Ts,
        measures=("theta",),
        outputs=("tau_hat", "omega_hat"),
        model=model,
        name=_NAMES.get(m, f"position-only order-{m} DOb"),
        error_dynamics=ErrorDynamics(
            m, poles_out, [float(c) for c in reversed(exact)], zeros=zeros
        ),
        info=info,
    )
    return PositionObserverDesign(
        model=model,
        order=m,
        poles=poles_out,
        bandwidth=g_out,
        velocity_bandwidth=gv_out,
        gains=readonly(K),
        predictor_gains=readonly(L),
        augmented_matrix=readonly(Aa),
        error_matrix=readonly(F.copy()),
        system=system,
        realised_poles=readonly(realised),
    )
