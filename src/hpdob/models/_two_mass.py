r"""A two-mass drive: motor and load coupled by a torsional spring and damper."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass, field

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, nonnegative, positive, readonly
from ._environment import Environment, check_environment
from ._plant import ExactSubsteps, Plant, contact_substeps, coulomb_substeps, replace_parameters

__all__ = ["DiscreteTwoMassServo", "TwoMassServo"]

_C = readonly(np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]))


@dataclass(frozen=True)
class TwoMassServo(Plant):
    r"""Motor and load coupled by a torsional spring and damper (a two-mass drive).

    With state :math:`x = [\theta_m, \omega_m, \theta_l, \omega_l]` (rad, rad/s):

    .. math::

        J_m \ddot\theta_m &= u - k(\theta_m - \theta_l) - c(\omega_m - \omega_l) - b_m\omega_m
        - f_c \tanh(\omega_m / v), \\
        J_l \ddot\theta_l &= k(\theta_m - \theta_l) + c(\omega_m - \omega_l) - b_l\omega_l
        - \tau_{ext}(t).

    The encoder, the PD and the observer are on the motor: in a simulation ``theta`` and
    ``omega`` are the motor's (``theta_load``, ``omega_load`` are recorded too) and the ground
    truth :math:`\tau_{dn}` is eq. (3) on the motor side. The external torque acts on the load.
    The linear part is integrated exactly over each sub-step (ZOH of the 4x4 model), the Coulomb
    friction of the motor by the exponential midpoint rule, as for the rigid
    :class:`~hpdob.ServoModel`.

    Parameters
    ----------
    J_motor : float
        Motor (rotor) inertia :math:`J_m` [kg m^2], positive.
    J_load : float
        Load inertia :math:`J_l` [kg m^2], positive.
    stiffness : float
        Torsional stiffness :math:`k` of the coupling [N m/rad], positive.
    damping : float, optional
        Damping :math:`c` of the coupling [N m s/rad], non-negative. Default 0.
    b_motor, b_load : float, optional
        Viscous friction of motor and load [N m s/rad], non-negative. Default 0.
    coulomb : float, optional
        Coulomb friction level of the motor [N m], non-negative. Default 0.
    coulomb_velocity : float, optional
        Velocity scale of the ``tanh`` smoothing of the Coulomb friction [rad/s]. Default 0.01.
    environment : Environment, optional
        A unilateral contact the load presses against (:class:`~hpdob.Environment`, or a dict
        of its arguments); simulated only. Default None.

    Raises
    ------
    TypeError, ValueError
        For a parameter of the wrong type or value, named in the message.

    Notes
    -----
    The coupling resonates at :math:`\omega_r = \sqrt{k (1/J_m + 1/J_l)}` (seen from the
    motor torque) with the anti-resonance :math:`\omega_a = \sqrt{k / J_l}` (the load alone on
    the spring); as :math:`k \to \infty` the plant becomes a rigid servo of inertia
    :math:`J_m + J_l`, the usual nominal inertia of a DOb on such a drive. ``docs/simulation.md``
    shows where the DOb and the HPDOb lose stability against the resonance.

    References
    ----------
    G. Ellis, R. D. Lorenz, "Resonant load control methods for industrial servo drives", IEEE
    IAS Annual Meeting, 2000 (the two-mass model); E. Sariyildiz, "A High Performance
    Disturbance Observer: A Unified Synthesis Approach", eq. (3).

    Examples
    --------
    >>> from hpdob import TwoMassServo
    >>> drive = TwoMassServo(J_motor=2.8e-4, J_load=2.8e-4, stiffness=20.0)
    >>> round(drive.resonance_frequency / (2 * 3.141592653589793), 2)  # sqrt(20 * 2/2.8e-4)/(2 pi)
    60.15
    """

    J_motor: float
    J_load: float
    stiffness: float
    damping: float = 0.0
    _: KW_ONLY
    b_motor: float = 0.0
    b_load: float = 0.0
    coulomb: float = 0.0
    coulomb_velocity: float = 0.01
    environment: Environment | None = field(default=None, repr=False)

    state_names = ("theta", "omega", "theta_load", "omega_load")

    def __post_init__(self) -> None:
        checks = {
            "J_motor": (positive, "a positive finite motor inertia [kg m^2]"),
            "J_load": (positive, "a positive finite load inertia [kg m^2]"),
            "stiffness": (positive, "a positive finite torsional stiffness [N m/rad]"),
            "damping": (nonnegative, "a non-negative finite coupling damping [N m s/rad]"),
            "b_motor": (nonnegative, "a non-negative finite viscous friction [N m s/rad]"),
            "b_load": (nonnegative, "a non-negative finite viscous friction [N m s/rad]"),
            "coulomb": (nonnegative, "a non-negative finite Coulomb friction torque [N m]"),
            "coulomb_velocity": (positive, "a positive finite velocity scale [rad/s]"),
        }
        for name, (check, what) in checks.items():
            object.__setattr__(self, name, check(getattr(self, name), name, what))
        object.__setattr__(self, "environment", check_environment(self.environment))
        A = self.A_C
        if not np.all(np.isfinite(A)):
            raise ParameterValueError(
                f"stiffness/J and damping/J must be finite, got A_C = {A.tolist()} for {self!r}"
            )

    # -- the continuous model ------------------------------------------------------------------
    @property
    def J(self) -> float:
        """Total inertia :math:`J_m + J_l` [kg m^2] (the rigid-body mode)."""
        return self.J_motor + self.J_load

    @property
    def motor_inertia(self) -> float:
        """:math:`J_m` [kg m^2]."""
        return self.J_motor

    @property
    def inertia_ratio(self) -> float:
        """Load/motor inertia ratio :math:`J_l / J_m`."""
        return self.J_load / self.J_motor

    @property
    def resonance_frequency(self) -> float:
        r""":math:`\omega_r = \sqrt{k (1/J_m + 1/J_l)}` [rad/s]."""
        return math.sqrt(self.stiffness * (1.0 / self.J_motor + 1.0 / self.J_load))

    @property
    def antiresonance_frequency(self) -> float:
        r""":math:`\omega_a = \sqrt{k / J_l}` [rad/s]."""
        return math.sqrt(self.stiffness / self.J_load)

    @property
    def A_C(self) -> np.ndarray:
        """Continuous state matrix (state ``theta, omega, theta_load, omega_load``)."""
        Jm, Jl, k, c = self.J_motor, self.J_load, self.stiffness, self.damping
        return np.array(
            [
                [0.0, 1.0, 0.0, 0.0],
                [-k / Jm, -(c + self.b_motor) / Jm, k / Jm, c / Jm],
                [0.0, 0.0, 0.0, 1.0],
                [k / Jl, c / Jl, -k / Jl, -(c + self.b_load) / Jl],
            ]
        )

    @property
    def B_C(self) -> np.ndarray:
        """Continuous input vector of the motor torque, ``[0, 1/J_m, 0, 0]``."""
        return np.array([0.0, 1.0 / self.J_motor, 0.0, 0.0])

    @property
    def D_C(self) -> np.ndarray:
        """Continuous input vector of the external torque (on the load, with a minus sign)."""
        return np.array([0.0, 0.0, 0.0, 1.0 / self.J_load])

    def coulomb_torque(self, omega):
        """Coulomb friction torque of the motor ``coulomb * tanh(omega / coulomb_velocity)``.

        Parameters
        ----------
        omega : float or array_like
            Motor velocity [rad/s].

        Returns
        -------
        ndarray
            The friction torque [N m], the shape of ``omega``.
        """
        return self.coulomb * np.tanh(np.asarray(omega, dtype=float) / self.coulomb_velocity)

    def discretize(self, Ts: float) -> DiscreteTwoMassServo:
        """Exact zero-order-hold discretisation.

        Parameters
        ----------
        Ts : float
            Sampling period [s], positive.

        Returns
        -------
        DiscreteTwoMassServo
            ``A, B, D, C`` of the four-state model (motor and load angle and velocity).
        """
        return DiscreteTwoMassServo(self, Ts)

    def replace(self, **changes) -> TwoMassServo:
        """A copy with some parameters changed (validated like the constructor).

        Parameters
        ----------
        **changes
            New values of any of the constructor's parameters.

        Returns
        -------
        TwoMassServo

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For an unknown parameter or a value the constructor rejects.
        """
        return replace_parameters(self, changes)

    # -- the plant protocol (hpdob.models.Plant) ----------------------------------------------
    def initial_state(self, x0) -> np.ndarray:
        """The plant state at the start of a run: the spring relaxed.

        Parameters
        ----------
        x0 : sequence of 2 floats
            The motor's ``[theta (rad), omega (rad/s)]``.

        Returns
        -------
        ndarray, shape (4,)
            ``[theta0, omega0, theta0, omega0]``: the load at the motor's angle and velocity.
        """
        theta, omega = (float(v) for v in x0)
        return np.array([theta, omega, theta, omega])

    def default_substeps(self, Ts: float) -> int:
        """Default plant sub-steps per sample of a simulation.

        Parameters
        ----------
        Ts : float
            Sampling period [s].

        Returns
        -------
        int
            8, more for a stiff Coulomb friction of the motor (``h c / (v J_m) <= 0.5``) or a
            stiff environment on the load (``h sqrt(k_e / J_l) <= 0.06``).
        """
        return max(coulomb_substeps(self.coulomb, self.coulomb_velocity, self.J_motor, Ts),
                   contact_substeps(self.environment, self.J_load, Ts))  # fmt: skip

    def sampler(self, Ts: float, substeps: int) -> ExactSubsteps:
        """The exact sub-step matrices the compiled kernel advances this plant with.

        Parameters
        ----------
        Ts : float
            Sampling period [s].
        substeps : int
            Sub-steps per sample.

        Returns
        -------
        ExactSubsteps
        """
        k, c = self.stiffness, self.damping
        return ExactSubsteps.of(self, Ts, substeps, shared=False, path="two-mass",
                                internal=np.array([k, c + self.b_motor, -k, -c]),
                                J_motor=self.J_motor, contact_index=2)  # fmt: skip


@dataclass(frozen=True, eq=False)
class DiscreteTwoMassServo:
    r"""Exact zero-order-hold discretisation of a :class:`TwoMassServo`.

    .. math:: x_{k+1} = A x_k + B u_k - D \tau_{ext,k}

    with :math:`[A\ B\ D] = [I\ 0\ 0]\exp\left(\begin{bmatrix}A_C & B_C & D_C\\ 0 & 0 & 0
    \end{bmatrix} T_s\right)` (``scipy.linalg.expm``). ``C`` selects the motor's angle and
    velocity, what the sensor measures.

    Parameters
    ----------
    continuous : TwoMassServo
        The continuous model.
    Ts : float
        Sampling period [s], positive.

    Attributes
    ----------
    A : ndarray, shape (4, 4)
    B, D : ndarray, shape (4,)
    C : ndarray, shape (2, 4)
    """

    continuous: TwoMassServo
    Ts: float
    A: np.ndarray = field(init=False, repr=False)
    B: np.ndarray = field(init=False, repr=False)
    D: np.ndarray = field(init=False, repr=False)

    state_names = TwoMassServo.state_names

    def __post_init__(self) -> None:
        from scipy.linalg import expm

        if not isinstance(self.continuous, TwoMassServo):
            raise ParameterTypeError(
                f"continuous must be a TwoMassServo, got {type(self.continuous).__name__}"
            )
        Ts = positive(self.Ts, "Ts", "a positive finite sampling period [s]")
        plant = self.continuous
        augmented = np.zeros((6, 6))
        augmented[:4, :4] = plant.A_C
        augmented[:4, 4] = plant.B_C
        augmented[:4, 5] = plant.D_C
        with np.errstate(all="ignore"):  # an overflow is refused just below
            E = expm(augmented * Ts)
        if not np.all(np.isfinite(E)):
            raise ParameterValueError(
                f"the ZOH discretisation of {plant!r} with Ts={Ts!r} s is not finite"
            )
        object.__setattr__(self, "Ts", Ts)
        object.__setattr__(self, "A", readonly(E[:4, :4].copy()))
        object.__setattr__(self, "B", readonly(E[:4, 4].copy()))
        object.__setattr__(self, "D", readonly(E[:4, 5].copy()))

    @property
    def C(self) -> np.ndarray:
        """Rows of the motor's angle and velocity in the state (read-only)."""
        return _C

    def step(self, x, u: float, tau: float = 0.0) -> np.ndarray:
        """One sample: ``A @ x + B * u - D * tau`` (inputs held over the sample).

        Parameters
        ----------
        x : sequence of 4 floats
            ``[theta_m, omega_m, theta_l, omega_l]`` [rad, rad/s] at sample ``k``.
        u : float
            Motor torque [N m].
        tau : float, optional
            External torque on the load [N m]. Default 0.

        Returns
        -------
        ndarray, shape (4,)
            The state at sample ``k + 1``.
        """
        return self.A @ np.asarray(x, dtype=float) + self.B * u - self.D * tau
