r"""The plant bonded to its environment: the linear model of the loop in contact."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, readonly
from ._plant import ExactSubsteps, Plant

__all__ = ["InContact"]


@dataclass(frozen=True)
class InContact(Plant):
    r"""A rigid servo or two-mass drive held in contact with its environment (bilateral).

    The unilateral :class:`~hpdob.Environment` of ``plant`` becomes a permanent spring-damper:
    with :math:`\theta_c, \omega_c` the contacting angle and velocity (the rigid axis, or the
    two-mass load), measured from the contact position :math:`\theta_e`,

    .. math:: \dot x = (A_C - D_C [\ldots, k_e, c_e, \ldots]) x + B_C u - D_C \tau_{ext},

    a linear plant: its ``discretize`` is the exact ZOH model of plant + spring that the analysis
    views (:func:`hpdob.closed_loop`, :func:`hpdob.closed_loop_poles`, margins) use for the loop
    in contact, and it simulates as that linear plant (no release). Coulomb friction is left to
    the simulation, as for the plant itself.

    Parameters
    ----------
    plant : ServoModel or TwoMassServo
        A plant with an ``environment``; angles of the result are measured from
        ``environment.position``.

    Raises
    ------
    ParameterTypeError
        If ``plant`` is not a ServoModel or TwoMassServo.
    ParameterValueError
        If it has no environment.

    Examples
    --------
    >>> from hpdob import Environment, ServoModel
    >>> from hpdob.models import InContact
    >>> model = InContact(ServoModel(3.06e-4, environment=Environment(10.0))).discretize(1e-3)
    >>> round(float(model.A[1, 0]), 2)          # about -k_e Ts / J = -32.68
    -32.5
    """

    plant: object
    A_C: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        from ._servo import ServoModel
        from ._two_mass import TwoMassServo

        if not isinstance(self.plant, (ServoModel, TwoMassServo)):
            raise ParameterTypeError(
                f"plant must be a ServoModel or TwoMassServo, got {type(self.plant).__name__}"
            )
        wall = self.plant.environment
        if wall is None:
            raise ParameterValueError(
                "plant must have an environment (plant.environment is None) to be in contact"
            )
        index = 0 if isinstance(self.plant, ServoModel) else 2
        row = np.zeros(len(self.plant.state_names))
        row[index], row[index + 1] = wall.stiffness, wall.damping
        A_C = np.asarray(self.plant.A_C) - np.outer(self.plant.D_C, row)
        object.__setattr__(self, "A_C", readonly(A_C))

    @property
    def state_names(self):
        """The plant's state names."""
        return self.plant.state_names

    @property
    def J(self) -> float:
        """The motor's inertia [kg m^2]."""
        return self.plant.motor_inertia

    @property
    def coulomb(self) -> float:
        """The plant's Coulomb friction [N m]."""
        return self.plant.coulomb

    @property
    def coulomb_velocity(self) -> float:
        """The plant's Coulomb velocity scale [rad/s]."""
        return self.plant.coulomb_velocity

    def initial_state(self, x0) -> np.ndarray:
        """The plant's initial state (see the plant's ``initial_state``).

        Parameters
        ----------
        x0 : sequence of 2 floats
            The motor's ``[theta (rad), omega (rad/s)]``, from the contact position.

        Returns
        -------
        ndarray
        """
        return self.plant.initial_state(x0)

    def default_substeps(self, Ts: float) -> int:
        """The plant's default sub-steps.

        Parameters
        ----------
        Ts : float
            Sampling period [s].

        Returns
        -------
        int
        """
        return self.plant.default_substeps(Ts)

    def discretize(self, Ts: float):
        """The exact ZOH model of plant + spring-damper.

        Parameters
        ----------
        Ts : float
            Sampling period [s].

        Returns
        -------
        DiscreteInContact
            With ``A, B, D, C``, ``state_names`` and ``Ts``.
        """
        return DiscreteInContact(self, Ts)

    def sampler(self, Ts: float, substeps: int) -> ExactSubsteps:
        """Exact sub-steps of the linear plant in contact (the generic compiled path).

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
        inner = self.plant.sampler(Ts, substeps)
        internal = np.array(inner.internal, dtype=float)
        if inner.shared:  # the spring acts on the motor itself: part of its acceleration
            wall = self.plant.environment
            internal = internal + np.array([wall.stiffness, wall.damping])
        h = Ts / substeps
        full, half = self.discretize(h), self.discretize(h / 2)
        return ExactSubsteps(A_h=full.A, B_h=full.B, D_h=full.D, A_half=half.A, B_half=half.B,
                             D_half=half.D, shared=inner.shared, internal=internal,
                             J_motor=inner.J_motor, coulomb=self.coulomb,
                             coulomb_velocity=self.coulomb_velocity, path="generic")  # fmt: skip


@dataclass(frozen=True, eq=False)
class DiscreteInContact:
    """Exact ZOH model of an :class:`InContact` plant: ``x+ = A x + B u - D tau``.

    Parameters
    ----------
    continuous : InContact
        The plant in contact.
    Ts : float
        Sampling period [s].
    """

    continuous: InContact
    Ts: float
    A: np.ndarray = field(init=False, repr=False)
    B: np.ndarray = field(init=False, repr=False)
    D: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        from scipy.linalg import expm

        plant = self.continuous.plant
        n = len(plant.state_names)
        augmented = np.zeros((n + 2, n + 2))
        augmented[:n, :n] = self.continuous.A_C
        augmented[:n, n] = plant.B_C
        augmented[:n, n + 1] = plant.D_C
        E = expm(augmented * self.Ts)
        object.__setattr__(self, "A", readonly(E[:n, :n].copy()))
        object.__setattr__(self, "B", readonly(E[:n, n].copy()))
        object.__setattr__(self, "D", readonly(E[:n, n + 1].copy()))

    @property
    def state_names(self):
        """The plant's state names."""
        return self.continuous.state_names

    @property
    def C(self) -> np.ndarray:
        """Rows of the motor's angle and velocity in the state."""
        C = np.zeros((2, len(self.state_names)))
        C[0, 0] = C[1, 1] = 1.0
        return C
