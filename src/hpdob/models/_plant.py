r"""The plant protocol: what the sampled-data loop needs from a plant.

A plant (:class:`Plant`) gives the loop

* its **state** (``state_names``, ``initial_state(x0)`` from the motor's angle and velocity);
* its **advance over one sample** in sub-steps (``sampler(Ts, substeps)``), as one of two
  kinds: :class:`ExactSubsteps`, the matrices of a plant whose linear part is integrated exactly
  over each sub-step with motor-side Coulomb friction (advanced by the compiled kernel: the
  rigid :class:`~hpdob.ServoModel`, the :class:`~hpdob.TwoMassServo`), or an object with the
  :class:`PlantSession` methods, advanced from Python (:class:`~hpdob.MujocoServo`);
* where the motor's :math:`\theta, \omega` and the eq. (3) ground truth come from (the first
  state entry and ``velocity_index``; the motor acceleration just after a command);
* its **linear ZOH model** for the analysis views (``discretize(Ts)``: ``A, B, D, C`` with
  :math:`x_{k+1} = A x_k + B a_k - D \tau_{ext,k}` and ``C`` the rows of the motor's
  :math:`\theta, \omega`).
"""

from __future__ import annotations

import dataclasses
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, as_int

__all__ = [
    "DEFAULT_SUBSTEPS",
    "MAX_PLANT_STEPS",
    "SUBSTEP_PATHS",
    "ExactSubsteps",
    "Plant",
    "PlantSession",
    "coulomb_substeps",
]

#: Default plant sub-steps per sample. Doubling it changes the canonical metrics by < 0.1 %
#: (tests/simulation/test_simulate.py::test_substep_convergence).
DEFAULT_SUBSTEPS = 8
#: Largest ``h c / (v J)`` (sub-step times the stiffness of the Coulomb term
#: ``c tanh(omega / v)``) of the default sub-step count; the midpoint rule is unstable above 2.
_COULOMB_STEP = 0.5
#: Most plant steps (samples times sub-steps) one run may take: 1e8 steps need 0.8 GB.
MAX_PLANT_STEPS = 100_000_000
#: The compiled kernel's sub-step paths, by name (the index is what the kernel reads): the rigid
#: servo's 2 states kept in registers, the two-mass drive's 4, and the generic loop over any
#: state size. A plant names its path in :class:`ExactSubsteps`; nothing is inferred from its
#: state size.
SUBSTEP_PATHS = ("rigid", "two-mass", "generic")
#: What each specialised path assumes: ``(states, shared, velocity_index)``.
_PATH_SHAPES = {"rigid": (2, True, 1), "two-mass": (4, False, 1)}


def coulomb_substeps(coulomb: float, velocity: float, J: float, Ts: float) -> int:
    """Default sub-steps per sample: :data:`DEFAULT_SUBSTEPS`, or more (an even number) when
    the Coulomb friction is so stiff that ``h c / (v J)`` would exceed 0.5.

    Near ``omega = 0`` the friction ``c tanh(omega / v)`` acts like a damper ``c / v``, which
    the explicit midpoint rule only integrates accurately for ``h c / (v J) <= 0.5``
    (``tests/simulation/test_simulate.py::test_stiff_coulomb_friction_converges``).
    """
    per_sample = Ts * (coulomb / velocity / J) if coulomb > 0.0 else 0.0  # Ts * stiffness
    if not per_sample <= MAX_PLANT_STEPS:  # also inf (overflow)
        raise ParameterValueError(
            f"plant Coulomb friction is too stiff to integrate: Ts c/(v J) = {per_sample:.3g} "
            f"for coulomb={coulomb!r} N m, coulomb_velocity={velocity!r} rad/s, J={J!r} kg m^2 "
            f"would need more than {MAX_PLANT_STEPS:.0e} sub-steps per sample; raise "
            "coulomb_velocity"
        )
    return max(DEFAULT_SUBSTEPS, 2 * math.ceil(per_sample / (2.0 * _COULOMB_STEP)))


