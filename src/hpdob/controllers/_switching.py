r"""Position control in free space, force control on contact: a latching switch on the RTOB."""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass

from .._validation import as_real, positive
from ._base import Controller
from ._force import ForceControl
from ._pd import PD
from ._system import LinearController, ProgramBuilder

__all__ = ["PositionForceSwitch"]


@dataclass(frozen=True)
class PositionForceSwitch(Controller):
    r"""A PD on the position reference until contact, then explicit force control: latching.

    .. math::

        u_k = \begin{cases}
        J_n\,(k_p (r_k - \theta_k) + k_d (\dot r_k - \omega_k) + \ddot r_k) + \hat\tau_{dn,k}
            & \text{before the switch} \\
        (J_n\,(-K_f \hat\tau_{reac,k} - K_v \omega_k) + \hat\tau_{dn,k}) + J_n K_f \tau_{ref}
            & \text{from the first sample with } \hat\tau_{reac,k} \ge \tau_{th}
        \end{cases}

    (clipped by the actuator): the PD of :class:`~hpdob.PD` while the reaction-torque
    estimate :math:`\hat\tau_{reac}` stays below the threshold :math:`\tau_{th}`, then, for the
    rest of the run, the law of :class:`~hpdob.controllers.ForceControl` with the constant force
    reference :math:`\tau_{ref}` (the loop's reference signal stays the position reference).
    The switch is a :class:`~hpdob.controllers.Switch` of the controller program: a latch state
    (0, then 1), compared in the generated Python and in the compiled kernel alike; the
    matrices (and so the analysis views) are the position mode's.

    **Not bumpless.** The force law has no state to preset, and the command jumps at the
    switching sample from the PD's to the force law's, by
    :math:`J_n(a_{force} - a_{pos})`; a PD that still pushes toward a reference beyond the
    wall when the switch trips is the usual cause of the impact peak
    (:meth:`hpdob.SimulationResult.contact_metrics` reports it).

    Parameters
    ----------
    kp, kd : float
        The PD's gains [1/s^2], [1/s], non-negative (:class:`~hpdob.PD`).
    kf : float
        Force gain :math:`K_f` [rad/(s^2 N m)], positive (:class:`ForceControl`).
    kv : float, optional
        Velocity damping :math:`K_v` [1/s] of the force law, non-negative. Default 0.
    tau_ref : float
        Force reference [N m] after the switch, finite.
    threshold : float
        :math:`\tau_{th}` [N m], positive: the switch trips when ``tau_reac >= threshold``.
    feedforward, velocity : optional
        The PD's (:class:`~hpdob.PD`): include :math:`\ddot r` (default True), and the
        velocity its derivative term reads, ``"measured"`` (default) or ``"observer"``.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        Naming the parameter: a gain the PD or the force law refuses, a non-finite
        ``tau_ref``, a non-positive ``threshold``.

    Examples
    --------
    >>> from hpdob import ServoModel
    >>> from hpdob.controllers import PositionForceSwitch
    >>> spec = PositionForceSwitch(400.0, 40.0, 1000.0, kv=40.0, tau_ref=0.05, threshold=0.01)
    >>> c = spec.design(ServoModel(2.8e-4), 1e-3)
    >>> c.inputs, c.n_states
    (('r', 'r_dot', 'r_ddot', 'theta', 'omega', 'tau_hat', 'tau_reac'), 1)
    >>> latch = (0.0,)                    # free space: the PD, 2.8e-4 * 400 * (0.1 - 0)
    >>> round(c.python.command(latch, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), 12)
    0.0112
    >>> round(c.python.command(latch, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.02), 12)  # tripped
    0.0084
    """

    kp: float
    kd: float
    kf: float
    kv: float = 0.0
    _: KW_ONLY
    tau_ref: float
    threshold: float
    feedforward: bool = True
    velocity: str = "measured"

    def __post_init__(self):
        pd = PD(self.kp, self.kd, feedforward=self.feedforward, velocity=self.velocity)
        force = ForceControl(self.kf, kv=self.kv)
        for name, value in (("kp", pd.kp), ("kd", pd.kd), ("kf", force.kf), ("kv", force.kv)):
            object.__setattr__(self, name, value)
        object.__setattr__(
            self, "tau_ref", as_real(self.tau_ref, "tau_ref", "a finite force reference [N m]")
        )
        object.__setattr__(
            self,
            "threshold",
            positive(self.threshold, "threshold", "a positive finite switching torque [N m]"),
        )

    @property
    def position(self) -> PD:
        """The free-space controller, :class:`~hpdob.PD` (``kp``, ``kd``, ``feedforward``,
        ``velocity``)."""
        return PD(self.kp, self.kd, feedforward=self.feedforward, velocity=self.velocity)

    @property
    def force(self) -> ForceControl:
        """The contact controller, :class:`ForceControl` (``kf``, ``kv``)."""
        return ForceControl(self.kf, kv=self.kv)

    def design(self, nominal, Ts: float) -> LinearController:
        """The switching controller: one latch state, the position mode's matrices.

        Parameters
        ----------
        nominal : ServoModel
            Its ``J`` is :math:`J_n`.
        Ts : float
            Sampling period [s].

        Returns
        -------
        LinearController
            With a :class:`~hpdob.controllers.Switch` in its program.
        """
        pd, force = self.position, self.force
        omega = "omega_hat" if pd.velocity == "observer" else "omega"
        inputs = ("r", "r_dot", *(("r_ddot",) if pd.feedforward else ()), "theta", "omega")
        if omega == "omega_hat":
            inputs += ("omega_hat",)
        inputs += ("tau_hat", "tau_reac")
        b = ProgramBuilder(inputs, ("latch",))
        b.signal("e", (1.0, "r"), (-1.0, "theta"))
        b.signal("e_dot", (1.0, "r_dot"), (-1.0, omega))
        terms = [(pd.kp, "e", "KP"), (pd.kd, "e_dot", "KD")]
        if pd.feedforward:
            terms.append((1.0, "r_ddot"))
        b.signal("a_pos", *terms)
        b.signal("u_pos", (nominal.J, "a_pos", "J_N"), (1.0, "tau_hat"))
        b.signal("a_force", (-force.kf, "tau_reac", "MINUS_KF"), (-force.kv, "omega", "MINUS_KV"))
        b.signal("u_force", (nominal.J, "a_force", "J_N"), (1.0, "tau_hat"))
        b.signal("u", (1.0, "u_pos"))
        b.switch(trigger="tau_reac", threshold=self.threshold, latch="latch", after="u_force",
                 offset=nominal.J * force.kf * self.tau_ref)  # fmt: skip
        b.describe("KP", "proportional gain [1/s^2]")
        b.describe("KD", "derivative gain [1/s]")
        b.describe("MINUS_KF", "-(force gain [rad/(s^2 N m)])")
        b.describe("MINUS_KV", "-(velocity damping [1/s])")
        b.describe("J_N", "nominal inertia [kg m^2]")
        return b.build(
            Ts=Ts,
            name=(f"PositionForceSwitch(kp={pd.kp:g}, kd={pd.kd:g}, kf={force.kf:g}, "
                  f"kv={force.kv:g}, tau_ref={self.tau_ref:g}, threshold={self.threshold:g})"),
            info=(
                ("controller", "position control, then force control from tau_reac >= threshold"),
                ("kp, kd", f"{pd.kp!r} 1/s^2, {pd.kd!r} 1/s"),
                ("kf, kv", f"{force.kf!r} rad/(s^2 N m), {force.kv!r} 1/s"),
                ("tau_ref", f"{self.tau_ref!r} N m"),
                ("threshold", f"{self.threshold!r} N m"),
            ),
        )  # fmt: skip
