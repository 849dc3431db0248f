r"""The PD of the paper's section IV, and the PD with a first-order filtered derivative."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass

from .._validation import ParameterTypeError, check_choice, nonnegative, positive
from ._base import Controller
from ._system import LinearController, ProgramBuilder

__all__ = ["PD", "VELOCITY_SOURCES", "FilteredPD"]

#: Where the derivative term takes the velocity from: the sensor's, or the observer's
#: ``omega_hat`` (the controller input of that name).
VELOCITY_SOURCES = ("measured", "observer")


def _check_pd(controller) -> None:
    object.__setattr__(
        controller, "kp", nonnegative(controller.kp, "kp", "a non-negative finite gain [1/s^2]")
    )
    object.__setattr__(
        controller, "kd", nonnegative(controller.kd, "kd", "a non-negative finite gain [1/s]")
    )
    if not isinstance(controller.feedforward, bool):
        raise ParameterTypeError(
            f"feedforward must be True or False, got {controller.feedforward!r}"
        )
    check_choice(controller.velocity, "velocity", VELOCITY_SOURCES)


def pd_builder(controller, states=()) -> tuple[ProgramBuilder, str]:
    """The inputs of a PD-like controller and its error signals ``e = r - theta`` and
    ``e_dot = r_dot - omega`` (``omega_hat`` with ``velocity="observer"``)."""
    omega = "omega_hat" if controller.velocity == "observer" else "omega"
    inputs = ("r", "r_dot", *(("r_ddot",) if controller.feedforward else ()), "theta", omega,
              "tau_hat")  # fmt: skip
    b = ProgramBuilder(inputs, states)
    b.signal("e", (1.0, "r"), (-1.0, "theta"))
    b.signal("e_dot", (1.0, "r_dot"), (-1.0, omega))
    return b, omega


def _command(b: ProgramBuilder, controller, J_n: float, derivative: str, *extra) -> None:
    """``a_ref = kp e + kd (e_dot or its filtered value) [+ extra terms] [+ r_ddot]`` and
    ``u = J_n a_ref + tau_hat``; ``extra`` are ``(operand, coefficient)`` pairs."""
    terms = [(controller.kp, "e", "KP"), (controller.kd, derivative, "KD")]
    terms += [(coefficient, operand) for operand, coefficient in extra]
    if controller.feedforward:
        terms.append((1.0, "r_ddot"))
    b.signal("a_ref", *terms)
    b.signal("u", (J_n, "a_ref", "J_N"), (1.0, "tau_hat"))
    b.describe("KP", "proportional gain [1/s^2]")
    b.describe("KD", "derivative gain [1/s]")
    b.describe("J_N", "nominal inertia [kg m^2]")


@dataclass(frozen=True)
class PD(Controller):
    r"""Acceleration-level PD controller with the observer's compensation (paper, section IV).

    .. math::

        u_k = J_n\,(k_p (r_k - \theta_k) + k_d (\dot r_k - \omega_k) + \ddot r_k) + \hat\tau_k

    with :math:`J_n` the nominal inertia and :math:`\hat\tau_k` the disturbance estimate (0
    without an observer). The closed loop of the nominal plant without disturbance is
    :math:`\ddot e + k_d \dot e + k_p e = 0`. As a :class:`~hpdob.controllers.LinearController`
    it has no state and its program is this expression term for term (:meth:`design`).

    Parameters
    ----------
    kp : float
        Proportional gain [1/s^2], non-negative.
    kd : float
        Derivative gain [1/s], non-negative.
    feedforward : bool, optional
        Include the reference acceleration :math:`\ddot r_k`. Default True.
    velocity : {"measured", "observer"}, optional
        The velocity :math:`\omega_k` of the derivative term: the sensor's (``"measured"``,
        default; with an encoder its backward difference) or the observer's estimate
        :math:`\hat\omega_k` (``"observer"``, for position-only observers, which estimate
        the velocity along with the disturbance).

    Examples
    --------
    >>> from hpdob import PD
    >>> u = PD(50.0, 5.0).torque(J_n=2.8e-4, r=1.0, r_dot=0.0, r_ddot=0.0, theta=0.9, omega=0.0)
    >>> round(u, 12)  # 2.8e-4 * 50 * 0.1 [N m]
    0.0014
    """

    kp: float
    kd: float
    _: KW_ONLY
    feedforward: bool = True
    velocity: str = "measured"

    def __post_init__(self):
        _check_pd(self)

    def design(self, nominal, Ts: float) -> LinearController:
        r"""The PD as a linear system: no state, the signals
        :math:`e = r - \theta`, :math:`\dot e = \dot r - \omega`,
        :math:`a_{ref} = k_p e + k_d \dot e + \ddot r`, :math:`u = J_n a_{ref} + \hat\tau`.

        Parameters
        ----------
        nominal : ServoModel
            Its ``J`` is :math:`J_n`.
        Ts : float
            Sampling period [s].

        Returns
        -------
        LinearController
            Inputs ``r, r_dot, (r_ddot), theta, omega (or omega_hat), tau_hat``.

        Examples
        --------
        >>> from hpdob import PD, ServoModel
        >>> c = PD(50.0, 5.0).design(ServoModel(2e-4), 1e-3)
        >>> c.inputs
        ('r', 'r_dot', 'r_ddot', 'theta', 'omega', 'tau_hat')
        >>> c.E.round(6).tolist()    # J_n (kp, kd, 1, -kp, -kd) and 1
        [[0.01, 0.001, 0.0002, -0.01, -0.001, 1.0]]
        """
        b, _ = pd_builder(self)
        _command(b, self, nominal.J, "e_dot")
        return b.build(Ts=Ts, name=f"PD(kp={self.kp:g}, kd={self.kd:g})",
                       info=(("controller", "PD"), ("kp", f"{self.kp!r} 1/s^2"),
                             ("kd", f"{self.kd!r} 1/s")))  # fmt: skip

    def torque(
        self,
        *,
        J_n: float,
        r: float,
        r_dot: float,
        r_ddot: float,
        theta: float,
        omega: float,
        tau_hat: float = 0.0,
    ) -> float:
        """Control torque for one sample (see the class docstring).

        Parameters
        ----------
        J_n : float
            Nominal inertia [kg m^2] that scales the acceleration command.
        r, r_dot, r_ddot : float
            Reference angle [rad], velocity [rad/s] and acceleration [rad/s^2] (the latter
            used only with ``feedforward``).
        theta, omega : float
            Measured angle [rad] and the velocity [rad/s] the D term uses.
        tau_hat : float, optional
            Disturbance estimate [N m] added as compensation. Default 0.

        Returns
        -------
        float
            ``J_n (kp (r - theta) + kd (r_dot - omega) [+ r_ddot]) + tau_hat`` [N m].

        Examples
        --------
        >>> from hpdob import PD
        >>> u = PD(50.0, 5.0).torque(J_n=2.0e-4, r=1.0, r_dot=0.0, r_ddot=3.0, theta=0.9,
        ...                          omega=0.2, tau_hat=0.001)
        >>> round(u, 12)   # 2e-4 (50 0.1 - 5 0.2 + 3) + 1e-3
        0.0024
        """
        acc = self.kp * (r - theta) + self.kd * (r_dot - omega)
        if self.feedforward:
            acc += r_ddot
        return J_n * acc + tau_hat


@dataclass(frozen=True)
class FilteredPD(Controller):
    r"""PD whose derivative term is low-passed by a first-order filter of time constant
    :math:`T_f`.

    .. math::

        d_k = a\,d_{k-1} + (1 - a)(\dot r_k - \omega_k),\qquad a = e^{-T_s/T_f},\\
        u_k = J_n\,(k_p (r_k - \theta_k) + k_d d_k + \ddot r_k) + \hat\tau_k,

    the exact (ZOH) discretisation of :math:`T_f \dot d + d = \dot e` for an input held over
    each sample: unity DC gain, a pole at :math:`a`. With an encoder the velocity is the
    backward difference of the angle, so :math:`d` is the classical filtered derivative
    :math:`s/(1 + T_f s)` of the error. A run starts with the filter converged on a
    reference at rest, :math:`d_{-1} = -\omega_0`.

    Parameters
    ----------
    kp : float
        Proportional gain [1/s^2], non-negative.
    kd : float
        Derivative gain [1/s], non-negative.
    time_constant : float
        :math:`T_f` [s], positive.
    feedforward : bool, optional
        Include :math:`\ddot r_k`. Default True.
    velocity : {"measured", "observer"}, optional
        As for :class:`PD`. Default ``"measured"``.

    Examples
    --------
    >>> from hpdob import FilteredPD, ServoModel
    >>> c = FilteredPD(50.0, 5.0, time_constant=2e-3).design(ServoModel(2.8e-4), 1e-3)
    >>> c.n_states, round(float(c.F[0, 0]), 6)      # the filter's pole exp(-1/2)
    (1, 0.606531)
    """

    kp: float
    kd: float
    _: KW_ONLY
    time_constant: float
    feedforward: bool = True
    velocity: str = "measured"

    def __post_init__(self):
        _check_pd(self)
        object.__setattr__(
            self,
            "time_constant",
            positive(self.time_constant, "time_constant", "a positive filter time constant [s]"),
        )

    def design(self, nominal, Ts: float) -> LinearController:
        r"""The filtered PD as a linear system: one state :math:`d_{k-1}`, the signals of
        :meth:`PD.design` with :math:`d_k` in place of :math:`\dot e_k`.

        Parameters
        ----------
        nominal : ServoModel
            Its ``J`` is :math:`J_n`.
        Ts : float
            Sampling period [s].

        Returns
        -------
        LinearController
        """
        a = math.exp(-Ts / self.time_constant)
        b, _ = pd_builder(self, states=("d",))
        b.signal("d_now", (a, "d", "A_F"), (1.0 - a, "e_dot", "B_F"))
        _command(b, self, nominal.J, "d_now")
        b.update("d", (1.0, "d_now"))
        b.reset("d", (-1.0, "omega0"))
        b.describe("A_F", "derivative filter pole exp(-Ts/T_f)")
        b.describe("B_F", "1 - A_F")
        return b.build(Ts=Ts, name=f"FilteredPD(kp={self.kp:g}, kd={self.kd:g}, "
                       f"T_f={self.time_constant:g})",
                       info=(("controller", "filtered PD"), ("kp", f"{self.kp!r} 1/s^2"),
                             ("kd", f"{self.kd!r} 1/s"),
                             ("T_f", f"{self.time_constant!r} s")))  # fmt: skip
