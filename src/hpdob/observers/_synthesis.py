r"""Unified synthesis of discrete disturbance observers of any truncation order.

Order ``m = 0`` is the conventional DOb (eqs. 9-13), ``m = 1`` the HPDOb (eqs. 14-24) and
``m >= 2`` the generalisation announced in the paper. With auxiliary variables
:math:`z_{i,k} = \tau_{k-(m+1-i)} + L_i^T x_k`, ``i = 1..m+1``, and the disturbance model
:math:`\Delta^{m+1}\tau = 0`, the observer is

.. math::

    \hat z_{k+1} = M \hat z_k + (G A - M G) x_k + G B u_k, \qquad
    \hat\tau_k = \hat z_{m+1,k} - L_{m+1}^T x_k,

where ``G`` stacks the gains :math:`L_i^T` as rows, :math:`M = C - k\,e_{m+1}^T`, ``C`` is the
companion matrix of :math:`(z-1)^{m+1}` (ones on the super-diagonal, last row the
extrapolation weights :math:`p_i = (-1)^{m+1-i}\binom{m+1}{i-1}`) and
:math:`k_i = L_i^T D_{Dn}`. The derivation is in ``docs/theory.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._validation import (
    ParameterValueError,
    _show,
    as_int,
    as_real_vector,
    check_choice,
    positive,
    readonly,
)
from ..models import DiscreteServoModel, as_discrete_model
from ._error_dynamics import (
    characteristic_basis,
    characteristic_polynomial,
    error_matrix,
    extrapolation_weights,
    schur_stable,
    unit_root_polynomial,
)
from ._poles import fmt_complex as _fmt_complex
from ._poles import fmt_pole as _fmt_pole
from ._poles import validate_poles as _validate_poles
from ._program import structured_program
from ._realised import POLE_TOLERANCE, finite_gains, realised_poles
from ._system import MEASUREMENTS, ErrorDynamics, LinearObserver, _Designed

__all__ = [
    "ObserverDesign",
    "characteristic_polynomial",
    "design_observer",
    "error_matrix",
    "extrapolation_weights",
]

#: Highest truncation order: binom(m+1, i) < 2**53 stays exact in double precision.
MAX_ORDER = 50
#: gain directions with |d^T D| <= _DEGENERATE * |d| |D| are rejected.
_DEGENERATE = 1e-8


def _show_k(k: np.ndarray) -> str:
    return np.array2string(np.asarray(k), threshold=6, precision=6, max_line_width=1_000_000)


@dataclass(frozen=True, eq=False)
class ObserverDesign(_Designed):
    r"""A synthesised disturbance observer of truncation order ``order`` (immutable).

    Built by :func:`design_observer`; every array attribute is read-only.

    Attributes
    ----------
    model : DiscreteServoModel
        The nominal discrete model (:math:`A_{Dn}, B_{Dn}, D_{Dn}`).
    order : int
        Truncation order ``m``: 0 conventional DOb, 1 HPDOb, ``m >= 2`` generalised.
    poles : ndarray, shape (order + 1,)
        Requested eigenvalues of the error matrix (float if all real, else complex).
    bandwidth : float or None
        Bandwidth ``g`` [rad/s] if the poles came from it (all at ``exp(-g Ts)``).
    gain_direction : ndarray, shape (2,)
        Direction ``d`` of every gain vector, ``L_i = k_i d / (d^T D_Dn)``.
    k : ndarray, shape (order + 1,)
        Scalar gains :math:`k_i = L_i^T D_{Dn}` (the paper's :math:`k_1, k_2` of eq. 25).
    gains : ndarray, shape (order + 1, 2)
        Row ``i`` is :math:`L_{i+1}^T`.
    error_matrix : ndarray, shape (order + 1, order + 1)
        :math:`M` of :math:`e_{k+1} = M e_k + [0,\dots,0,\Delta^{m+1}\tau_{k+1}]^T`
        (eqs. 12, 22).
    state_matrix, state_input, control_input : ndarray
        The observer recursion :math:`\hat z_{k+1} = M\hat z_k + K_x x_k + K_u u_k` with
        ``state_matrix = M``, ``state_input = K_x = G A - M G`` (shape (order+1, 2)) and
        ``control_input = K_u = G B`` (shape (order+1,)).
    system : LinearObserver
        The observer as the linear system every consumer runs (the observer protocol):
        ``F = M``, ``G = [K_x, K_u]``, ``H = e_{m+1}^T``, ``E = [-L_{m+1}^T, 0]``,
        ``N = [G, 1]``, with the companion structure kept in its program (unit shifts and
        integer extrapolation weights as exact terms; see :func:`structured_program`).
    realised_poles : ndarray, shape (order + 1,)
        The poles the gains rounded to doubles really place, paired with ``poles``.
    """

    model: DiscreteServoModel
    order: int
    poles: np.ndarray
    bandwidth: float | None
    gain_direction: np.ndarray
    k: np.ndarray
    gains: np.ndarray
    error_matrix: np.ndarray
    state_input: np.ndarray
    control_input: np.ndarray
    system: LinearObserver = field(repr=False)
    realised_poles: np.ndarray | None = field(default=None, repr=False)

    @property
    def state_matrix(self) -> np.ndarray:
        """Alias of :attr:`error_matrix`: the observer's own state matrix is ``M``."""
        return self.error_matrix

    def __repr__(self) -> str:
        poles = ", ".join(_fmt_pole(p) for p in np.atleast_1d(self.poles))
        return (
            f"ObserverDesign(order={self.order}, poles=[{poles}], "
            f"Ts={self.model.Ts:g}, J_n={self.model.J:g}, b_n={self.model.b:g})"
        )


def design_observer(
    model: DiscreteServoModel,
    *,
    order: int,
    poles=None,
    bandwidth: float | None = None,
    measurement: str = "state",
    velocity_bandwidth: float | None = None,
    gain_direction=None,
    pole_tolerance: float | None = POLE_TOLERANCE,
):
    r"""Synthesise an observer of truncation order ``order`` by eigenvalue placement.

    Two families share the disturbance model :math:`\Delta^{m+1}\tau = 0` (``tau`` held over
    each sample, eq. 8) and the exact ZOH model: ``measurement="state"`` (default) is the
    paper's observer, which measures angle and velocity; ``measurement="position"`` measures the
    angle only and estimates the velocity with the disturbance (``docs/theory.md``, section 9).

    Parameters
    ----------
    model : DiscreteServoModel or control.TransferFunction or control.StateSpace
        Nominal discrete model, e.g. ``ServoModel(J_n, b_n).discretize(Ts)``. A sampled
        python-control servo (``control.c2d(sys, Ts)``) is read by
        :meth:`DiscreteServoModel.from_lti`.
    order : int
        Truncation order ``m >= 0``: 0 is the conventional DOb (eqs. 9-13), 1 the HPDOb
        (eqs. 14-24), higher orders cancel disturbances whose samples are polynomials of
        degree ``m`` exactly.
    poles : sequence of complex, optional
        Desired eigenvalues of the error matrix, strictly inside the unit circle; complex ones
        in conjugate pairs; repeated poles are allowed. ``order + 1`` of them for
        ``measurement="state"``, ``order + 3`` for ``measurement="position"`` (the
        disturbance history, angle and velocity are all estimated).
    bandwidth : float, optional
        Observer bandwidth ``g > 0`` [rad/s]; places every disturbance pole (``order + 1``
        of them) at ``exp(-g Ts)``. Exactly one of ``poles`` and ``bandwidth`` must be given.
    measurement : {"state", "position"}, optional
        What the observer measures: angle and velocity (``"state"``, default, the paper's
        observer) or the angle alone (``"position"``, e.g. an encoder count).
    velocity_bandwidth : float, optional
        ``measurement="position"`` with ``bandwidth`` only: bandwidth ``g_v > 0`` [rad/s] of
        the two position/velocity poles, placed at ``exp(-g_v Ts)``. Default ``bandwidth``:
        all ``order + 3`` poles at one place, which minimises the estimation error of a slow
        disturbance at a given noise gain (``docs/analysis.md``, section 8).
    gain_direction : sequence of 2 floats, optional
        ``measurement="state"`` only. Direction ``d`` of the gain vectors,
        ``L_i = k_i d / (d^T D_Dn)``. The default ``(1, 1)`` is the paper's eq. (25).
        ``(0, 1)`` makes the estimate independent of the absolute position.
    pole_tolerance : float or None, optional
        Refuse a design whose realised poles (``design.realised_poles``: the eigenvalues the
        gains rounded to doubles really place, from the exact characteristic polynomial) lie
        further than ``pole_tolerance (1 - |p|)`` from a requested pole ``p`` (default 0.05;
        None: accept any design that is stable, decided exactly). Both families.

    Returns
    -------
    ObserverDesign or PositionObserverDesign
        For ``measurement="state"`` and ``"position"`` respectively.

    Raises
    ------
    TypeError
        If ``model`` is not a :class:`DiscreteServoModel` or an argument has the wrong type.
    ValueError
        If ``order < 0``, both or neither of ``poles``/``bandwidth`` are given, a pole is not
        strictly inside the unit circle or lacks its conjugate, the number of poles is not
        ``order + 1`` (``order + 3`` for position-only), ``bandwidth <= 0``,
        ``gain_direction`` is zero or (nearly) orthogonal to ``D_Dn``, ``measurement`` is not
        one of the two, ``velocity_bandwidth`` or ``gain_direction`` is given where it does not
        apply, ``order > 50``, or the error matrix is not stable although the requested
        poles are (high orders or repeated poles very close to 1: the gains, rounded to
        double precision, no longer place them; decided exactly by a Schur-Cohn test), or a
        realised pole is off by more than ``pole_tolerance``.

    Notes
    -----
    The characteristic polynomial of the error matrix is affine in ``k``:
    :math:`\det(zI - M) = (z-1)^{m+1} + \sum_j k_j q_j(z)` (``docs/theory.md``), so ``k``
    follows from one triangular linear solve, which generalises eq. (24). Repeated poles
    are placed exactly; no pole-placement routine is involved. For
    ``measurement="position"`` the observer estimates the augmented state
    ``[theta, omega, tau_(k-m), ..., tau_k]`` in current form; its characteristic polynomial
    is affine in the gains too and is placed by a power-series division
    (``docs/theory.md``, section 9). Both families' realised gains are certified stable by
    the exact Schur-Cohn test.

    References
    ----------
    E. Sariyildiz, "A High Performance Disturbance Observer: A Unified Synthesis Approach",
    eqs. (9)-(13), (14)-(25).

    Examples
    --------
    >>> from hpdob import ServoModel, design_observer
    >>> model = ServoModel(J=2.8e-4).discretize(1e-3)
    >>> design = design_observer(model, order=1, poles=[0.9, 0.8])
    >>> design.k     # eq. (24): [1 - 0.9*0.8, 2 - 0.9 - 0.8]
    array([0.28, 0.3 ])

    Measuring the angle only (an encoder), the velocity estimated along:

    >>> pos = design_observer(model, order=1, bandwidth=100.0, measurement="position")
    >>> pos.system.measures, pos.system.outputs, pos.poles.size
    (('theta',), ('tau_hat', 'omega_hat'), 4)
    """
    model = as_discrete_model(model, "model")
    m = as_int(order, "order", "a non-negative integer truncation order", minimum=0)
    if m > MAX_ORDER:
        raise ParameterValueError(
            f"order must be at most {MAX_ORDER}: the extrapolation weights binom(m+1, i) of "
            f"higher orders are not exact in double precision, got {m}"
        )
    check_choice(measurement, "measurement", MEASUREMENTS)
    if measurement == "position":
        if gain_direction is not None:
            raise ParameterValueError(
                "gain_direction applies to measurement='state' only (a position-only "
                f"observer's gains act on the angle alone), got {gain_direction!r}"
            )
        from ._position import design_position_observer

        return design_position_observer(
            model,
            m,
            poles=poles,
            bandwidth=bandwidth,
            velocity_bandwidth=velocity_bandwidth,
            pole_tolerance=pole_tolerance,
        )
    if velocity_bandwidth is not None:
        raise ParameterValueError(
            "velocity_bandwidth applies to measurement='position' only (an observer that "
            f"measures the state has no velocity poles), got {velocity_bandwidth!r}"
        )
    if gain_direction is None:
        gain_direction = (1.0, 1.0)
    if (poles is None) == (bandwidth is None):
        given = "both" if poles is not None else "neither"
        raise ParameterValueError(
            f"give exactly one of poles (order + 1 = {m + 1} eigenvalues) or "
            f"bandwidth (rad/s); got {given}"
        )
    if bandwidth is not None:
        g = positive(bandwidth, "bandwidth", "a positive finite observer bandwidth [rad/s]")
        placed = np.full(m + 1, math.exp(-g * model.Ts))
        g_out: float | None = g
    else:
        placed = _validate_poles(poles, m + 1, f"order + 1 = {m + 1}", m)
        g_out = None
    d = as_real_vector(
        gain_direction, "gain_direction", "a direction vector (d_theta, d_omega)", length=2
    )
    D = np.asarray(model.D)
    # Only the direction matters (L_i = k_i d / d^T D): scale it to max |d_j| = 1 first so
    # that tiny (subnormal) or huge entries neither underflow nor overflow below.
    scale = float(np.max(np.abs(d)))
    unit = d / scale if scale > 0.0 else d
    dD = float(unit @ D)
    # The test on D scaled to max |D_j| = 1 too: |D| of a tiny J_n (1e-300: D ~ 1e297) would
    # overflow the norm (a numpy warning, then "orthogonal" for a direction that is not).
    D_scale = float(np.max(np.abs(D)))
    D_unit = D / D_scale if 0.0 < D_scale < np.inf else D
    if abs(float(unit @ D_unit)) <= _DEGENERATE * np.linalg.norm(unit) * np.linalg.norm(D_unit):
        raise ParameterValueError(
            f"gain_direction must not be zero or orthogonal to D_Dn = {D.tolist()}: "
            f"d^T D_Dn = {float(d @ D):.3g} for gain_direction={d.tolist()}"
        )

    desired = np.real(np.poly(placed)) if placed.size else np.array([1.0])
    # desired (highest power first, monic, degree m+1) minus (z-1)^{m+1}, ascending powers.
    rhs = desired[::-1][: m + 1] - unit_root_polynomial(m)[: m + 1]
    k = np.linalg.solve(characteristic_basis(m), rhs)

    G = finite_gains(k, unit, dD, model)
    M = error_matrix(k)
    if not schur_stable(k):
        asked = f"bandwidth={g_out!r} rad/s" if g_out is not None else f"poles={_show(poles)}"
        raise ParameterValueError(
            f"{asked} cannot be realised for order {m} in double precision: with the gains "
            f"rounded to doubles, k = {_show_k(k)}, the error matrix is not stable (an eigenvalue "
            f"has |z| >= 1, exact Schur-Cohn test); high orders and repeated poles near 1 are "
            f"too ill-conditioned. Use a lower order, a higher bandwidth or distinct poles"
        )
    A, B = np.asarray(model.A), np.asarray(model.B)
    Kx = G @ A - M @ G
    Ku = G @ B
    poles_out = readonly(placed)
    design_info = _design_info(model, m, poles_out, g_out, d)
    system = LinearObserver(
        F=M,
        G=np.column_stack([Kx, Ku]),
        H=np.eye(m + 1)[-1:],
        E=np.array([[-G[-1, 0], -G[-1, 1], 0.0]]),
        N=np.column_stack([G, np.ones(m + 1)]),
        Ts=model.Ts,
        measures=("theta", "omega"),
        outputs=("tau_hat",),
        model=model,
        name=_ORDER_NAMES.get(m, f"order-{m} DOb"),
        program=structured_program(k, G, Kx, Ku, extrapolation_weights(m)),
        error_dynamics=ErrorDynamics(m, poles_out, characteristic_polynomial(k)),
        info=design_info,
    )
    return ObserverDesign(
        model=model,
        order=m,
        poles=poles_out,
        bandwidth=g_out,
        gain_direction=readonly(d),
        k=readonly(k),
        gains=readonly(G),
        error_matrix=readonly(M),
        state_input=readonly(Kx),
        control_input=readonly(Ku),
        system=system,
        realised_poles=readonly(realised_poles(k, placed, pole_tolerance, g_out, poles)),
    )


_ORDER_NAMES = {0: "DOb (order 0)", 1: "HPDOb (order 1)"}


def _design_info(model, m, poles, bandwidth, d) -> tuple:
    kind = {0: "conventional DOb, paper eqs. 9-13", 1: "HPDOb, paper eqs. 14-24"}.get(
        m, "generalised DOb, Delta^(m+1) tau = 0"
    )
    text = ", ".join(_fmt_complex(p) for p in poles)
    if bandwidth is not None:
        text += f" (bandwidth {bandwidth!r} rad/s)"
    return (
        ("nominal model", f"J_n = {model.J!r} kg m^2, b_n = {model.b!r} N m s/rad"),
        ("sampling period", f"Ts = {model.Ts!r} s"),
        ("order", f"{m} ({kind})"),
        ("poles", text),
        ("gain direction", f"({float(d[0])!r}, {float(d[1])!r}): L_i = k_i d / (d^T D_Dn)"),
    )
