"""Servo model (eq. 1) and its exact zero-order-hold discretisation (eqs. 4, 5, 8)."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass, field

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, nonnegative, positive, readonly
from ._environment import Environment, check_environment
from ._lti import discrete_servo_parameters, is_lti, servo_parameters
from ._plant import ExactSubsteps, Plant, coulomb_substeps, replace_parameters

__all__ = ["DiscreteServoModel", "ServoModel", "as_discrete_model", "as_servo_model"]


@dataclass(frozen=True)
class ServoModel(Plant):
    r"""Continuous-time single-axis servo: inertia, viscous and Coulomb friction.

    The state is :math:`x = [\theta, \omega]` (rad, rad/s) and the dynamics are eq. (1)
    of the paper,

    .. math:: \dot x = A_C x + B_C u - D_C \tau_d,

    with :math:`A_C = [[0, 1], [0, -b/J]]` and :math:`B_C = D_C = [0, 1/J]^T`. The Coulomb
    friction torque ``coulomb * tanh(omega / coulomb_velocity)`` is not part of the linear
    model: the simulator treats it as an internal disturbance.

    Parameters
    ----------
    J : float
        Inertia [kg m^2], positive and finite.
    b : float, optional
        Viscous friction coefficient [N m s/rad], non-negative. Default 0.
    coulomb : float, optional
        Coulomb friction level [N m], non-negative. Default 0.
    coulomb_velocity : float, optional
        Velocity scale of the ``tanh`` smoothing of Coulomb friction [rad/s], positive.
        Default 0.01.
    environment : Environment, optional
        A unilateral contact the axis presses against (:class:`~hpdob.Environment`, or a dict
        of its arguments); simulated only (the linear model of ``discretize`` leaves it out).
        Default None.

    Raises
    ------
    TypeError
        If a parameter is not a real number.
    ValueError
        If a parameter is out of range or not finite.

    References
    ----------
    E. Sariyildiz, "A High Performance Disturbance Observer: A Unified Synthesis
    Approach", eqs. (1)-(2).

    Examples
    --------
    >>> from hpdob import ServoModel
    >>> motor = ServoModel(J=3.06e-4, b=5e-5)
    >>> motor.A_C
    array([[ 0.        ,  1.        ],
           [ 0.        , -0.16339869]])
    """

    J: float
    b: float = 0.0
    _: KW_ONLY
    coulomb: float = 0.0
    coulomb_velocity: float = 0.01
    environment: Environment | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        J = positive(self.J, "J", "a positive finite inertia [kg m^2]")
        b = nonnegative(self.b, "b", "a non-negative finite viscous friction [N m s/rad]")
        coulomb = nonnegative(
            self.coulomb, "coulomb", "a non-negative finite Coulomb friction torque [N m]"
        )
        velocity = positive(
            self.coulomb_velocity, "coulomb_velocity", "a positive finite velocity scale [rad/s]"
        )
        object.__setattr__(self, "J", J)
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "coulomb", coulomb)
        object.__setattr__(self, "coulomb_velocity", velocity)
        object.__setattr__(self, "environment", check_environment(self.environment))

    @classmethod
    def from_lti(cls, sys, *, torque_gain: float = 1.0, name: str = "sys", **friction):
        r"""The servo of a continuous python-control system ``k/(J s^2 + b s)``.

        Parameters
        ----------
        sys : control.TransferFunction or control.StateSpace
            Continuous (``dt = 0``), from the command to the angle [rad]: a pole at the origin,
            one real pole at ``-b/J`` (or a second one at the origin) and no zero.
        torque_gain : float, optional
            Torque per unit of the input, ``k`` [N m per input unit] (e.g. the torque constant
            for a current input). Default 1: the input is the torque [N m].
        name : str, optional
            Parameter name used in messages. Default ``"sys"``.
        **friction
            ``coulomb`` and ``coulomb_velocity``, which a linear system does not hold.

        Returns
        -------
        ServoModel

        Raises
        ------
        ParameterTypeError, ParameterValueError
            One line naming what is not a servo: a discrete system, a zero, a pole off the
            origin that is not real, no pole at the origin, more inputs or outputs.

        Examples
        --------
        >>> import control
        >>> from hpdob import ServoModel
        >>> s = control.tf("s")
        >>> ServoModel.from_lti(1 / (3.06e-4 * s**2 + 5e-5 * s))
        ServoModel(J=0.000306, b=5e-05, coulomb=0.0, coulomb_velocity=0.01)
        >>> ServoModel.from_lti(0.05 / (2.8e-4 * s**2), torque_gain=0.05)  # from a current [A]
        ServoModel(J=0.00028, b=0.0, coulomb=0.0, coulomb_velocity=0.01)
        """
        J, b = servo_parameters(sys, torque_gain=torque_gain, name=name)
        return cls(J, b, **friction)

    @property
    def A_C(self) -> np.ndarray:
        """Continuous state matrix ``[[0, 1], [0, -b/J]]`` of eq. (1)."""
        return np.array([[0.0, 1.0], [0.0, -self.b / self.J]])

    @property
    def B_C(self) -> np.ndarray:
        """Continuous control input vector ``[0, 1/J]`` of eq. (1), shape (2,)."""
        return np.array([0.0, 1.0 / self.J])

    @property
    def D_C(self) -> np.ndarray:
        """Continuous disturbance input vector ``[0, 1/J]`` of eq. (1), shape (2,)."""
        return np.array([0.0, 1.0 / self.J])

    def coulomb_torque(self, omega):
        """Coulomb friction torque, smoothed: ``coulomb * tanh(omega / coulomb_velocity)``.

        Parameters
        ----------
        omega : float or array_like
            Angular velocity [rad/s].

        Returns
        -------
        ndarray
            The friction torque [N m], the shape of ``omega``.

        Examples
        --------
        >>> from hpdob import ServoModel
        >>> ServoModel(2.8e-4, coulomb=0.01).coulomb_torque([0.0, 1.0])   # tanh(100) = 1
        array([0.  , 0.01])
        """
        return self.coulomb * np.tanh(np.asarray(omega, dtype=float) / self.coulomb_velocity)

    def discretize(self, Ts: float) -> DiscreteServoModel:
        r"""Exact zero-order-hold discretisation (eqs. 4-8).

        Parameters
        ----------
        Ts : float
            Sampling period [s], positive.

        Returns
        -------
        DiscreteServoModel
            ``A, B, D`` of :math:`x_{k+1} = A x_k + B u_k - D \tau_k`.

        Raises
        ------
        ParameterTypeError, ParameterValueError
            If ``Ts`` is not a positive finite number.
        """
        return DiscreteServoModel(self, Ts)

    # -- the plant protocol (hpdob.models.Plant) -------------------------------------------
    def default_substeps(self, Ts: float) -> int:
        """Default plant sub-steps per sample of a simulation.

        Parameters
        ----------
        Ts : float
            Sampling period [s].

        Returns
        -------
        int
            8, or the even number ``2 ceil(Ts c / (v J))`` for a stiff Coulomb friction, so
            that ``h c / (v J) <= 0.5`` with ``h = Ts / substeps``.

        Raises
        ------
        ParameterValueError
            If the friction is too stiff for 1e8 sub-steps per sample.
        """
        return coulomb_substeps(self.coulomb, self.coulomb_velocity, self.J, Ts)

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
            The ZOH matrices over ``h = Ts/substeps`` and ``h/2``, and the friction data.
        """
        return ExactSubsteps.of(self, Ts, substeps, shared=True, path="rigid",
                                internal=np.array([0.0, self.b]), J_motor=self.J,
                                contact_index=0)  # fmt: skip

    def replace(self, **changes) -> ServoModel:
        """Return a copy with some parameters changed (validated like the constructor).

        Parameters
        ----------
        **changes
            New values of ``J``, ``b``, ``coulomb``, ``coulomb_velocity`` or ``environment``.

        Returns
        -------
        ServoModel

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For an unknown parameter or a value the constructor rejects.

        Examples
        --------
        >>> from hpdob import ServoModel
        >>> ServoModel(2.8e-4).replace(b=1e-4)
        ServoModel(J=0.00028, b=0.0001, coulomb=0.0, coulomb_velocity=0.01)
        """
        return replace_parameters(self, changes)


