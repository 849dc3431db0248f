r"""Force control without a force sensor: explicit force and impedance control on the RTOB."""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass

from .._validation import nonnegative, positive
from ._base import Controller
from ._system import LinearController, ProgramBuilder

__all__ = ["ForceControl", "ImpedanceControl"]


@dataclass(frozen=True)
class ForceControl(Controller):
    r"""Explicit force control on the reaction-torque estimate, inside the DOb's loop.

    .. math::

        a_{ref,k} = K_f(\tau_{ref,k} - \hat\tau_{reac,k}) - K_v\,\omega_k,\qquad
        u_k = J_n a_{ref,k} + \hat\tau_{dn,k}

    (clipped by the actuator). The force reference :math:`\tau_{ref}` [N m] is the loop's
    reference signal ``r`` (``simulate(..., reference=...)``: its first entry, read in N m);
    :math:`\hat\tau_{reac}` is the observer output ``tau_reac``
    (:func:`hpdob.observers.reaction_torque_observer`), :math:`\hat\tau_{dn}` its ``tau_hat``.

    Parameters
    ----------
    kf : float
        Force gain :math:`K_f` [rad/(s^2 N m)], positive.
    kv : float, optional
        Velocity damping :math:`K_v` [1/s], non-negative. Default 0.

    References
    ----------
    S. Katsura, Y. Matsumoto, K. Ohnishi, "Modeling of force sensing and validation of
    disturbance observer for force control", IEEE Trans. Ind. Electron. 54(1), 2007.

    Examples
    --------
    >>> from hpdob import ServoModel
    >>> from hpdob.controllers import ForceControl
    >>> c = ForceControl(2000.0, kv=20.0).design(ServoModel(3.06e-4), 1e-3)
    >>> c.inputs
    ('r', 'omega', 'tau_hat', 'tau_reac')
    """

    kf: float
    kv: float = 0.0

    def __post_init__(self):
        object.__setattr__(
            self, "kf", positive(self.kf, "kf", "a positive force gain [rad/(s^2 N m)]")
        )
        object.__setattr__(self, "kv", nonnegative(self.kv, "kv", "a non-negative damping [1/s]"))

    def design(self, nominal, Ts: float) -> LinearController:
        """The force controller as a linear system (no state).

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
        b = ProgramBuilder(("r", "omega", "tau_hat", "tau_reac"))
        b.signal(
            "a_ref",
            (self.kf, "r", "KF"),
            (-self.kf, "tau_reac", "MINUS_KF"),
            (-self.kv, "omega", "MINUS_KV"),
        )
        b.signal("u", (nominal.J, "a_ref", "J_N"), (1.0, "tau_hat"))
        b.describe("KF", "force gain [rad/(s^2 N m)]")
        b.describe("MINUS_KF", "-KF")
        b.describe("MINUS_KV", "-(velocity damping [1/s])")
        b.describe("J_N", "nominal inertia [kg m^2]")
        return b.build(
            Ts=Ts,
            name=f"ForceControl(kf={self.kf:g}, kv={self.kv:g})",
            info=(
                ("controller", "explicit force control"),
                ("kf", f"{self.kf!r} rad/(s^2 N m)"),
                ("kv", f"{self.kv!r} 1/s"),
            ),
        )


@dataclass(frozen=True)
class ImpedanceControl(Controller):
    r"""Impedance control on the reaction-torque estimate, inside the DOb's loop.

    .. math::

        a_{ref,k} = \ddot r_k + \frac{-D_d(\omega_k - \dot r_k) - K_d(\theta_k - r_k)
            - \hat\tau_{reac,k}}{M_d},\qquad u_k = J_n a_{ref,k} + \hat\tau_{dn,k}

    (clipped by the actuator): the axis behaves as the target impedance
    :math:`M_d\ddot e + D_d\dot e + K_d e = -\tau_{reac}` about the reference. Against a
    spring :math:`k_e` at :math:`\theta_e` it rests at
    :math:`\theta = (K_d r + k_e\theta_e)/(K_d + k_e)`.

    Parameters
    ----------
    M_d : float
        Target inertia [kg m^2], positive.
    D_d : float
        Target damping [N m s/rad], non-negative.
    K_d : float
        Target stiffness [N m/rad], non-negative.

    Examples
    --------
    >>> from hpdob import ServoModel
    >>> from hpdob.controllers import ImpedanceControl
    >>> c = ImpedanceControl(M_d=3e-4, D_d=0.01, K_d=0.1).design(ServoModel(3.06e-4), 1e-3)
    >>> c.inputs
    ('r', 'r_dot', 'r_ddot', 'theta', 'omega', 'tau_hat', 'tau_reac')
    """

    _: KW_ONLY
    M_d: float
    D_d: float
    K_d: float

    def __post_init__(self):
        object.__setattr__(
            self, "M_d", positive(self.M_d, "M_d", "a positive target inertia [kg m^2]")
        )
        object.__setattr__(
            self, "D_d", nonnegative(self.D_d, "D_d", "a non-negative target damping [N m s/rad]")
        )
        object.__setattr__(
            self, "K_d", nonnegative(self.K_d, "K_d", "a non-negative target stiffness [N m/rad]")
        )

    def design(self, nominal, Ts: float) -> LinearController:
        """The impedance controller as a linear system (no state).

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
        b = ProgramBuilder(("r", "r_dot", "r_ddot", "theta", "omega", "tau_hat", "tau_reac"))
        b.signal("e", (1.0, "r"), (-1.0, "theta"))
        b.signal("e_dot", (1.0, "r_dot"), (-1.0, "omega"))
        b.signal(
            "a_ref",
            (1.0, "r_ddot"),
            (self.K_d / self.M_d, "e", "KD_M"),
            (self.D_d / self.M_d, "e_dot", "DD_M"),
            (-1.0 / self.M_d, "tau_reac", "MINUS_INV_M"),
        )
        b.signal("u", (nominal.J, "a_ref", "J_N"), (1.0, "tau_hat"))
        b.describe("KD_M", "K_d / M_d [1/s^2]")
        b.describe("DD_M", "D_d / M_d [1/s]")
        b.describe("MINUS_INV_M", "-1 / M_d [1/(kg m^2)]")
        b.describe("J_N", "nominal inertia [kg m^2]")
        return b.build(
            Ts=Ts,
            name=f"ImpedanceControl(M_d={self.M_d:g}, D_d={self.D_d:g}, K_d={self.K_d:g})",
            info=(
                ("controller", "impedance control"),
                ("M_d", f"{self.M_d!r} kg m^2"),
                ("D_d", f"{self.D_d!r} N m s/rad"),
                ("K_d", f"{self.K_d!r} N m/rad"),
            ),
        )
