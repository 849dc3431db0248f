"""The position loop that produced a log, for simulating it with identified parameters."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass
from typing import TYPE_CHECKING

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

if TYPE_CHECKING:
    from ..controllers import LinearController

__all__ = ["FeedbackLoop", "simulate_loop"]

#: A simulated loop stops when |position| or |velocity| exceeds this (diverged).
DIVERGENCE_LIMIT = 1e9


@dataclass(frozen=True, eq=False)
class FeedbackLoop:
    r"""The controller of a logged run on a sampled position, in torque/force units.

    At sample ``k``, with the measured position :math:`y_k` and the velocity estimate
    :math:`v_k = \frac{1}{T_s}\sum_i c_i\,y_{k-i}` (``velocity_filter`` :math:`c`), the
    command is PD in force units,

    .. math:: u_k = \mathrm{sat}_{\pm\mathrm{limit}}\big(k_p (r_k - y_k)
              + k_d (\dot r_k - v_k) + u_{ff,k}\big),

    or, with ``controller``, any linear controller of :mod:`hpdob.controllers` fed the
    loop's signals :math:`(r_k, \dot r_k, \ddot r_k, y_k, v_k)` and :math:`\hat\tau_k = 0`:
    :math:`u_k = \mathrm{sat}(H c_k + E v_k + u_{ff,k})`, its state updated with the
    limited command (:class:`~hpdob.controllers.LinearController`; ``kp = kd = 0``).

    ``method="idim-iv"`` of :func:`hpdob.identify` simulates this loop around the identified
    model to build noise-free instruments; the closer it is to the real controller, the
    better. The EMPS controller (description, eq. 6) is
    ``FeedbackLoop(qg, kp=gtau*kv*kp, kd=gtau*kv, velocity_filter=(0.5, 0, -0.5),
    limit=10*gtau)`` (:func:`hpdob.identification.emps_loop`); hpdob's controllers are
    :meth:`from_controller` (:class:`~hpdob.PD`, :class:`~hpdob.PID`,
    :class:`~hpdob.FilteredPD`, :class:`~hpdob.ADRC`, which carries its own ESO) and
    :meth:`from_pd`. A disturbance observer of the loop is not modelled: identify from a run
    without one (a controller reading an observer's output is refused).

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
    reference_acceleration : array_like, optional
        :math:`\ddot r_k` [rad/s^2 or m/s^2], read by ``controller`` only (0 if None).
    controller : LinearController, optional
        The whole command but the feed-forward (then ``kp = kd = 0``); its inputs may be
        only the loop's signals (:data:`hpdob.controllers.LOOP_SIGNALS`) and ``tau_hat``
        (0: no observer). Built by :meth:`from_controller`. None (default): the PD above.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        Naming the parameter: a gain, filter, limit or array that is not as described, a
        controller that is not a linear one on the loop's signals, or gains beside it.

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
    reference_acceleration: np.ndarray | None = None
    controller: LinearController | None = None

    def __post_init__(self) -> None:
        what = "positions [rad or m]"
        arrays = {"reference": sample_vector(self.reference, "reference", what)}
        if self.reference_velocity is not None:
            arrays["reference_velocity"] = sample_vector(
                self.reference_velocity, "reference_velocity", "velocities [rad/s or m/s]"
            )
        if self.reference_acceleration is not None:
            arrays["reference_acceleration"] = sample_vector(
                self.reference_acceleration, "reference_acceleration",
                "accelerations [rad/s^2 or m/s^2]",
            )  # fmt: skip
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
        if self.controller is not None:
            _check_controller(self.controller, "controller")
            if kp != 0.0 or kd != 0.0:
                raise ParameterValueError(
                    "kp and kd must be 0 with a controller (it gives the whole command), got "
                    f"kp = {kp!r}, kd = {kd!r}"
                )
        for name, array in arrays.items():
            object.__setattr__(self, name, readonly(array))
        object.__setattr__(self, "kp", kp)
        object.__setattr__(self, "kd", kd)
        object.__setattr__(self, "velocity_filter", coefficients)
        object.__setattr__(self, "limit", limit)

    def __len__(self) -> int:
        return self.reference.size

    @classmethod
    def from_controller(
        cls,
        controller,
        *,
        nominal,
        reference,
        Ts: float | None = None,
        reference_velocity=None,
        reference_acceleration=None,
        velocity_filter=(1.0, -1.0),
        limit: float | None = None,
    ) -> FeedbackLoop:
        r"""The loop of one of hpdob's linear controllers on the nominal model (no observer).

        A :class:`~hpdob.PD` becomes the PD form above,
        :math:`u_k = J_n(\ddot r_k + k_p(r_k - y_k) + k_d(\dot r_k - v_k))`: gains
        ``J_n kp`` and ``J_n kd`` and feed-forward ``J_n r_ddot`` (if the controller has
        feed-forward and ``reference_acceleration`` is given). Any other controller is
        designed on ``nominal`` at ``Ts`` (:func:`hpdob.controllers.controller_system`) and
        run as it is by :func:`simulate_loop`: its state, anti-windup and own observer (ADRC)
        included, fed :math:`\hat\tau = 0`. For a run of :func:`hpdob.simulate` without an
        observer pass the result's ``r``, ``r_dot`` and ``r_ddot``: the loop is then that
        run's (same controller, same sensor, same torque limit).

        Parameters
        ----------
        controller : Controller or LinearController
            :class:`~hpdob.PD`, :class:`~hpdob.PID`, :class:`~hpdob.FilteredPD`,
            :class:`~hpdob.ADRC` or any controller whose inputs are the loop's signals
            (:data:`hpdob.controllers.LOOP_SIGNALS`) and ``tau_hat``. Refused: a controller
            that reads another observer output (``PD(velocity="observer")``'s
            ``omega_hat``, the force controllers' ``tau_reac``) or switches.
        nominal : ServoModel or float
            The nominal model (or its inertia ``J_n`` [kg m^2 or kg], positive).
        reference : array_like
            Reference position [rad or m] at each sample.
        Ts : float, optional
            Sampling period [s]; needed for every controller but :class:`~hpdob.PD` (whose
            loop holds no state), and then :func:`simulate_loop` must be called at it.
        reference_velocity, reference_acceleration : array_like, optional
            :math:`\dot r_k`, :math:`\ddot r_k` (0 where a controller reads them and they
            are None; a PD's acceleration is used with feed-forward only).
        velocity_filter : sequence of float or None, optional
            Default ``(1, -1)``: an :class:`~hpdob.Encoder` with backward-difference
            velocity; None: an ideal sensor (the exact velocity).
        limit : float, optional
            Saturation of the command [N m or N] (the actuator's torque limit). Default none.

        Returns
        -------
        FeedbackLoop

        Raises
        ------
        ParameterTypeError, ParameterValueError
            Naming the parameter: a controller that is not one of hpdob's, reads an observer
            output or switches; a missing ``Ts``; an invalid value.

        Examples
        --------
        Against a constant load (``offset`` 2e-3 N m) a PD settles short of the reference by
        ``offset / (J_n kp)``; a PID's integral removes the error:

        >>> import numpy as np
        >>> from hpdob import PD, PID
        >>> from hpdob.identification import FeedbackLoop, simulate_loop
        >>> for controller in (PD(400.0, 40.0), PID(400.0, 2000.0, 40.0)):
        ...     loop = FeedbackLoop.from_controller(controller, nominal=2.8e-4, Ts=1e-3,
        ...                                         reference=np.ones(3000))
        ...     theta, u = simulate_loop(loop, (3.06e-4, 5e-5, 0.0, 2e-3), Ts=1e-3)
        ...     print(f"{theta[-1]:.4f}")   # 1 - 2e-3 / (2.8e-4 * 400) = 0.9821 for the PD
        0.9821
        1.0000
        """
        from ..controllers import PD, controller_system
        from ..models import ServoModel

        if not isinstance(nominal, ServoModel):
            nominal = ServoModel(
                positive(nominal, "nominal", "a ServoModel or a positive finite nominal "
                         "inertia J_n [kg m^2 or kg]")
            )  # fmt: skip
        reference = sample_vector(reference, "reference", "positions [rad or m]")
        if type(controller) is PD:
            if controller.velocity != "measured":
                raise ParameterValueError(
                    "controller must use the measured velocity (a loop without an observer), "
                    f"got PD(velocity={controller.velocity!r}), which reads omega_hat"
                )
            J_n = nominal.J
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
        if Ts is None:
            raise ParameterValueError(
                f"Ts must be given for a {type(controller).__name__}: its design depends on "
                "the sampling period [s]"
            )
        Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
        system = _check_controller(controller_system(controller, nominal, Ts), "controller")
        return cls(
            reference,
            kp=0.0,
            kd=0.0,
            reference_velocity=reference_velocity,
            reference_acceleration=reference_acceleration,
            velocity_filter=velocity_filter,
            limit=limit,
            controller=system,
        )

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

        :meth:`from_controller` for a PD:
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
        from ..controllers import PD

        controller = require_instance(controller, PD, "controller")
        J_n = positive(J_n, "J_n", "a positive finite nominal inertia [kg m^2 or kg]")
        return cls.from_controller(
            controller,
            nominal=J_n,
            reference=reference,
            reference_velocity=reference_velocity,
            reference_acceleration=reference_acceleration,
            velocity_filter=velocity_filter,
            limit=limit,
        )


#: The inputs a controller may read in a loop without an observer: the loop's signals, in the
#: order of the kernel's signal vector, and the estimate ``tau_hat`` (0).
_INPUTS = {"r": 0, "r_dot": 1, "r_ddot": 2, "theta": 3, "omega": 4, "tau_hat": 5}


def _check_controller(controller, name: str) -> LinearController:
    """``controller`` if it is a linear controller on the loop's signals and ``tau_hat``."""
    from ..controllers import LinearController

    controller = require_instance(controller, LinearController, name)
    other = [i for i in controller.inputs if i not in _INPUTS]
    if other:
        raise ParameterValueError(
            f"{name} must read only {', '.join(_INPUTS)} (a loop without an observer), got "
            f"{controller.name} reading {', '.join(other)}"
        )
    if controller.program.switch is not None:
        raise ParameterValueError(
            f"{name} must be linear, got {controller.name} with a latching switch"
        )
    return controller


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
        If the parameters cannot be simulated (``J <= 0``, ``b < 0`` or ``coulomb < 0``),
        ``Ts`` is not the period the loop's controller was designed at, or the simulated loop
        diverges.
    """
    loop = require_instance(loop, FeedbackLoop, "loop")
    return run_simulation(loop, parameters, Ts=Ts, theta0=theta0, velocity0=velocity0)


def run_simulation(loop, parameters, *, Ts, theta0=0.0, velocity0=0.0, command=True,
                   reference=None, feedforward=None, reference_velocity=None,
                   out=None, command_out=None):  # fmt: skip
    """:func:`simulate_loop` (checked as there); ``command=False`` does not record the command
    (returned as None), and ``reference``/``feedforward``/``reference_velocity`` replace the
    loop's (``loop`` may then be a length ``n``: an open-loop run, the logged input applied as
    it is, needs no :class:`FeedbackLoop` and no array of zeros). A missing input is one 0,
    not an array of the log's length: the same simulation in less memory. ``out``: a float64
    array of ``n`` samples to write the position into, which may be one of the inputs (the
    kernel reads sample ``k`` of each before it writes sample ``k``, and never again);
    ``command_out``: one to write the command into (with ``command=True``), not ``out``."""
    if len(parameters) != 4:
        raise ParameterTypeError(f"parameters must be (J, b, coulomb, offset), got {parameters!r}")
    J, b, coulomb, offset = (as_real(p, "parameters", "a finite number") for p in parameters)
    if not (J > 0.0 and b >= 0.0 and coulomb >= 0.0):
        raise ParameterValueError(
            "the loop can only be simulated with J > 0, b >= 0 and coulomb >= 0; got "
            f"J = {J:.6g}, b = {b:.6g}, coulomb = {coulomb:.6g}"
        )
    Ts = positive(Ts, "Ts", "a positive finite sampling period [s]")
    if isinstance(loop, int):  # open loop: the input alone
        n, kp, kd, c, exact, limit, controller = loop, 0.0, 0.0, None, True, None, None
        r_dot = r_ddot = None
    else:
        n, kp, kd, c, limit = len(loop), loop.kp, loop.kd, loop.velocity_filter, loop.limit
        exact, controller = loop.velocity_filter is None, loop.controller
        r_dot, r_ddot = loop.reference_velocity, loop.reference_acceleration
        r_dot = r_dot if reference_velocity is None else reference_velocity
        reference = loop.reference if reference is None else reference
        feedforward = loop.feedforward if feedforward is None else feedforward
    zero = np.zeros(1)  # a missing input: one 0 (the kernel's stride 0)
    c = np.array((1.0, -1.0) if exact else c)
    limit = math.inf if limit is None else limit
    theta = np.empty(n) if out is None else out
    u = np.empty(n if command else 1) if command_out is None else command_out
    state, source, signal_rows, update_rows = _program(
        controller, Ts, float(theta0), float(velocity0)
    )

    def given(x):
        return zero if x is None else np.ascontiguousarray(x)

    done = loop_kernel()(
        J, b, coulomb, offset, Ts, float(theta0), float(velocity0), given(reference),
        given(r_dot), given(feedforward), kp, kd, c, exact, limit, DIVERGENCE_LIMIT, theta, u,
        given(r_ddot), state, source, signal_rows, update_rows,
    )  # fmt: skip
    if done < n:
        raise ParameterValueError(
            f"the simulated loop diverged at t = {done * Ts:.6g} s with J = {J:.6g}, b = {b:.6g}, "
            f"coulomb = {coulomb:.6g}, offset = {offset:.6g}: check the loop's gains and units"
        )
    return theta, (u if command else None)


#: The kernel's arguments for the PD law: no controller state, inputs or rows.
_NO_ROWS = (np.zeros(1, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=np.int64))


def _program(controller, Ts: float, theta0: float, velocity0: float):
    """The kernel's controller arguments: its initial state ``N [theta0, velocity0, 0]``, where
    its inputs come from and its signal and update rows (empty for the PD law)."""
    if controller is None:
        return np.zeros(0), np.zeros(0, dtype=np.int64), _NO_ROWS, _NO_ROWS
    if not math.isclose(controller.Ts, Ts, rel_tol=1e-9):
        raise ParameterValueError(
            f"Ts must be the sampling period the loop's controller was designed at, "
            f"{controller.Ts!r} s, got {Ts!r}"
        )
    signal_rows, update_rows, _ = controller.kernel_arrays
    state = np.array(controller.python.reset(theta0, velocity0, 0.0), dtype=float)  # as simulate
    source = np.array([_INPUTS[name] for name in controller.inputs], dtype=np.int64)
    return np.ascontiguousarray(state), source, signal_rows, update_rows