_EYE2 = readonly(np.eye(2))

#: 1/(n+2)! for the Taylor series of phi_2 (alternating; 22 terms reach 1/23! ~ 4e-23).
_PHI2_TAYLOR = tuple(1.0 / math.factorial(n + 2) for n in range(22))


def _zoh_phi(alpha: float) -> tuple[float, float, float]:
    r"""Return :math:`(e^{-\alpha}, \varphi_1(-\alpha), \varphi_2(-\alpha))` for alpha >= 0.

    These are the entries of :math:`\exp\left(\begin{bmatrix}0&1&0\\0&-\alpha&1\\0&0&0
    \end{bmatrix}\right)`, the matrix exponential of the dimensionless augmented ZOH matrix:
    ``E[1,1]``, ``E[0,1] = E[1,2]`` and ``E[0,2]``. They are evaluated in closed form rather than
    by ``scipy.linalg.expm``, which loses up to ~50 ulp near alpha = 3: ``exp``/``expm1`` for the
    first two and, below alpha = 1 where :math:`(\alpha - 1 + e^{-\alpha})/\alpha^2` cancels,
    the Taylor series :math:`\varphi_2 = \sum_n (-\alpha)^n/(n+2)!`. Every value is within a
    few ulp for all alpha >= 0, including alpha = 0 exactly.
    """
    decay = math.exp(-alpha)
    em1 = math.expm1(-alpha)
    phi1 = 1.0 if alpha == 0.0 else -em1 / alpha
    if alpha < 1.0:
        phi2 = 0.0
        for coefficient in reversed(_PHI2_TAYLOR):
            phi2 = coefficient - alpha * phi2
    else:
        phi2 = (alpha + em1) / (alpha * alpha)
    return decay, phi1, phi2


