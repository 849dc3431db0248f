r"""The N-joint loop: an observer and a controller per joint, stepped together at ``Ts``.

Independent-joint control (Ohnishi's robust motion control): joint ``i`` is treated as the
single-axis servo of the paper with nominal inertia :math:`J_{n,i}` and friction
:math:`b_{n,i}`; gravity, the coupling to the other joints, a payload and external forces are
all its disturbance. Its nominal disturbance (eq. 3 per joint) is

.. math:: \tau_{dn,i} = u_i - b_{n,i}\,\dot q_i - J_{n,i}\,\ddot q_i .
"""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass, field, replace

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_real,
    nonnegative,
    positive,
)
from ..models import ServoModel
from ..observers import as_system, initial_state
from ..simulation import Actuator, Encoder
from ._controllers import controller_types, joint_controller
from ._errors import qualified

__all__ = ["ArmLoop", "JointSines", "per_joint"]


def _entries(value, name: str):
    """A 1-D numpy array of per-joint entries (``np.array([spec] * 7)``) as the list it holds."""
    if isinstance(value, np.ndarray) and value.dtype == object:
        if value.ndim != 1:
            raise ParameterValueError(
                f"{name} must be one entry for every joint or a list of one per joint, got an "
                f"array of shape {value.shape}"
            )
        return list(value)
    return value


def per_joint(value, n: int, name: str, kinds, *, optional: bool = False) -> tuple:
    """``value`` for every joint: one value for all joints, or a list of ``n``."""
    value = _entries(value, name)
    if isinstance(value, (list, tuple)):
        values = tuple(value)
        if len(values) != n:
            raise ParameterValueError(
                f"{name} must have one entry per joint ({n}), got {len(values)}"
            )
    else:
        values = (value,) * n
    for i, v in enumerate(values):
        if v is None and optional:
            continue
        if not isinstance(v, kinds):
            names = " or ".join(
                k.__name__ for k in (kinds if isinstance(kinds, tuple) else (kinds,))
            )
            raise ParameterTypeError(
                f"{name}[{i}] must be {names}{' or None' if optional else ''}, "
                f"got {type(v).__name__}"
            )
    return values


def _vector(value, n: int, name: str, what: str, check) -> np.ndarray:
    array = np.array(value, dtype=float) if not np.isscalar(value) else np.full(n, float(value))
    if array.shape != (n,):
        raise ParameterValueError(
            f"{name} must have one entry per joint ({n}), got shape {array.shape}"
        )
    return np.array([check(v, f"{name}[{i}]", what) for i, v in enumerate(array)])


@dataclass(frozen=True)
class JointSines:
    r"""A smooth joint-space trajectory :math:`r_i = c_i + \tfrac{a_i}{2}(1 - \cos 2\pi f_i t)`
    that starts at rest at ``c`` (with a step in acceleration at ``t = 0``).

    Its peak velocity is :math:`\pi a_i f_i` [rad/s].

    Parameters
    ----------
    center : sequence of float
        Start angles :math:`c_i` [rad].
    amplitude : sequence of float or float
        Swing :math:`a_i` [rad].
    frequency : sequence of float or float
        Frequency :math:`f_i` [Hz], positive.

    Examples
    --------
    >>> from hpdob.robots import JointSines
    >>> ref = JointSines(center=(0.0, 0.5), amplitude=1.0, frequency=1.0)
    >>> [round(float(v), 3) for v in ref.peak_velocity]
    [3.142, 3.142]
    """

    center: tuple
    amplitude: object = 0.5
    frequency: object = 1.0

    def __post_init__(self):
        center = np.array(self.center, dtype=float).reshape(-1)
        n = center.size
        object.__setattr__(self, "center", tuple(center.tolist()))
        if n == 0 or not np.all(np.isfinite(center)):
            raise ParameterValueError(
                f"center must be one finite start angle [rad] per joint, got {center.tolist()}"
            )
        amp = _vector(self.amplitude, n, "amplitude", "a finite swing [rad]", as_real)
        freq = _vector(self.frequency, n, "frequency", "a positive finite frequency [Hz]",
                       positive)  # fmt: skip
        object.__setattr__(self, "amplitude", tuple(amp.tolist()))
        object.__setattr__(self, "frequency", tuple(freq.tolist()))

    @property
    def peak_velocity(self) -> np.ndarray:
        """:math:`\\pi a_i f_i` [rad/s] per joint."""
        return np.pi * np.abs(self.amplitude) * np.array(self.frequency)

    def __call__(self, t):
        """``(r, r_dot, r_ddot)``, each of shape ``(len(t), N)`` [rad, rad/s, rad/s^2]."""
        t = np.asarray(t, dtype=float)[:, None]
        c, a = np.array(self.center), np.array(self.amplitude)
        w = 2.0 * np.pi * np.array(self.frequency)
        return (
            c + 0.5 * a * (1.0 - np.cos(w * t)),
            0.5 * a * w * np.sin(w * t),
            0.5 * a * w**2 * np.cos(w * t),
        )


