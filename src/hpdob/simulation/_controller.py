"""Outer-loop controller: acceleration-level PD with disturbance compensation."""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass

from .._validation import ParameterTypeError, check_choice, nonnegative

#: Where the PD's derivative term takes the velocity from.
VELOCITY_SOURCES = ("measured", "observer")

__all__ = ["PD"]


@dataclass(frozen=True)
class PD:
    r"""Acceleration-level PD controller with the observer's compensation (paper, section IV).

    .. math::

        u_k = J_n\,(\ddot r_k + k_p (r_k - \theta_k) + k_d (\dot r_k - \omega_k)) + \hat\tau_k

    with :math:`J_n` the nominal inertia and :math:`\hat\tau_k` the disturbance estimate (0
    without an observer). The closed loop of the nominal plant without disturbance is
    :math:`\ddot e + k_d \dot e + k_p e = 0`.

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
        object.__setattr__(
            self, "kp", nonnegative(self.kp, "kp", "a non-negative finite gain [1/s^2]")
        )
        object.__setattr__(
            self, "kd", nonnegative(self.kd, "kd", "a non-negative finite gain [1/s]")
        )
        if not isinstance(self.feedforward, bool):
            raise ParameterTypeError(f"feedforward must be True or False, got {self.feedforward!r}")
        check_choice(self.velocity, "velocity", VELOCITY_SOURCES)

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
