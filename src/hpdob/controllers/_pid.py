r"""PID at the acceleration level, with back-calculation anti-windup against the torque limit."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass

from .._validation import ParameterValueError, positive
from ._base import Controller
from ._pd import _check_pd, _command, pd_builder
from ._system import LinearController

__all__ = ["PID"]


@dataclass(frozen=True)
class PID(Controller):
    r"""PID with the observer's compensation and back-calculation anti-windup.

    .. math::

        a_k &= k_p e_k + k_d \dot e_k + I_k + \ddot r_k, \qquad
        u_k = J_n a_k + \hat\tau_k, \\
        I_{k+1} &= I_k + k_i T_s e_k + \frac{T_s}{T_t}\,\frac{\bar u_k - u_k}{J_n},

    with :math:`e = r - \theta`, :math:`\dot e = \dot r - \omega`, :math:`\bar u_k` the
    command after the actuator's torque limit and :math:`I` the integral term [rad/s^2]
    (forward-Euler integration of :math:`k_i e`). **Anti-windup by back-calculation**
    (Åström & Hägglund, *Advanced PID Control*, 2006, section 3.5): while the command is
    clipped the integral is driven back towards the value at which the command is just at
    the limit, with time constant :math:`T_t` (the tracking time); unclipped,
    :math:`\bar u = u` and it is the plain PID. The scheme is linear in
    :math:`(I, e, \bar u, u)`, so it is part of the controller's linear system (the loop
    passes :math:`\bar u` to the update) and the analysis views see the plain PID.

    Parameters
    ----------
    kp : float
        Proportional gain [1/s^2], non-negative.
    ki : float
        Integral gain [1/s^3], positive.
    kd : float
        Derivative gain [1/s], non-negative.
    tracking_time : float, optional
        :math:`T_t` [s], at least ``Ts``. Default :math:`\sqrt{T_i T_d} = \sqrt{k_d/k_i}`
        (:math:`T_i = k_p/k_i`, :math:`T_d = k_d/k_p`, the rule of thumb of Åström &
        Hägglund), or :math:`T_i` if ``kd = 0``; raised to ``Ts`` if shorter.
    feedforward : bool, optional
        Include :math:`\ddot r_k`. Default True.
    velocity : {"measured", "observer"}, optional
        As for :class:`~hpdob.PD`. Default ``"measured"``.

    References
    ----------
    K. J. Åström, T. Hägglund, *Advanced PID Control*, ISA, 2006, section 3.5 (integrator
    windup, back-calculation and tracking).

    Examples
    --------
    >>> from hpdob import PID, ServoModel
    >>> c = PID(50.0, 100.0, 5.0).design(ServoModel(2.8e-4), 1e-3)
    >>> c.n_states, c.inputs[-1], round(PID(50.0, 100.0, 5.0).tracking_time_for(1e-3), 4)
    (1, 'tau_hat', 0.2236)
    """

    kp: float
    ki: float
    kd: float
    _: KW_ONLY
    tracking_time: float | None = None
    feedforward: bool = True
    velocity: str = "measured"

    def __post_init__(self):
        _check_pd(self)
        object.__setattr__(self, "ki", positive(self.ki, "ki", "a positive integral gain [1/s^3]"))
        if self.tracking_time is not None:
            object.__setattr__(
                self,
                "tracking_time",
                positive(self.tracking_time, "tracking_time", "a positive tracking time [s]"),
            )

    def tracking_time_for(self, Ts: float) -> float:
        """The tracking time :math:`T_t` [s] of a loop at ``Ts``.

        Parameters
        ----------
        Ts : float
            Sampling period [s].

        Returns
        -------
        float
            ``tracking_time``, or the default (see the class docstring).

        Raises
        ------
        ParameterValueError
            For a given ``tracking_time`` shorter than ``Ts`` (the discrete back-calculation
            would overshoot the limit every sample).
        """
        if self.tracking_time is not None:
            if self.tracking_time < Ts:
                raise ParameterValueError(
                    f"tracking_time must be at least Ts = {Ts!r} s, got {self.tracking_time!r}"
                )
            return self.tracking_time
        default = math.sqrt(self.kd / self.ki) if self.kd > 0 else self.kp / self.ki
        return max(default, Ts)

    def design(self, nominal, Ts: float) -> LinearController:
        r"""The PID as a linear system: one state :math:`I_k`, the signals of
        :meth:`PD.design` with :math:`I_k` added to :math:`a_k`.

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
        Tt = self.tracking_time_for(Ts)
        J_n = nominal.J
        b, _ = pd_builder(self, states=("integral",))
        _command(b, self, J_n, "e_dot", ("integral", 1.0))
        back = Ts / Tt / J_n
        b.update("integral", (1.0, "integral"), (self.ki * Ts, "e", "KI_TS"),
                 (back, "u_bar", "AW"), (-back, "u", "AW", True))  # fmt: skip
        b.describe("KI_TS", "ki Ts [1/s^2]")
        b.describe("AW", "back-calculation gain Ts / (T_t J_n) [1/(kg m^2)]")
        return b.build(Ts=Ts, name=f"PID(kp={self.kp:g}, ki={self.ki:g}, kd={self.kd:g})",
                       info=(("controller", "PID, back-calculation anti-windup"),
                             ("kp", f"{self.kp!r} 1/s^2"), ("ki", f"{self.ki!r} 1/s^3"),
                             ("kd", f"{self.kd!r} 1/s"), ("T_t", f"{Tt!r} s")))  # fmt: skip