@dataclass(frozen=True, eq=False)
class ExactSubsteps:
    r"""A plant advanced by the compiled kernel: exact ZOH sub-steps plus motor Coulomb friction.

    Over each sub-step of ``h = Ts/S``,
    :math:`x_{j+1} = A_h x_j + B_h (a - F_c(\omega_m)) - D_h \tau_{ext}` with
    :math:`F_c = c \tanh(\omega_m / v)` evaluated at the exponential midpoint (``_half``: the
    same matrices over ``h/2``). The motor acceleration (for eq. 3) is
    ``(a - internal @ x - F_c - [tau_ext]) / J_motor``.

    Attributes
    ----------
    A_h, B_h, D_h : ndarray
        The ZOH matrices over a sub-step ``h``.
    A_half, B_half, D_half : ndarray
        The same over ``h/2`` (for the midpoint of the friction).
    shared : bool
        The external torque acts where the command does (``D == B``); the forces are then
        summed before the product, as for the rigid servo.
    internal : ndarray
        Row giving the internal torque on the motor from the state (viscous friction,
        spring and damper) [N m].
    J_motor : float
        Motor inertia [kg m^2].
    coulomb, coulomb_velocity : float
        The motor's Coulomb friction level [N m] and ``tanh`` velocity scale [rad/s].
    velocity_index : int
        Index of the motor velocity in the state. Default 1.
    path : {"rigid", "two-mass", "generic"}
        Which compiled sub-step path advances the plant (:data:`SUBSTEP_PATHS`): the
        specialised ones hold the state in registers and require its shape (2 states, shared
        external torque; 4 states, external torque on the load; motor velocity at index 1),
        ``"generic"`` (default) runs any state size.
    environment : Environment or None
        A unilateral contact (:class:`~hpdob.Environment`) on the state entries
        ``contact_index`` (angle) and ``contact_index + 1`` (velocity), its torque acting
        where the external torque does (``D``). Default None.
    contact_index : int
        Index of the contacting angle in the state (0: the rigid servo, 2: a two-mass load).

    Raises
    ------
    ParameterValueError
        For an unknown ``path`` or one whose shape the matrices do not have.
    """

    A_h: np.ndarray
    B_h: np.ndarray
    D_h: np.ndarray
    A_half: np.ndarray
    B_half: np.ndarray
    D_half: np.ndarray
    shared: bool
    internal: np.ndarray
    J_motor: float
    coulomb: float
    coulomb_velocity: float
    velocity_index: int = 1
    path: str = "generic"
    environment: object = None
    contact_index: int = 0

    def __post_init__(self):
        if self.path not in SUBSTEP_PATHS:
            raise ParameterValueError(
                f"path must be one of {', '.join(SUBSTEP_PATHS)}, got {self.path!r}"
            )
        shape = (np.shape(self.A_h)[0], bool(self.shared), int(self.velocity_index))
        if self.path in _PATH_SHAPES and shape != _PATH_SHAPES[self.path]:
            raise ParameterValueError(
                f"path {self.path!r} needs (states, shared, velocity_index) = "
                f"{_PATH_SHAPES[self.path]}, got {shape}"
            )

    @property
    def path_index(self) -> int:
        """The index of :attr:`path` in :data:`SUBSTEP_PATHS` (what the kernel reads)."""
        return SUBSTEP_PATHS.index(self.path)

    @classmethod
    def of(cls, plant, Ts: float, substeps: int, **structure) -> ExactSubsteps:
        """The sub-step matrices of a plant with a linear model.

        Parameters
        ----------
        plant : Plant
            A plant whose ``discretize`` gives its ZOH model, with ``coulomb`` and
            ``coulomb_velocity``.
        Ts : float
            Sampling period [s].
        substeps : int
            Sub-steps per sample.
        **structure
            ``shared``, ``internal``, ``J_motor`` and optionally ``path``,
            ``velocity_index`` and ``contact_index`` (see the attributes).

        Returns
        -------
        ExactSubsteps
            With the matrices of ``plant.discretize`` over ``h = Ts/substeps`` and ``h/2``.
        """
        h = Ts / substeps
        full, half = plant.discretize(h), plant.discretize(h / 2)
        return cls(A_h=full.A, B_h=full.B, D_h=full.D, A_half=half.A, B_half=half.B,
                   D_half=half.D, coulomb=plant.coulomb,
                   coulomb_velocity=plant.coulomb_velocity,
                   environment=getattr(plant, "environment", None), **structure)  # fmt: skip


def replace_parameters(plant, changes: dict):
    """A copy of the dataclass ``plant`` with ``changes`` applied, through its constructor
    (validated like it); an unknown name is a TypeError listing the valid ones."""
    names = [f.name for f in dataclasses.fields(plant) if f.init and f.name != "_"]
    unknown = sorted(set(changes) - set(names))
    if unknown:
        raise ParameterTypeError(
            f"replace() got unknown parameter(s) {unknown}; valid: {sorted(names)}"
        )
    return type(plant)(**{**{name: getattr(plant, name) for name in names}, **changes})


