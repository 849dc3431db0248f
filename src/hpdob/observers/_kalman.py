r"""A steady-state Kalman filter with a disturbance state: the Kalman disturbance observer.

The exact ZOH nominal model (eq. 8) is augmented with the disturbance model of the
position-only observers, :math:`\Delta^{m+1}\tau = 0` driven by white noise: with state
:math:`x = [\theta_k, \omega_k, \tau_k, \Delta\tau_k, \dots, \Delta^m\tau_k]` (``n = m + 3``),

.. math::

    [\theta, \omega]_{k+1} &= A [\theta, \omega]_k + B u_k - D \tau_k, \\
    \Delta^j\tau_{k+1} &= \Delta^j\tau_k + \Delta^{j+1}\tau_k \quad (j < m),\qquad
    \Delta^m\tau_{k+1} = \Delta^m\tau_k + w_k,

with :math:`w_k \sim N(0, q^2)` (``process_noise_std``) and the measurement
:math:`y_k = \theta_k + v_k`, :math:`v_k \sim N(0, r^2)` (``position_noise_std``; for an encoder
of resolution ``q_e`` the quantisation has :math:`r = q_e/\sqrt{12}`). The filter is the
steady-state one in current (filtered) form,

.. math:: \hat x_k = \bar x_k + K(y_k - C\bar x_k),\qquad \bar x_{k+1} = A\hat x_k + B u_k,

with :math:`K = P C^T (C P C^T + r^2)^{-1}` and ``P`` the a-priori covariance solving the
discrete algebraic Riccati equation (``scipy.linalg.solve_discrete_are``). Its estimate is the
disturbance state, :math:`\hat\tau_k = \hat x_{3,k}`: the nominal disturbance over sample ``k``,
like the DOb's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._validation import (
    ParameterValueError,
    as_int,
    positive,
    readonly,
)
from ..models import DiscreteServoModel, as_discrete_model
from ._error_dynamics import schur_cohn_stable
from ._realised import matrix_characteristic_polynomial
from ._runtime import _DesignedObserver
from ._system import LinearObserver, _Designed

__all__ = ["KalmanDesign", "KalmanDisturbanceObserver", "design_kalman", "kalman_process_noise"]

#: Highest disturbance order of the Kalman observer.
MAX_ORDER = 4


def augmented_model(model: DiscreteServoModel, order: int):
    """``(A, B, C, G)`` of the augmented model: state ``[theta, omega, tau, Delta tau, ...]``,
    ``G`` the column the process noise enters by."""
    n = order + 3
    A = np.zeros((n, n))
    A[:2, :2] = model.A
    A[:2, 2] = -np.asarray(model.D)
    for j in range(2, n):
        A[j, j] = 1.0
        if j + 1 < n:
            A[j, j + 1] = 1.0
    B = np.zeros(n)
    B[:2] = model.B
    C = np.zeros((1, n))
    C[0, 0] = 1.0
    G = np.zeros(n)
    G[-1] = 1.0
    return A, B, C, G


def _check_model(model) -> DiscreteServoModel:
    return as_discrete_model(model, "model")


def _check_order(order) -> int:
    m = as_int(order, "order", "a non-negative integer disturbance order", minimum=0)
    if m > MAX_ORDER:
        raise ParameterValueError(f"order must be at most {MAX_ORDER}, got {m}")
    return m


def _noise(value, name: str, what: str) -> float:
    """A noise std: positive, finite, and with a variance that neither underflows nor
    overflows (the Riccati equation works with the variances)."""
    value = positive(value, name, what)
    if not 0.0 < value * value < math.inf:
        how = "underflows to 0" if value < 1.0 else "overflows"
        raise ParameterValueError(
            f"{name}={value!r} is out of range: its variance {how} in double precision; give "
            "the noise in units where it has a realistic size"
        )
    return value


@dataclass(frozen=True, eq=False)
class KalmanDesign(_Designed):
    """A steady-state Kalman disturbance observer (immutable); see :func:`design_kalman`.

    Attributes
    ----------
    model : DiscreteServoModel
    order : int
        ``m`` of the disturbance model :math:`\\Delta^{m+1}\\tau = 0`.
    position_noise_std, process_noise_std : float
        ``r`` [rad] and ``q`` [N m per sample^m] of the noise model.
    A, B, C : ndarray
        The augmented model.
    covariance : ndarray
        The a-priori steady-state covariance ``P`` (DARE solution).
    gain : ndarray
        The filter gain ``K``.
    system : LinearObserver
        The observer as a linear system (measures ``theta``; outputs ``tau_hat``,
        ``omega_hat``).
    """

    model: DiscreteServoModel
    order: int
    position_noise_std: float
    process_noise_std: float
    A: np.ndarray = field(repr=False)
    B: np.ndarray = field(repr=False)
    C: np.ndarray = field(repr=False)
    covariance: np.ndarray = field(repr=False)
    gain: np.ndarray = field(repr=False)
    system: LinearObserver = field(repr=False)

    @property
    def poles(self) -> np.ndarray:
        """Eigenvalues of the estimation-error dynamics, ``eig(A - A K C)``."""
        return np.linalg.eigvals(np.asarray(self.system.F))


def design_kalman(
    model: DiscreteServoModel,
    *,
    order: int = 0,
    position_noise_std: float,
    process_noise_std: float,
) -> KalmanDesign:
    r"""Design the steady-state Kalman disturbance observer (see the module docstring).

    Parameters
    ----------
    model : DiscreteServoModel or control.TransferFunction or control.StateSpace
        Nominal discrete model, ``ServoModel(J_n, b_n).discretize(Ts)``. A sampled python-control
        servo (``control.c2d(sys, Ts)``) is read by :meth:`DiscreteServoModel.from_lti`.
    order : int, optional
        ``m``: the disturbance model :math:`\Delta^{m+1}\tau = 0` (0, default: a random walk
        of :math:`\tau`; 1: of its increment). At most 4.
    position_noise_std : float
        Standard deviation ``r`` of the angle measurement [rad], positive; for an
        :class:`~hpdob.Encoder` its quantisation ``resolution / sqrt(12)``.
    process_noise_std : float
        Standard deviation ``q`` of the white noise driving :math:`\Delta^m\tau` [N m per
        sample^m], positive. :func:`kalman_process_noise` picks it for a target bandwidth.

    Returns
    -------
    KalmanDesign

    Raises
    ------
    TypeError, ValueError
        Naming the parameter: a wrong model, a negative or too large order, a non-positive or
        non-finite noise level, or noise levels for which the Riccati equation has no
        stabilising solution (also when the solver returns one whose filter, rounded to doubles,
        is unstable: decided exactly by a Schur-Cohn test on the state matrix).

    References
    ----------
    R. E. Kalman, "A new approach to linear filtering and prediction problems", 1960; B. D. O.
    Anderson, J. B. Moore, *Optimal Filtering*, 1979, ch. 4 (the steady-state filter in
    filtered form).

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import ServoModel
    >>> from hpdob.observers import design_kalman
    >>> kf = design_kalman(ServoModel(2.8e-4).discretize(1e-3), position_noise_std=1e-4,
    ...                    process_noise_std=1e-3)
    >>> bool(np.all(np.abs(kf.poles) < 1))
    True
    """
    from scipy.linalg import LinAlgError, solve_discrete_are

    model = _check_model(model)
    m = _check_order(order)
    r = _noise(position_noise_std, "position_noise_std", "a positive finite noise std [rad]")
    q = _noise(
        process_noise_std, "process_noise_std", "a positive finite disturbance noise std [N m]"
    )
    A, B, C, G = augmented_model(model, m)
    n = m + 3
    Ts, J = model.Ts, model.J
    # Work in x~ = diag(d) x, where the chain of sampled integrations is well conditioned.
    d = np.array([1.0, Ts, *([Ts * Ts / J] * (n - 2))])
    A_s = d[:, None] * A / d[None, :]
    G_s = d * G
    try:
        with np.errstate(all="ignore"):
            # scipy's balancing casts NaN for hopeless noise ratios: judged by the result below
            # (numpy's floating-point warnings, the thread's own to silence: not
            # warnings.catch_warnings, whose filters a sweep's other threads share)
            P_s = solve_discrete_are(A_s.T, C.T, (q * q) * np.outer(G_s, G_s), np.array([[r * r]]))
        if not np.all(np.isfinite(P_s)):
            raise ValueError("the solution is not finite")
    except (LinAlgError, ValueError) as err:
        raise ParameterValueError(
            f"the Riccati equation has no stabilising solution for position_noise_std={r!r} "
            f"and process_noise_std={q!r} (order {m}): {err}"
        ) from None
    P = P_s / np.outer(d, d)
    with np.errstate(all="ignore"):  # judged below
        K = (P @ C.T).ravel() / (float((C @ P @ C.T)[0, 0]) + r * r)
    if not np.all(np.isfinite(K)):
        raise ParameterValueError(
            f"the Kalman gain is not finite for position_noise_std={r!r} and "
            f"process_noise_std={q!r}; the noise levels are too far apart"
        )
    I_KC = np.eye(n) - np.outer(K, C[0])
    F = A @ I_KC
    if not schur_cohn_stable(matrix_characteristic_polynomial(F)[0]):
        with np.errstate(all="ignore"):
            radius = float(np.abs(np.linalg.eigvals(F)).max())
        raise ParameterValueError(
            f"the Kalman observer for position_noise_std={r!r} and process_noise_std={q!r} "
            f"(order {m}) is not stable in double precision (spectral radius about "
            f"{radius:.6g}, exact Schur-Cohn test): the Riccati solver found no stabilising "
            "solution for noise levels this far apart; bring them closer (see "
            "kalman_process_noise)"
        )
    outputs = np.zeros((2, n))
    outputs[0, 2] = 1.0  # tau_hat
    outputs[1, 1] = 1.0  # omega_hat
    N = np.zeros((n, 3))
    N[0, 0], N[1, 1], N[2, 2] = 1.0, 1.0, 1.0
    system = LinearObserver(
        F=F,
        G=np.column_stack([A @ K, B]),
        H=outputs @ I_KC,
        E=np.column_stack([outputs @ K, np.zeros(2)]),
        N=N,
        Ts=Ts,
        measures=("theta",),
        outputs=("tau_hat", "omega_hat"),
        model=model,
        name=f"Kalman (m={m})",
        info=(
            ("observer", f"steady-state Kalman filter, disturbance model Delta^{m + 1} tau = 0"),
            ("nominal model", f"J_n = {J!r} kg m^2, b_n = {model.b!r} N m s/rad"),
            ("sampling period", f"Ts = {Ts!r} s"),
            ("noise", f"position std {r!r} rad, process std {q!r}"),
        ),
    )
    return KalmanDesign(
        model=model,
        order=m,
        position_noise_std=r,
        process_noise_std=q,
        A=readonly(A),
        B=readonly(B),
        C=readonly(C),
        covariance=readonly(P),
        gain=readonly(K),
        system=system,
    )


def _bandwidth(design: KalmanDesign) -> float:
    """Highest frequency [rad/s] where the estimation response |Q| is still >= 1/sqrt(2)."""
    from ._response import estimation_frequency_response

    nyquist = math.pi / design.Ts
    w = np.geomspace(1e-2, nyquist * 0.999, 600)
    gain = np.abs(estimation_frequency_response(design.system, np.exp(1j * w * design.Ts), False))
    above = np.nonzero(gain >= 1 / math.sqrt(2))[0]
    if above.size == 0:
        return 0.0
    i = above[-1]
    if i + 1 >= w.size:
        return nyquist
    # interpolate the crossing on the log grid
    g0, g1 = gain[i] - 1 / math.sqrt(2), gain[i + 1] - 1 / math.sqrt(2)
    return float(w[i] * (w[i + 1] / w[i]) ** (g0 / (g0 - g1)))


def kalman_process_noise(
    model: DiscreteServoModel, *, bandwidth: float, position_noise_std: float, order: int = 0
) -> float:
    r"""The process noise ``q`` that gives the Kalman observer a target bandwidth.

    The bandwidth of an observer is taken as the frequency where its estimation response
    :math:`|Q(e^{j\omega T_s})|` (:func:`hpdob.estimation_response`) falls below
    :math:`1/\sqrt 2` (for the DOb of bandwidth ``g`` this is close to ``g``). ``q`` is found by
    bisection on :math:`\log q`: the larger the process noise against the measurement noise,
    the faster the filter.

    Parameters
    ----------
    model : DiscreteServoModel
    bandwidth : float
        Target bandwidth [rad/s], positive and below the Nyquist frequency ``pi/Ts``.
    position_noise_std : float
        Measurement noise std [rad].
    order : int, optional
        Disturbance order ``m``. Default 0.

    Returns
    -------
    float
        ``process_noise_std`` for :func:`design_kalman`.

    Raises
    ------
    ValueError
        If the bandwidth is not positive or not reachable (too close to the Nyquist frequency).

    Examples
    --------
    >>> from hpdob import ServoModel
    >>> from hpdob.observers import design_kalman, kalman_process_noise
    >>> model = ServoModel(2.8e-4).discretize(1e-3)
    >>> q = kalman_process_noise(model, bandwidth=100.0, position_noise_std=1e-4)
    >>> kf = design_kalman(model, position_noise_std=1e-4, process_noise_std=q)
    """
    from scipy.optimize import brentq

    model = _check_model(model)
    m = _check_order(order)
    g = positive(bandwidth, "bandwidth", "a positive finite target bandwidth [rad/s]")
    r = _noise(position_noise_std, "position_noise_std", "a positive finite noise std [rad]")
    if not g < 0.5 * math.pi / model.Ts:
        raise ParameterValueError(
            f"bandwidth must be below half the Nyquist frequency pi/(2 Ts) = "
            f"{0.5 * math.pi / model.Ts:.6g} rad/s, got {g!r}"
        )

    seen: dict = {}  # the ends are asked up to three times each (the loops, the check, brentq)

    def mismatch(log_q: float) -> float:
        if log_q not in seen:
            seen[log_q] = _mismatch(log_q)
        return seen[log_q]

    def _mismatch(log_q: float) -> float:
        try:
            design = design_kalman(
                model, order=m, position_noise_std=r, process_noise_std=10**log_q
            )
        except ParameterValueError:  # no stabilising solution that far out: treat as an end
            return -math.inf if log_q < centre else math.inf
        return math.log(max(_bandwidth(design), 1e-12) / g)

    # q scales like r J / Ts^2 times (g Ts)^(m + 2): bracket around that
    centre = math.log10(r * model.J / model.Ts**2) + (m + 2) * math.log10(g * model.Ts)
    lo, hi = centre - 6, centre + 6
    while mismatch(lo) == -math.inf and lo < centre - 1:
        lo += 1.0
    while mismatch(hi) == math.inf and hi > centre + 1:
        hi -= 1.0
    if mismatch(lo) > 0 or mismatch(hi) < 0:
        raise ParameterValueError(
            f"bandwidth={g!r} rad/s is not reachable with position_noise_std={r!r} (order {m})"
        )
    q = 10 ** brentq(mismatch, lo, hi, xtol=1e-6)
    # brentq also "converges" on a jump between two ends that cannot be designed: verify
    if not (math.isfinite(q) and q > 0.0 and abs(mismatch(math.log10(q))) < 0.01):
        raise ParameterValueError(
            f"bandwidth={g!r} rad/s is not reachable with position_noise_std={r!r} (order {m}): "
            "no process noise that can be designed in double precision gives it"
        )
    return q


class KalmanDisturbanceObserver(_DesignedObserver):
    r"""The steady-state Kalman disturbance observer as a runtime object (see
    :func:`design_kalman`).

    The sample loop is that of the position-only observers: ``tau_hat = obs.estimate(theta_k)``
    (``obs.velocity`` then gives :math:`\hat\omega_k`), ``u_k``, ``obs.update(theta_k, u_k)``.

    Parameters
    ----------
    model : DiscreteServoModel
        Nominal discrete model.
    order : int, optional
        Disturbance order ``m``. Default 0.
    position_noise_std : float
        Measurement noise std [rad] (an encoder's ``resolution / sqrt(12)``).
    process_noise_std : float
        Process noise std (see :func:`kalman_process_noise`).

    Attributes
    ----------
    design : KalmanDesign

    Examples
    --------
    >>> from hpdob import KalmanDisturbanceObserver, ServoModel
    >>> kf = KalmanDisturbanceObserver(ServoModel(2.8e-4).discretize(1e-3),
    ...                                position_noise_std=1e-4, process_noise_std=1e-3)
    >>> kf.reset(tau0=0.02)
    >>> round(kf.estimate(0.0), 12)
    0.02
    """

    __slots__ = ()

    def __init__(self, model, *, order=0, position_noise_std, process_noise_std):
        design = design_kalman(
            model,
            order=order,
            position_noise_std=position_noise_std,
            process_noise_std=process_noise_std,
        )
        self._start(design)

    def __repr__(self) -> str:
        d = self._design
        return (
            f"KalmanDisturbanceObserver(order={d.order}, position_noise_std="
            f"{d.position_noise_std:g}, process_noise_std={d.process_noise_std:g}, Ts={d.Ts:g})"
        )