@dataclass(frozen=True, eq=False)
class DiscreteServoModel:
    r"""Exact zero-order-hold discretisation of a :class:`ServoModel` (eqs. 4, 5, 8).

    .. math:: x_{k+1} = A x_k + B u_k - D \tau_k

    with :math:`A = e^{A_C T_s}`, :math:`B = \int_0^{T_s} e^{A_C s} B_C\,ds` and
    :math:`D = \int_0^{T_s} e^{A_C s} D_C\,ds` (here ``D == B`` because ``D_C == B_C``).
    With :math:`\alpha = b T_s / J`:

    .. math::

        A = \begin{bmatrix} 1 & T_s\varphi_1 \\ 0 & e^{-\alpha}\end{bmatrix},\quad
        B = D = \frac{1}{J}\begin{bmatrix} T_s^2 \varphi_2 \\ T_s \varphi_1\end{bmatrix},\quad
        \varphi_1 = \frac{1-e^{-\alpha}}{\alpha},\
        \varphi_2 = \frac{\alpha-1+e^{-\alpha}}{\alpha^2}.

    This is the matrix exponential of the augmented matrix
    :math:`\begin{bmatrix}A_C & B_C\\ 0 & 0\end{bmatrix} T_s`; its entries are evaluated in
    closed form with ``expm1`` and, for small :math:`\alpha`, a Taylor series, so they are accurate
    to a few ulp for ``b = 0`` and for every ``b*Ts/J`` (1e-12 to 10 and beyond) without the
    cancellation of the naive :math:`(1-e^{-\alpha})/\alpha` forms. Coulomb friction does not
    enter.

    Parameters
    ----------
    continuous : ServoModel
        The continuous model that is discretised.
    Ts : float
        Sampling period [s], positive and finite.

    Attributes
    ----------
    A : ndarray, shape (2, 2)
        Discrete state matrix :math:`A_D` (read-only).
    B : ndarray, shape (2,)
        Discrete control input vector :math:`B_D` (read-only).
    D : ndarray, shape (2,)
        Discrete disturbance input vector :math:`D_D` (read-only).

    Notes
    -----
    Two discrete models compare equal when they come from equal continuous models and the
    same ``Ts``.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import ServoModel
    >>> plant = ServoModel(J=2.8e-4).discretize(1e-3)
    >>> bool(np.allclose(plant.D, [1e-3**2 / (2 * 2.8e-4), 1e-3 / 2.8e-4]))  # b = 0
    True
    """

    continuous: ServoModel
    Ts: float
    A: np.ndarray = field(init=False, repr=False)
    B: np.ndarray = field(init=False, repr=False)
    D: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.continuous, ServoModel):
            raise ParameterTypeError(
                f"continuous must be a ServoModel, got {type(self.continuous).__name__}"
            )
        Ts = positive(self.Ts, "Ts", "a positive finite sampling period [s]")
        model = self.continuous
        alpha = model.b * Ts / model.J
        if not np.isfinite(alpha):
            raise ParameterValueError(
                f"b*Ts/J must be finite, got {alpha} (b={model.b}, Ts={Ts}, J={model.J})"
            )
        decay, phi1, phi2 = _zoh_phi(alpha)
        A = np.array([[1.0, Ts * phi1], [0.0, decay]])
        B = np.array([Ts * Ts * phi2 / model.J, Ts * phi1 / model.J])
        if not (np.all(np.isfinite(B)) and B[1] > 0.0):
            raise ParameterValueError(
                f"the ratio Ts/J = {Ts!r} s / {model.J!r} kg m^2 is beyond the float range: the "
                f"discrete input vector B_D = D_D = [Ts^2 phi_2/J, Ts phi_1/J] is {B.tolist()} "
                f"(J={model.J!r}, Ts={Ts!r}); use SI units with J and Ts of a realistic scale"
            )
        object.__setattr__(self, "Ts", Ts)
        object.__setattr__(self, "A", readonly(A))
        object.__setattr__(self, "B", readonly(B))
        object.__setattr__(self, "D", readonly(B.copy()))

    @classmethod
    def from_lti(cls, sys, *, torque_gain: float = 1.0, name: str = "sys") -> DiscreteServoModel:
        r"""The model of a sampled python-control servo (``control.c2d(servo, Ts)``, ZOH).

        Parameters
        ----------
        sys : control.TransferFunction or control.StateSpace
            Discrete (``dt = Ts > 0``), from the command to the angle [rad]: poles ``z = 1``
            and ``z = exp(-b Ts/J)``, the numerator of the zero-order-hold sampling.
        torque_gain : float, optional
            Torque per unit of the input [N m per input unit]. Default 1.
        name : str, optional
            Parameter name used in messages. Default ``"sys"``.

        Returns
        -------
        DiscreteServoModel
            ``ServoModel(J, b).discretize(Ts)`` with the transfer function of ``sys``.

        Raises
        ------
        ParameterTypeError, ParameterValueError
            If ``sys`` is continuous or not the ZOH sampling of a servo.

        Examples
        --------
        >>> import control
        >>> from hpdob import DiscreteServoModel
        >>> s = control.tf("s")
        >>> model = DiscreteServoModel.from_lti(control.c2d(1 / (2.8e-4 * s**2), 1e-3))
        >>> round(model.J, 12), model.b, model.Ts
        (0.00028, 0.0, 0.001)
        """
        J, b, Ts = discrete_servo_parameters(
            sys, servo=ServoModel, torque_gain=torque_gain, name=name
        )
        return cls(ServoModel(J, b), Ts)

    #: Names of the state entries (rows of ``C``: the motor angle and velocity).
    state_names = ("theta", "omega")

    @property
    def C(self) -> np.ndarray:
        """Rows of the motor's angle and velocity in the state: the identity (read-only)."""
        return _EYE2

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, DiscreteServoModel):
            return NotImplemented
        return self.continuous == other.continuous and self.Ts == other.Ts

    def __hash__(self) -> int:
        return hash((self.continuous, self.Ts))

    @property
    def J(self) -> float:
        """Inertia of the continuous model [kg m^2]."""
        return self.continuous.J

    @property
    def b(self) -> float:
        """Viscous friction of the continuous model [N m s/rad]."""
        return self.continuous.b

    def step(self, x, u: float, tau: float = 0.0) -> np.ndarray:
        """One sample of eq. (8): ``A @ x + B * u - D * tau`` (inputs held over the sample).

        Parameters
        ----------
        x : sequence of 2 floats
            ``[theta (rad), omega (rad/s)]`` at sample ``k``.
        u : float
            Control torque [N m].
        tau : float, optional
            Disturbance torque [N m]. Default 0.

        Returns
        -------
        ndarray, shape (2,)
            The state at sample ``k + 1``.

        References
        ----------
        Eq. (8) with the matrices of eqs. (4)-(7).

        Examples
        --------
        >>> import numpy as np
        >>> from hpdob import ServoModel
        >>> J, Ts, u = 2.8e-4, 1e-3, 0.01
        >>> x1 = ServoModel(J).discretize(Ts).step([0.0, 0.0], u)
        >>> bool(np.allclose(x1, [u * Ts**2 / (2 * J), u * Ts / J]))   # b = 0: a parabola
        True
        """
        return self.A @ np.asarray(x, dtype=float) + self.B * u - self.D * tau