class PlantSession(ABC):
    """One run of a plant advanced from Python (e.g. MuJoCo), at a given state."""

    @abstractmethod
    def motor(self) -> tuple[float, float]:
        """The motor's angle [rad] and velocity [rad/s] now.

        Returns
        -------
        tuple of float
            ``(theta, omega)``.
        """

    @abstractmethod
    def acceleration(self, applied: float, tau: float) -> float:
        """Motor acceleration just after a torque is applied (for the ground truth of eq. 3).

        Parameters
        ----------
        applied : float
            The motor torque applied [N m].
        tau : float
            The external torque at that instant [N m].

        Returns
        -------
        float
            The motor's angular acceleration [rad/s^2].
        """

    @abstractmethod
    def advance(self, applied: float, tau_mid: np.ndarray) -> None:
        """Advance the run over one sample.

        Parameters
        ----------
        applied : float
            The motor torque [N m], held over the sample.
        tau_mid : ndarray, shape (substeps,)
            The external torque [N m] at the midpoints of the sub-steps.
        """

    @abstractmethod
    def diverged(self, limit: float) -> bool:
        """Whether the run has diverged.

        Parameters
        ----------
        limit : float
            Bound on the magnitude of every state entry (SI units).

        Returns
        -------
        bool
            True if the state left ``|x| <= limit`` or the plant flagged an unstable run.
        """

    def states(self) -> np.ndarray | None:
        """The full plant state, when it is worth recording (None: the motor's only)."""
        return None

    def contact(self) -> tuple[float, float] | None:
        """The ground-truth contact torque [N m] and in-contact flag (1.0 or 0.0) just after
        the command of the sample is applied, for a plant that presses something (None: it
        does not)."""
        return None


class Plant(ABC):
    """Base class of the plants the loop accepts (:class:`~hpdob.ServoModel`,
    :class:`~hpdob.TwoMassServo`, :class:`~hpdob.MujocoServo`); see the module docstring."""

    __slots__ = ()

    #: Names of the state entries; the motor's angle comes first.
    state_names: tuple = ("theta", "omega")
    #: Index of the motor velocity in the state.
    velocity_index: int = 1

    @property
    def motor_inertia(self) -> float:
        """Inertia the motor's own acceleration sees [kg m^2]."""
        return self.J

    def initial_state(self, x0) -> np.ndarray:
        """Full plant state at the start of a run.

        Parameters
        ----------
        x0 : sequence of 2 floats
            The motor's ``[theta (rad), omega (rad/s)]``.

        Returns
        -------
        ndarray
            The state, entries named by :attr:`state_names` (here ``x0`` itself).
        """
        return np.array(x0, dtype=float)

    def substeps(self, Ts: float, substeps: int | None) -> int:
        """Plant steps per sample of a run.

        Parameters
        ----------
        Ts : float
            Sampling period [s].
        substeps : int or None
            The number asked for, or None for :meth:`default_substeps`.

        Returns
        -------
        int
            ``substeps`` (checked), or this plant's default.

        Raises
        ------
        ParameterTypeError, ParameterValueError
            If ``substeps`` is not a positive integer.
        """
        if substeps is None:
            return self.default_substeps(Ts)
        return as_int(
            substeps, "substeps", "a positive integer number of sub-steps per sample", minimum=1
        )

    def default_substeps(self, Ts: float) -> int:
        """Default plant steps per sample.

        Parameters
        ----------
        Ts : float
            Sampling period [s].

        Returns
        -------
        int
            :data:`DEFAULT_SUBSTEPS` (8) unless the plant needs more.
        """
        return DEFAULT_SUBSTEPS

    @abstractmethod
    def sampler(self, Ts: float, substeps: int):
        """How the loop advances this plant over one sample.

        Parameters
        ----------
        Ts : float
            Sampling period [s].
        substeps : int
            Plant steps per sample (from :meth:`substeps`).

        Returns
        -------
        ExactSubsteps or sampler
            :class:`ExactSubsteps` (advanced by the compiled kernel) or an object whose
            ``start(x)`` returns a :class:`PlantSession` (advanced from Python).
        """

    def discretize(self, Ts: float):
        """Linear zero-order-hold model for the analysis views.

        Parameters
        ----------
        Ts : float
            Sampling period [s].

        Returns
        -------
        discrete model
            With ``A, B, D, C`` and ``state_names`` (see the module docstring).

        Raises
        ------
        ParameterValueError
            For a plant that is simulated only (no linear model), as here.
        """
        raise ParameterValueError(
            f"plant must have a linear model for the analysis views; a {type(self).__name__} "
            "is simulated only"
        )
