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
\dot q - \tau_{ext}`, and it sees it through its own low-pass: :math:`\hat\tau_{dn} = Q\,
\tau_{dn}` (:math:`1 - Q(z) = (z-1)^{m+1}/\prod_i (z - p_i)` for the order-m family). Its
external-torque estimate passes what a nominal model says of the rest, :math:`w = \hat g +
\hat C\dot q + (\hat B - B_n)\dot q + (\hat M - J_n)\bar a`, through the same observer, so that
both sides see the same :math:`Q`: :math:`\hat\tau_{ext} = Q\,w - \hat\tau_{dn}`, which is
:math:`Q\,\tau_{ext}` on a correct model (the loop's recovery from a push, the coupling
:math:`(M - J_n)\ddot q`, cancels instead of showing up as force). :math:`Q w` is the observer's
estimate with ``w`` as its command and its measured signals at zero (on its nominal model a
command that cancels the disturbance leaves the plant at rest), and :math:`\bar a_k = (\dot
q_{k+1} - \dot q_k)/T_s` the mean acceleration over sample ``k``, what a disturbance held over
that sample acts with (causal: ``w_k`` first reaches the estimate of sample ``k + 1``). Without
a model: :math:`-\hat\tau_{dn}` alone.

The end-effector force follows from :math:`\tau_{ext} = J^T F` by the damped pseudo-inverse
:math:`\hat F = (J J^T + \lambda^2 I)^{-1} J \hat\tau_{ext}` (Nakamura and Hanafusa 1986).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, nonnegative, positive
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
    n = getattr(model, "n_joints", None)
    if not isinstance(n, int):
        raise ParameterTypeError(
            f"{name} must be an arm model (TwoLinkArm or MujocoArm), got {type(model).__name__}"
        )
    if n != result.q.shape[1]:
        raise ParameterValueError(
            f"{name} must be an arm model with the run's {result.q.shape[1]} joints, got one "
            f"with {n}"
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
        raise ParameterValueError(
            f"gain must be a positive finite observer gain [1/s] with gain * Ts < 1 (Ts = {Ts!r}"
            f" s), got {K_o!r}"
        )
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


def _estimate_of(system, w, tau_start):
    """Observer ``system``'s estimate of a disturbance ``w`` on its nominal model: ``w`` fed as
    its command with the measured signals at zero (a nominal plant at rest whose command cancels
    its disturbance stays at rest), from the state converged on ``tau_start`` -- :math:`Q w`."""
    g, h = system.G[:, -1], system.H[0]
    s = system.N @ np.array([0.0, 0.0, tau_start])
    out = np.empty(len(w))
    for k, wk in enumerate(w):
        out[k] = h @ s
        s = system.F @ s + g * wk
    return out


def joint_observer_external(result: ArmResult, model=None, *, loop=None, measured: bool = True,
                            damping: float = 1e-3) -> ExternalEstimate:  # fmt: skip
    r"""External joint torques from the per-joint observers' estimates (module docstring).

    With a nominal model, joint ``i``'s estimate is
    :math:`\hat\tau_{ext,i} = Q_i w_i - \hat\tau_{dn,i}`: the model's part of the nominal
    disturbance, :math:`w = \hat g + \hat C\dot q + (\hat B - B_n)\dot q + (\hat M - J_n)
    \bar a`, passed through joint ``i``'s own observer (its estimate of a disturbance ``w`` on
    its nominal model, :math:`Q_i w_i`), so that both terms see the same low-pass :math:`Q_i`
    and :math:`\hat\tau_{ext} = Q\,\tau_{ext}` on a correct model; :math:`\bar a_k =
    (\dot q_{k+1} - \dot q_k)/T_s` is the mean acceleration over sample ``k``, the value a
    held disturbance of that sample acts with (causal: the observer's estimate at ``k + 1`` is
    the first to read it).

    Parameters
    ----------
    result : ArmResult
        A run with per-joint observers (``tau_hat``).
    model : arm model, optional
        The nominal model whose gravity, Coriolis, friction and inertial coupling are
        subtracted; None: ``-tau_hat`` alone (and no force: it needs the Jacobian).
    loop : ArmLoop
        The run's loop: its per-joint observers and :math:`J_{n,i}`, :math:`b_{n,i}`; needed
        with a model.
    measured : bool, optional
        Evaluate the model at the measured (default) or the true state.
    damping : float, optional
        :math:`\lambda` of :func:`end_effector_force`.

    Returns
    -------
    ExternalEstimate

    Raises
    ------
    ParameterTypeError, ParameterValueError
        Naming the argument: not an ArmResult, a model or loop of another number of joints,
        a loop without an observer on some joint or at another ``Ts``.
    """
    if model is None:
        tau = -np.asarray(result.tau_hat)
        return ExternalEstimate(result.t, tau, np.full((len(result.t), 3), np.nan),
                                "joint observers")  # fmt: skip
    _check(model, result)
    from ._arm_loop import ArmLoop

    if not isinstance(loop, ArmLoop):
        raise ParameterTypeError(
            f"loop must be the run's ArmLoop when a model is given, got {type(loop).__name__}"
        )
    N = result.q.shape[1]
    if loop.n_joints != N or not math.isclose(loop.Ts, result.Ts, rel_tol=1e-12):
        raise ParameterValueError(
            f"loop must be the run's ({N} joints at Ts = {result.Ts!r} s), got {loop.n_joints} "
            f"joints at Ts = {loop.Ts!r} s"
        )
    missing = [i for i, s in enumerate(loop.systems) if s is None]
    if missing:
        raise ParameterValueError(
            f"loop must have an observer on every joint, got none on joint(s) {missing}"
        )
    J_n = np.asarray(loop.nominal_inertia, dtype=float)
    b_n = np.asarray(loop.nominal_friction, dtype=float)
    q, qd = _signals(result, measured)
    accel = np.zeros_like(qd)
    accel[:-1] = np.diff(qd, axis=0) / result.Ts  # the last one reaches no recorded estimate
    w = np.zeros_like(q)
    for k in range(len(q)):
        w[k] = model.gravity_torque(q[k]) + model.coriolis(q[k], qd[k])
        w[k] += _friction(model, qd[k]) - b_n * qd[k]
        w[k] += (model.mass_matrix(q[k]) - np.diag(J_n)) @ accel[k]
    filtered = np.column_stack([
        _estimate_of(system, w[:, i], result.tau_hat[0, i])
        for i, system in enumerate(loop.systems)
    ])  # fmt: skip
    tau = filtered - result.tau_hat
    force = end_effector_force(model, q, tau, damping=damping)
    return ExternalEstimate(result.t, tau, force, "joint observers")
