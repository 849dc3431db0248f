r"""External joint torques and the end-effector force: De Luca's momentum observer, the
per-joint observers' estimates, and the force through the Jacobian.

The arm moves by :math:`M\ddot q + C\dot q + g + B\dot q = u + \tau_{ext}`, and with
:math:`p = M\dot q` and :math:`\dot M = C + C^T`, :math:`\dot p = u + \tau_{ext} + C^T\dot q - g -
B\dot q`. De Luca's first-order momentum observer (De Luca and Mattone, ICRA 2005; Haddadin, De
Luca and Albu-Schaeffer, IEEE T-RO 2017, eq. 22)

.. math:: r(t) = K_o\left(p(t) - \int_0^t (u + C^T\dot q - g - B\dot q + r)\,ds - p(0)\right)

obeys :math:`\dot r = K_o(\tau_{ext} - r)`: each joint's estimate is the external torque seen
through a first-order low-pass of bandwidth :math:`K_o` [1/s]. Discrete time, sample ``Ts``:
the command is held over each sample (ZOH), so its integral is exactly :math:`T_s u_k`; the
model terms :math:`\beta = C^T\dot q - g - B\dot q` are continuous and integrated by the
trapezoidal rule; the feedback :math:`r` by the rectangle rule (it is known at ``k`` only):

.. math:: \sigma_{k+1} = \sigma_k + T_s\,(u_k + \tfrac12(\beta_k + \beta_{k+1}) + r_k),
    \qquad r_{k+1} = K_o\,(p_{k+1} - p_0 - \sigma_{k+1}),

causal (:math:`\beta_{k+1}` comes from sample ``k + 1``'s measurement, before :math:`r_{k+1}`),
of the nominal model at the measured :math:`q, \dot q`.

A per-joint observer estimates joint ``i``'s nominal disturbance, which holds the external
torque with the opposite sign: :math:`\tau_{dn} = (M - J_n)\ddot q + C\dot q + g + (B - B_n)
\dot q - \tau_{ext}`. Its external-torque estimate subtracts what a nominal model says of the
rest: :math:`\hat\tau_{ext} = \hat g + \hat C\dot q + (\hat B - B_n)\dot q + (\hat M - J_n)\ddot r
- \hat\tau_{dn}` (the coupling through the reference acceleration :math:`\ddot r`, the only
acceleration the loop knows without differentiating twice), or :math:`-\hat\tau_{dn}` alone
without a model.

The end-effector force follows from :math:`\tau_{ext} = J^T F` by the damped pseudo-inverse
:math:`\hat F = (J J^T + \lambda^2 I)^{-1} J \hat\tau_{ext}` (Nakamura and Hanafusa 1986).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import ParameterTypeError, nonnegative, positive
from ._result import ArmResult

__all__ = ["ExternalEstimate", "end_effector_force", "joint_observer_external", "momentum_observer"]


@dataclass(frozen=True)
class ExternalEstimate:
    """Estimated external joint torques and end-effector force of a run.

    Attributes
    ----------
    t : ndarray, shape (samples,)
        Sampling instants [s].
    tau : ndarray, shape (samples, N)
        Estimated external joint torques [N m] (robotics sign: ``M qdd + ... = u + tau``).
    force : ndarray, shape (samples, 3)
        The end-effector force [N] (world frame) from ``tau`` (:func:`end_effector_force`).
    method : str
        ``"momentum"`` or ``"joint observers"``.
    """

    t: np.ndarray
    tau: np.ndarray
    force: np.ndarray
    method: str


def _check(model, result, name="model"):
    if not isinstance(result, ArmResult):
        raise ParameterTypeError(f"result must be an ArmResult, got {type(result).__name__}")
    if getattr(model, "n_joints", None) != result.q.shape[1]:
        raise ParameterTypeError(
            f"{name} must be an arm model with the run's {result.q.shape[1]} joints, got "
            f"{type(model).__name__}"
        )


def _signals(result, measured):
    return (result.q_measured, result.qd_measured) if measured else (result.q, result.qd)


def end_effector_force(model, q, tau, *, damping: float = 1e-3,
                       wrench: bool = False) -> np.ndarray:  # fmt: skip
    r"""The end-effector force :math:`\hat F = (J J^T + \lambda^2 I)^{-1} J \tau` [N].

    Parameters
    ----------
    model : arm model
        Gives ``jacobian(q)`` (translational, ``(3, N)`` or ``(2, N)``; with ``wrench``,
        ``jacobian(q, rotational=True)``, ``(6, N)``).
    q : array_like, shape (samples, N)
        Joint angles [rad].
    tau : array_like, shape (samples, N)
        External joint torques [N m].
    damping : float, optional
        :math:`\lambda`, non-negative. Default 1e-3.
    wrench : bool, optional
        Estimate the force and the moment about the site [N, N m] (a :class:`MujocoArm`).
        Default False: the force alone, the moment assumed zero.

    Returns
    -------
    ndarray, shape (samples, 3), (samples, 2) or, with ``wrench``, (samples, 6)
    """
    lam = nonnegative(damping, "damping", "a non-negative finite damping")
    q, tau = np.atleast_2d(q), np.atleast_2d(tau)
    out = []
    for qk, tk in zip(q, tau, strict=True):
        J = model.jacobian(qk, rotational=True) if wrench else model.jacobian(qk)
        out.append(np.linalg.solve(J @ J.T + lam**2 * np.eye(J.shape[0]), J @ tk))
    return np.array(out)


def _friction(model, qd):
    friction = getattr(model, "friction", None)
    return np.zeros_like(qd) if friction is None else np.asarray(friction(qd))


def momentum_observer(model, result: ArmResult, *, gain: float, measured: bool = True,
                      damping: float = 1e-3) -> ExternalEstimate:  # fmt: skip
    """De Luca's momentum observer on the nominal ``model`` over a run (module docstring).

    Parameters
    ----------
    model : TwoLinkArm or MujocoArm
        The nominal model (``mass_matrix``, ``coriolis_transpose``, ``gravity_torque``).
    result : ArmResult
        The run: its commands ``u`` and measured (or true) ``q``, ``qd``.
    gain : float
        :math:`K_o` [1/s], positive, with :math:`K_o T_s < 1`.
    measured : bool, optional
        Use the sensor's ``q_measured``/``qd_measured`` (default) or the true state.
    damping : float, optional
        :math:`\\lambda` of :func:`end_effector_force`. Default 1e-3.

    Returns
    -------
    ExternalEstimate
    """
    _check(model, result)
    K_o = positive(gain, "gain", "a positive finite observer gain [1/s]")
    Ts = result.Ts
    if K_o * Ts >= 1.0:
        raise ParameterTypeError(f"gain must satisfy gain * Ts < 1, got {K_o!r} * {Ts!r}")
    q, qd = _signals(result, measured)
    K, N = q.shape
    r = np.zeros((K, N))
    sigma = np.zeros(N)
    p0 = beta_prev = None
    for k in range(K):
        p = model.mass_matrix(q[k]) @ qd[k]
        beta = model.coriolis_transpose(q[k], qd[k]) - model.gravity_torque(q[k])
        beta -= _friction(model, qd[k])
        if p0 is None:
            p0 = p
        else:
            sigma += Ts * (result.u[k - 1] + 0.5 * (beta_prev + beta) + r[k - 1])
            r[k] = K_o * (p - p0 - sigma)
        beta_prev = beta
    force = end_effector_force(model, q, r, damping=damping)
    return ExternalEstimate(result.t, r, force, "momentum")


def joint_observer_external(result: ArmResult, model=None, *, nominal_inertia=None,
                            nominal_friction=None, measured: bool = True,
                            damping: float = 1e-3) -> ExternalEstimate:  # fmt: skip
    """External joint torques from the per-joint observers' estimates (module docstring).

    Parameters
    ----------
    result : ArmResult
        A run with per-joint observers (``tau_hat``).
    model : arm model, optional
        The nominal model whose gravity, Coriolis, friction and inertial coupling are
        subtracted; None: ``-tau_hat`` alone (and no force: it needs the Jacobian).
    nominal_inertia, nominal_friction : sequence of float, optional
        The loop's :math:`J_{n,i}`, :math:`b_{n,i}` (``loop.nominal_inertia``,
        ``loop.nominal_friction``); needed with a model.
    measured : bool, optional
        Evaluate the model at the measured (default) or the true state.
    damping : float, optional
        :math:`\\lambda` of :func:`end_effector_force`.

    Returns
    -------
    ExternalEstimate
    """
    if model is None:
        tau = -np.asarray(result.tau_hat)
        return ExternalEstimate(result.t, tau, np.full((len(result.t), 3), np.nan),
                                "joint observers")  # fmt: skip
    _check(model, result)
    if nominal_inertia is None or nominal_friction is None:
        raise ParameterTypeError(
            "nominal_inertia and nominal_friction must be the loop's (loop.nominal_inertia, "
            "loop.nominal_friction) when a model is given"
        )
    J_n = np.asarray(nominal_inertia, dtype=float)
    b_n = np.asarray(nominal_friction, dtype=float)
    q, qd = _signals(result, measured)
    tau = np.zeros_like(q)
    for k in range(len(q)):
        coupling = (model.mass_matrix(q[k]) - np.diag(J_n)) @ result.r_ddot[k]
        known = model.gravity_torque(q[k]) + model.coriolis(q[k], qd[k]) + coupling
        known += _friction(model, qd[k]) - b_n * qd[k]
        tau[k] = known - result.tau_hat[k]
    force = end_effector_force(model, q, tau, damping=damping)
    return ExternalEstimate(result.t, tau, force, "joint observers")