@dataclass(frozen=True)
class ArmLoop:
    r"""The N-joint closed loop as a value: plant, per-joint observers and controllers.

    Parameters
    ----------
    plant : TwoLinkArm or MujocoArm
        The arm that is simulated.
    Ts : float
        Sampling period [s].
    controller : controller, sequence of controllers, or ComputedTorque
        One controller of the protocol (:class:`~hpdob.PD`, :class:`~hpdob.PID`,
        :class:`~hpdob.FilteredPD`, :class:`~hpdob.ADRC`, a :class:`~hpdob.LinearController`)
        for every joint, one per joint, or computed-torque control on a nominal model
        (:class:`ComputedTorque`, without per-joint observers).
    observers : optional
        Per-joint disturbance observers: None (none), one entry for every joint or a list of
        one per joint (None for a joint without). An entry is an observer spec
        (``{"order": 1, "bandwidth": 100.0}``, ``{"type": "eso", ...}``: any registered family)
        designed on the joint's nominal model ``ServoModel(J_n,i, b_n,i).discretize(Ts)``, or a
        :class:`~hpdob.LinearObserver` / design (designed on that ``Ts``).
    nominal : arm model, optional
        The model the nominal inertias default to (the plant itself if None).
    nominal_inertia : sequence of float, optional
        :math:`J_{n,i}` [kg m^2]; default the diagonal of ``nominal.mass_matrix(q0)``.
    nominal_friction : sequence of float or float, optional
        :math:`b_{n,i}` [N m s/rad]. Default 0.
    q0 : sequence of float, optional
        Initial joint angles [rad] (at rest). Default zeros.
    sensor : None, Encoder or sequence, optional
        Ideal sensing (None) or an :class:`~hpdob.Encoder`, for every joint or per joint.
    actuator : Actuator or sequence, optional
        Torque limit and delay, for every joint or per joint.

    Raises
    ------
    ParameterTypeError, ParameterValueError
        Naming the parameter: a per-joint list of the wrong length, a wrong kind of entry, a
        non-positive inertia.
    """

    plant: object
    Ts: float
    controller: object
    _: KW_ONLY
    observers: object = None
    nominal: object = None
    nominal_inertia: object = None
    nominal_friction: object = 0.0
    q0: object = None
    sensor: object = None
    actuator: object = field(default_factory=Actuator)
    systems: tuple = field(init=False, repr=False)
    controllers: tuple = field(init=False, repr=False)
    controller_rows: tuple = field(init=False, repr=False)
    _defaults: tuple = field(init=False, repr=False, compare=False)
    sensors: tuple = field(init=False, repr=False)
    actuators: tuple = field(init=False, repr=False)

    def __post_init__(self):
        from ._computed_torque import ComputedTorque

        set_ = object.__setattr__
        # which fields took their default from others (replace() derives them again)
        set_(self, "_defaults", tuple(name for name in ("nominal", "nominal_inertia")
                                      if getattr(self, name) is None))  # fmt: skip
        n = getattr(self.plant, "n_joints", None)
        if not isinstance(n, int):
            raise ParameterTypeError(
                f"plant must be an arm (TwoLinkArm or MujocoArm), got {type(self.plant).__name__}"
            )
        set_(self, "Ts", positive(self.Ts, "Ts", "a positive finite sampling period [s]"))
        nominal = self.plant if self.nominal is None else self.nominal
        if getattr(nominal, "n_joints", None) != n:
            raise ParameterValueError(
                f"nominal must be an arm model with the plant's {n} joints, got "
                f"{getattr(nominal, 'n_joints', type(nominal).__name__)}"
            )
        set_(self, "nominal", nominal)
        q0 = np.zeros(n) if self.q0 is None else self.q0
        q0 = _vector(q0, n, "q0", "a finite joint angle [rad]", as_real)
        set_(self, "q0", tuple(q0.tolist()))
        if self.nominal_inertia is None:
            J_n = np.diag(nominal.mass_matrix(q0)).copy()
        else:
            J_n = _vector(self.nominal_inertia, n, "nominal_inertia",
                          "a positive finite inertia [kg m^2]", positive)  # fmt: skip
        set_(self, "nominal_inertia", tuple(J_n.tolist()))
        b_n = _vector(self.nominal_friction, n, "nominal_friction",
                      "a non-negative finite friction [N m s/rad]", nonnegative)  # fmt: skip
        set_(self, "nominal_friction", tuple(b_n.tolist()))
        if isinstance(self.controller, ComputedTorque):
            if self.controller.n_joints != n:
                raise ParameterValueError(
                    f"controller must be for the plant's {n} joints, got a ComputedTorque for "
                    f"{self.controller.n_joints}"
                )
            if self.observers is not None:
                raise ParameterValueError(
                    "observers must be None with controller=ComputedTorque: a per-joint "
                    "observer's nominal model (eq. 3 per joint: J_n qdd = u - b_n qd - tau_dn) "
                    "is not the computed-torque model; estimate external torques with "
                    "momentum_observer"
                )
            set_(self, "controllers", ())
            set_(self, "controller_rows", ())
        else:
            set_(self, "controllers", per_joint(self.controller, n, "controller",
                                                controller_types()))  # fmt: skip
            rows = tuple(
                joint_controller(c, J_n[i], b_n[i], self.Ts, f"controller[{i}]")
                for i, c in enumerate(self.controllers)
            )
            set_(self, "controller_rows", rows)
        set_(self, "sensors", per_joint(self.sensor, n, "sensor", Encoder, optional=True))
        set_(self, "actuators", per_joint(self.actuator, n, "actuator", Actuator))
        entries = _entries(self.observers, "observers")
        if entries is None or isinstance(entries, dict) or not isinstance(entries, (list, tuple)):
            entries = (entries,) * n
        elif len(entries) != n:
            raise ParameterValueError(
                f"observers must have one entry per joint ({n}), got {len(entries)}"
            )
        systems = []
        for i, entry in enumerate(entries):
            systems.append(self._system(entry, i, J_n[i], b_n[i]))
        for i, rows in enumerate(self.controller_rows):
            if "omega_hat" in rows.inputs and (systems[i] is None or not systems[i].has_velocity):
                raise ParameterValueError(
                    f"controller[{i}] reads omega_hat (velocity = 'observer'), which needs an "
                    "observer with a velocity estimate on that joint"
                )
        set_(self, "systems", tuple(systems))

    def _system(self, entry, i, J_n, b_n):
        if entry is None:
            return None
        where = f"observers[{i}]"
        if isinstance(entry, dict):
            try:  # the family registry's public name (issue 20)
                from ..observers import design_from_spec
            except ImportError:  # before it: the spec table of hpdob.observers._families
                from ..observers import design_from_spec

            model = ServoModel(J_n, b_n).discretize(self.Ts)
            with qualified(where, tuple(entry)):  # "order must be ..." -> "observers[0].order ..."
                return as_system(design_from_spec(model, entry, where), where)
        system = as_system(entry, where)
        if not math.isclose(system.Ts, self.Ts, rel_tol=1e-12):
            raise ParameterValueError(
                f"{where} must be designed at Ts = {self.Ts!r} s, got one at {system.Ts!r} s"
            )
        return system

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return self.plant.n_joints

    def replace(self, **changes) -> ArmLoop:
        """A copy with some fields changed (validated again).

        Parameters
        ----------
        **changes
            New values of ``plant``, ``Ts``, ``controller``, ``observers``, ``nominal``,
            ``nominal_inertia``, ``nominal_friction``, ``q0``, ``sensor``, ``actuator``.

        Returns
        -------
        ArmLoop
            ``nominal`` and ``nominal_inertia`` that took their defaults (the plant, the
            diagonal of ``M(q0)``) are derived again from the new values.
        """
        derived = {name: None for name in self._defaults if name not in changes}
        return replace(self, **derived, **changes)

    def initial_observer_states(self, tau0) -> list:
        """Each joint's observer state converged on ``tau0[i]`` at rest at ``q0``.

        Parameters
        ----------
        tau0 : sequence of float
            The disturbance of each joint [N m].

        Returns
        -------
        list
            One state tuple per joint (None for a joint without observer).
        """
        return [
            None if s is None else initial_state(s, x0=(self.q0[i], 0.0), tau0=float(tau0[i]))
            for i, s in enumerate(self.systems)
        ]