def as_servo_model(value, name: str = "model"):
    """A :class:`ServoModel`: ``value`` itself, or one read off a continuous python-control system.

    Parameters
    ----------
    value : ServoModel or control.TransferFunction or control.StateSpace
        The model; a python-control system is ``1/(J s^2 + b s)`` from torque [N m] to angle.
    name : str, optional
        Parameter name used in messages.

    Returns
    -------
    ServoModel
        Any other model (e.g. a ``TwoMassServo`` plant) is returned unchanged for the caller's
        own check.
    """
    return ServoModel.from_lti(value, name=name) if is_lti(value) else value


def as_discrete_model(value, name: str = "model"):
    """A :class:`DiscreteServoModel`: ``value`` itself, or read off a sampled python-control servo.

    Parameters
    ----------
    value : DiscreteServoModel or control.TransferFunction or control.StateSpace
        The nominal discrete model; a python-control system is the ZOH sampling of
        ``1/(J s^2 + b s)`` (torque [N m] to angle), e.g. ``control.c2d(sys, Ts)``.
    name : str, optional
        Parameter name used in messages.

    Returns
    -------
    DiscreteServoModel

    Raises
    ------
    ParameterTypeError
        For a continuous model (``ServoModel`` or continuous system: discretise it first) or
        another type.
    ParameterValueError
        For a python-control system that is not a sampled servo.
    """
    if isinstance(value, DiscreteServoModel):
        return value
    if is_lti(value) and value.isdtime(strict=True):
        return DiscreteServoModel.from_lti(value, name=name)
    if isinstance(value, ServoModel) or is_lti(value):
        raise ParameterTypeError(
            f"{name} must be a DiscreteServoModel (or a sampled python-control servo); "
            "discretise the continuous model first, e.g. ServoModel(J_n, b_n).discretize(Ts), "
            "ServoModel.from_lti(sys).discretize(Ts) or control.c2d(sys, Ts)"
        )
    raise ParameterTypeError(
        f"{name} must be a DiscreteServoModel or a sampled python-control servo, got "
        f"{type(value).__name__}"
    )
