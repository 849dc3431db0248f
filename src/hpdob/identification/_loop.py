"""The position loop that produced a log, for simulating it with identified parameters."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_real,
    as_real_vector,
    nonnegative,
    positive,
    readonly,
    require_instance,
)
from ._checks import check_lengths, sample_vector
from ._loop_kernel import loop_kernel

__all__ = ["FeedbackLoop", "simulate_loop"]

#: A simulated loop stops when |position| or |velocity| exceeds this (diverged).
DIVERGENCE_LIMIT = 1e9


@dataclass(frozen=True, eq=False)
class FeedbackLoop:
    r"""The controller of a logged run: PD on a sampled position, in torque/force units.

    At sample ``k``, with the measured position :math:`y_k` and the velocity estimate
    :math:`v_k = \frac{1}{T_s}\sum_i c_i\,y_{k-i}` (``velocity_filter`` :math:`c`),

    .. math:: u_k = \mathrm{sat}_{\pm\mathrm{limit}}\big(k_p (r_k - y_k)
              + k_d (\dot r_k - v_k) + u_{ff,k}\big).

    ``method="idim-iv"`` of :func:`hpdob.identify` simulates this loop around the identified
    model to build noise-free instruments; the closer it is to the real controller, the
    better. The EMPS controller (description, eq. 6) is
    ``FeedbackLoop(qg, kp=gtau*kv*kp, kd=gtau*kv, velocity_filter=(0.5, 0, -0.5),
    limit=10*gtau)`` (:func:`hpdob.identification.emps_loop`); hpdob's own
    :class:`~hpdob.PD` is :meth:`from_pd`. Observers in the loop are not modelled: identify
    from a run under plain PD control.

    Parameters
    ----------
    reference : array_like
        Reference position :math:`r_k` [rad or m], one per logged sample.
    kp : float
        Position gain [N m/rad or N/m], >= 0.
    kd : float
        Velocity gain [N m s/rad or N s/m], >= 0.
    reference_velocity : array_like, optional
        :math:`\dot r_k` [rad/s or m/s]; None (default) for pure velocity feedback,
        :math:`-k_d v_k`, as in EMPS.
    feedforward : array_like, optional
        Feed-forward torque/force :math:`u_{ff,k}` [N m or N] (e.g. ``J_n * r_ddot``).
    velocity_filter : sequence of float or None, optional
        Coefficients :math:`c_0, c_1, \dots` of the velocity estimate; they must form a
        differentiator (:math:`\sum_i c_i = 0`, :math:`-\sum_i i\,c_i = 1`). Default
        ``(1, -1)``, the backward difference; EMPS uses ``(0.5, 0, -0.5)``. None: the exact
        velocity (an ideal sensor).
    limit : float, optional
        Saturation of the command [N m or N]; None for none.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob.identification import FeedbackLoop
    >>> loop = FeedbackLoop(np.zeros(5), kp=100.0, kd=10.0, velocity_filter=(0.5, 0.0, -0.5))
    >>> len(loop), loop.velocity_filter
    (5, (0.5, 0.0, -0.5))
    """

    reference: np.ndarray
    _: KW_ONLY
    kp: float
    kd: float
    reference_velocity: np.ndarray | None = None
    feedforward: np.ndarray | None = None
    velocity_filter: tuple | None = (1.0, -1.0)
    limit: float | None = None

    def __post_init__(self) -> None:
        what = "positions [rad or m]"
        arrays = {"reference": sample_vector(self.reference, "reference", what)}
        if self.reference_velocity is not None:
            arrays["reference_velocity"] = sample_vector(
                self.reference_velocity, "reference_velocity", "velocities [rad/s or m/s]"
            )
        if self.feedforward is not None:
            arrays["feedforward"] = sample_vector(
                self.feedforward, "feedforward", "torques or forces [N m or N]"
            )
        check_lengths(arrays)
        kp = nonnegative(self.kp, "kp", "a non-negative finite gain [N m/rad or N/m]")
        kd = nonnegative(self.kd, "kd", "a non-negative finite gain [N m s/rad or N s/m]")
        coefficients = None
        if self.velocity_filter is not None:
            c = as_real_vector(
                self.velocity_filter, "velocity_filter", "a sequence of filter coefficients"
            )
            scale = float(np.max(np.abs(c))) if c.size else 0.0
            gain = -float(np.dot(np.arange(c.size), c))
            if c.size < 2 or abs(c.sum()) > 1e-9 * scale or abs(gain - 1.0) > 1e-9:
                raise ParameterValueError(
                    "velocity_filter must be a differentiator: coefficients c_i of "
                    "v_k = sum_i c_i y_(k-i) / Ts with sum c_i = 0 and -sum i c_i = 1, "
                    f"e.g. (1, -1) or (0.5, 0, -0.5); got {tuple(c.tolist())}"
                )
            coefficients = tuple(float(x) for x in c)
        limit = self.limit
        if limit is not None:
            limit = positive(limit, "limit", "a positive finite torque/force [N m or N] or None")
        for name, array in arrays.items():
            object.__setattr__(self, name, readonly(array))
        object.__setattr__(self, "kp", kp)
        object.__setattr__(self, "kd", kd)
        object.__setattr__(self, "velocity_filter", coefficients)
        object.__setattr__(self, "limit", limit)

    def __len__(self) -> int:
        return self.reference.size

    @classmethod
    def from_pd(
        cls,
        controller,
        *,
        J_n: float,
        reference,
        reference_velocity=None,
        reference_acceleration=None,
        velocity_filter=(1.0, -1.0),
        limit: float | None = None,
    ) -> FeedbackLoop:
        r"""The loop of hpdob's :class:`~hpdob.PD` with nominal inertia ``J_n`` (no observer).

        :math:`u_k = J_n(\ddot r_k + k_p(r_k - y_k) + k_d(\dot r_k - v_k))`, i.e. gains
        ``J_n kp`` and ``J_n kd`` and feed-forward ``J_n r_ddot`` (if the controller has
        feed-forward). For a run of :func:`hpdob.simulate` pass the result's ``r``, ``r_dot``
        and ``r_ddot``.

        Parameters
        ----------
        controller : PD
            hpdob's controller (its ``kp`` [1/s^2], ``kd`` [1/s] and ``feedforward``).
        J_n : float
            Nominal inertia [kg m^2 or kg], positive.
        reference : array_like
            Reference position [rad or m] at each sample.
        reference_velocity, reference_acceleration : array_like, optional
            :math:`\dot r_k`, :math:`\ddot r_k` (the latter used with feed-forward only).
        velocity_filter : sequence of float or None, optional
            Default ``(1, -1)``: an :class:`~hpdob.Encoder` with backward-difference
            velocity; None: an ideal sensor (the exact velocity).
        limit : float, optional
            Saturation of the command [N m or N]. Default none.

        Returns
        -------
        FeedbackLoop

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For a controller that is not a PD or an invalid value.
        """
        from ..simulation import PD

        controller = require_instance(controller, PD, "controller")
        J_n = positive(J_n, "J_n", "a positive finite nominal inertia [kg m^2 or kg]")
        reference = sample_vector(reference, "reference", "positions [rad or m]")
        feedforward = None
        if controller.feedforward and reference_acceleration is not None:
            feedforward = J_n * sample_vector(
                reference_acceleration, "reference_acceleration", "accelerations"
            )
        return cls(
            reference,
            kp=J_n * controller.kp,
            kd=J_n * controller.kd,
            reference_velocity=reference_velocity,
            feedforward=feedforward,
            velocity_filter=velocity_filter,
            limit=limit,
        )


def simulate_loop(
    loop: FeedbackLoop,
    parameters,
    *,
    Ts: float,
    theta0: float = 0.0,
    velocity0: float = 0.0,
):
    r"""Simulate ``loop`` around a rigid axis with Coulomb friction.

    The plant :math:`J\dot v = u - \mathrm{offset} - b v - c\,\mathrm{sign}(v)` (sticking at
    :math:`v = 0` while :math:`|u - \mathrm{offset}| \le c`) is integrated exactly over each
    sample with the command held (zero-order hold); the position is measured without noise.

    Parameters
    ----------
    loop : FeedbackLoop
        The controller and its reference.
    parameters : sequence of 4 floats
        ``(J, b, coulomb, offset)`` in the log's units, e.g. ``fit.parameters.values()``.
    Ts : float
        Sampling period [s].
    theta0, velocity0 : float, optional
        Initial position [rad or m] and velocity [rad/s or m/s]. Default 0.

    Returns
    -------
    theta : ndarray
        Simulated position at each sample [rad or m].
    u : ndarray
        Command at each sample [N m or N].

    References
    ----------
    The EMPS description (see :func:`emps`), eq. 3; the IDIM-IV instruments of
    :func:`hpdob.identify` are built with it.

    Examples
    --------
    The EMPS loop around the benchmark's published model follows the measured run:

    >>> import numpy as np
    >>> from hpdob.identification import EMPS_PUBLISHED, emps, emps_loop, simulate_loop
    >>> log = emps()
    >>> theta, u = simulate_loop(emps_loop(log), tuple(EMPS_PUBLISHED.values()), Ts=log.Ts)
    >>> error = np.linalg.norm(theta - log.theta) / np.linalg.norm(log.theta)
    >>> bool(error < 0.01)   # below 1 %
    True

    Raises
    ------
    ParameterValueError
        If the parameters cannot be simulated (``J <= 0``, ``b < 0`` or ``coulomb < 0``) or
        the simulated loop diverges.
    """
    loop = require_instance(loop, FeedbackLoop, "loop")
    if len(parameters) != 4:
        raise ParameterTypeError(f"parameters must be (J, b, coulomb, offset), got {parameters!r}")
    J, b, coulomb, offset = (as_real(p, "parameters", "a finite number") for p in parameters)
    if not (J > 0.0 and b >= 0.0 and coulomb >= 0.0):
        raise ParameterValueError(
            "the loop can only be simulated with J > 0, b >= 0 and coulomb >= 0; got "
            f"J = {J:.6g}, b = {b:.6g}, coulomb = {coulomb:.6g}"
        )
    Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
    n = len(loop)
    zeros = np.zeros(n)
    r_dot = zeros if loop.reference_velocity is None else loop.reference_velocity
    feedforward = zeros if loop.feedforward is None else loop.feedforward
    exact = loop.velocity_filter is None
    c = np.array((1.0, -1.0) if exact else loop.velocity_filter)
    limit = math.inf if loop.limit is None else loop.limit
    theta, u = np.empty(n), np.empty(n)
    done = loop_kernel()(
        J, b, coulomb, offset, Ts, float(theta0), float(velocity0),
        np.ascontiguousarray(loop.reference), np.ascontiguousarray(r_dot),
        np.ascontiguousarray(feedforward), loop.kp, loop.kd, c, exact, limit,
        DIVERGENCE_LIMIT, theta, u,
    )  # fmt: skip
    if done < n:
        raise ParameterValueError(
            f"the simulated loop diverged at t = {done * Ts:.6g} s with J = {J:.6g}, b = {b:.6g}, "
            f"coulomb = {coulomb:.6g}, offset = {offset:.6g}: check the loop's gains and units"
        )
    return theta, u
