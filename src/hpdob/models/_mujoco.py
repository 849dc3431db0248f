r"""A servo simulated by MuJoCo: an independent physics engine as the plant of :func:`simulate`.

MuJoCo is imported on first use only (``pip install 'hpdob[mujoco]'``), so ``import hpdob``
stays fast and works without it. The sample loop that drives the model is in
``hpdob.simulation._python_plant``.
"""

from __future__ import annotations

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_real,
    as_real_vector,
    check_choice,
    nonnegative,
    positive,
)
from ._mjcf import (
    INTEGRATORS,
    TIP_GEOM,
    MujocoHandle,
    compile_model,
    find_joint,
    import_mujoco,
    integrator_name,
    joint_and_actuator,
    joint_inertia,
    open_handle,
    read_mjcf,
    servo_xml,
)
from ._mujoco_session import MujocoSampler
from ._plant import DEFAULT_SUBSTEPS, Plant

__all__ = ["MujocoServo"]


def _check_timestep(timestep):
    if timestep is None:
        return None
    return positive(timestep, "timestep", "a positive finite MuJoCo time step [s] or None")


class MujocoServo(Plant):
    r"""A servo simulated by MuJoCo, usable as ``plant=`` in :func:`simulate` and :func:`sweep`.

    The built model is one hinge joint (axis horizontal) with

    .. math::

        (J + m L^2)\,\ddot\theta = u - b\,\omega - f_c(\omega) - m g L \sin\theta
        - \tau_{ext}(t),

    where the rotor inertia ``J`` is the joint's ``armature`` (plus 1e-6 ``J`` carried by the
    rotor body, which MuJoCo needs, so that the total is exactly ``J``), ``b`` its viscous
    ``damping``, :math:`f_c` MuJoCo's dry friction ``frictionloss`` of level ``coulomb`` (a soft
    constraint, not a ``tanh``), and an optional pendulum link: a point mass ``link_mass`` at
    ``link_length`` from the axis, hanging down at :math:`\theta = 0`, whose weight
    (:math:`g` = 9.81 m/s^2) is a position-dependent load. ``u`` is applied by a ``<motor>``
    actuator, ``tau_ext`` through ``qfrc_applied``. ``xml`` holds the generated MJCF.

    Parameters
    ----------
    J : float
        Rotor inertia [kg m^2], positive.
    b : float, optional
        Viscous friction [N m s/rad], non-negative. Default 0.
    coulomb : float, optional
        Dry friction level [N m] (MuJoCo ``frictionloss``), non-negative. Default 0.
    link_mass : float, optional
        Mass of the pendulum link [kg], non-negative. Default 0 (no link).
    link_length : float, optional
        Distance of the link's mass from the axis [m], non-negative. Default 0.
    timestep : float, optional
        MuJoCo's time step [s]; ``Ts`` must be an integer multiple of it, and the run takes
        ``Ts/timestep`` MuJoCo steps per sample. None (default): ``Ts/substeps``.
    integrator : {'RK4', 'Euler', 'implicit', 'implicitfast'}, optional
        MuJoCo's integrator. Default ``'RK4'``, which makes the cross-validation against hpdob's
        own integrator tight (see docs/mujoco.md).
    wall : float, optional
        The angle :math:`\theta_e` [rad] at which the link presses a wall (force control,
        issue 21): the link gets a sphere tip (radius ``0.1 link_length``, no mass) and the
        world a fixed box whose face is the radial plane the tip touches at
        :math:`\theta = \theta_e`; MuJoCo's soft contact then pushes back for
        :math:`\theta > \theta_e`. Results get ``tau_contact`` (the contact force through
        the contact Jacobian, ``MujocoSession.contact``) and ``in_contact``. Needs a positive
        ``link_length`` (``link_mass`` may be 0: no gravity torque). Default None (no wall).

    Raises
    ------
    TypeError, ValueError
        For a parameter of the wrong type or value, named in the message.

    Notes
    -----
    The ground truth :math:`\tau_{dn}` of a run comes from MuJoCo's own acceleration just after
    ``u_k`` is applied; the disturbance is applied at the midpoint of each MuJoCo step.
    ``MujocoServo.from_xml`` wraps a model of your own.

    References
    ----------
    E. Todorov, T. Erez, Y. Tassa, "MuJoCo: A physics engine for model-based control", IROS
    2012. E. Sariyildiz, "A High Performance Disturbance Observer: A Unified Synthesis
    Approach", eqs. (1), (3).

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import MujocoServo
    >>> pendulum = MujocoServo(3.06e-4, 5e-5, link_mass=0.02, link_length=0.1)
    >>> pendulum.inertia  # J + m L^2 [kg m^2]
    0.000506
    >>> print(f"{pendulum.bias_torque(np.pi / 2)[0]:.6f} N m")  # m g L = 0.02 * 9.81 * 0.1
    0.019620 N m
    """

    __slots__ = ("_actuator", "_joint", "_overrides", "_params", "_path", "_source", "_timestep")

    def __init__(
        self,
        J,
        b=0.0,
        *,
        coulomb=0.0,
        link_mass=0.0,
        link_length=0.0,
        timestep=None,
        integrator="RK4",
        wall=None,
    ):
        params = {
            "J": positive(J, "J", "a positive finite inertia [kg m^2]"),
            "b": nonnegative(b, "b", "a non-negative finite viscous friction [N m s/rad]"),
            "coulomb": nonnegative(
                coulomb, "coulomb", "a non-negative finite dry friction torque [N m]"
            ),
            "link_mass": nonnegative(link_mass, "link_mass", "a non-negative finite mass [kg]"),
            "link_length": nonnegative(
                link_length, "link_length", "a non-negative finite length [m]"
            ),
            "integrator": check_choice(integrator, "integrator", INTEGRATORS),
            "wall": None if wall is None else as_real(wall, "wall", "a finite wall angle [rad]"),
        }
        if params["wall"] is not None and not params["link_length"] > 0.0:
            raise ParameterValueError(
                f"wall = {params['wall']!r} needs a link to press it: link_length must be "
                f"positive, got {params['link_length']!r}"
            )
        import_mujoco()  # fail here, not at the first run, if the extra is missing
        source = servo_xml(**params)
        self._set(source, None, "hinge", "motor", _check_timestep(timestep), params, {})

    def _set(self, source, path, joint, actuator, timestep, params, overrides):
        for name, value in (
            ("_source", source),
            ("_path", path),
            ("_joint", joint),
            ("_actuator", actuator),
            ("_timestep", timestep),
            ("_params", params),
            ("_overrides", overrides),
        ):
            object.__setattr__(self, name, value)

    def __setattr__(self, name, value):
        raise AttributeError("MujocoServo is immutable; use replace() for a changed copy")

    @classmethod
    def from_xml(cls, path_or_string, *, joint=None, actuator=None, timestep=None):
        """Wrap a MuJoCo model of your own (MJCF) as a servo plant.

        Parameters
        ----------
        path_or_string : str or os.PathLike
            The MJCF text (a string starting with ``<``) or the path of an MJCF file (assets
            and includes resolve relative to it).
        joint : str, optional
            Name of the controlled hinge joint; may be omitted if the model has exactly one.
        actuator : str, optional
            Name of the ``<motor>`` driving that joint directly (``u`` is applied as
            ``ctrl = u / (gear * gain)``); may be omitted if exactly one actuator drives it.
        timestep : float, optional
            MuJoCo's time step [s], replacing the model's; None: ``Ts/substeps``.

        Returns
        -------
        MujocoServo
            Its ``J`` is the joint-space inertia at the model's reference pose ``qpos0``,
            ``b`` and ``coulomb`` the joint's ``damping`` and ``frictionloss``; ``link_mass``
            and ``link_length`` are None. The model's integrator and gravity are kept; other
            joints move freely from ``qpos0`` under the model's own dynamics.

        Raises
        ------
        ValueError
            If the XML does not compile, the file does not exist, the joint is not a hinge,
            or the actuator is not a motor driving it (the valid names are listed).
        """
        source, path = read_mjcf(path_or_string)
        timestep = _check_timestep(timestep)
        name, actuator = joint_and_actuator(compile_model(source, path), joint, actuator)
        servo = object.__new__(cls)
        servo._set(source, path, name, actuator, timestep, None, {})
        return servo

    # -- parameters -------------------------------------------------------------------------

    def _model_value(self, attribute: str) -> float:
        model = self.open(1e-3).model
        dof = model.jnt_dofadr[find_joint(model, self._joint)]
        return float(getattr(model, attribute)[dof])

    @property
    def J(self) -> float:
        """Rotor inertia [kg m^2] (wrapped model: joint inertia at ``qpos0``)."""
        if self._params is not None:
            return self._params["J"]
        return joint_inertia(self.open(1e-3))

    @property
    def b(self) -> float:
        """Viscous friction [N m s/rad] (the joint's ``damping``)."""
        if self._params is not None:
            return self._params["b"]
        if "b" in self._overrides:
            return self._overrides["b"]
        return self._model_value("dof_damping")

    @property
    def coulomb(self) -> float:
        """Dry friction level [N m] (the joint's ``frictionloss``)."""
        if self._params is not None:
            return self._params["coulomb"]
        if "coulomb" in self._overrides:
            return self._overrides["coulomb"]
        return self._model_value("dof_frictionloss")

    @property
    def link_mass(self) -> float | None:
        """Pendulum link mass [kg]; None for a wrapped model."""
        return None if self._params is None else self._params["link_mass"]

    @property
    def link_length(self) -> float | None:
        """Pendulum link length [m]; None for a wrapped model."""
        return None if self._params is None else self._params["link_length"]

    @property
    def wall(self) -> float | None:
        """The angle [rad] at which the link's tip touches the wall (None: no wall)."""
        return None if self._params is None else self._params["wall"]

    @property
    def contact_geom(self) -> str | None:
        """The geom whose contacts give ``tau_contact`` (the link's tip with a wall, else
        None)."""
        return TIP_GEOM if self.wall is not None else None

    @property
    def inertia(self) -> float:
        """Total inertia about the axis [kg m^2]: ``J + link_mass * link_length**2``."""
        if self._params is None:
            return self.J
        p = self._params
        return p["J"] + p["link_mass"] * p["link_length"] ** 2

    @property
    def timestep(self) -> float | None:
        """MuJoCo's time step [s], or None for ``Ts/substeps``."""
        return self._timestep

    @property
    def integrator(self) -> str:
        """MuJoCo's integrator (MJCF name)."""
        if self._params is not None:
            return self._params["integrator"]
        return integrator_name(self.open(1e-3).model)

    @property
    def joint(self) -> str:
        """Name of the controlled hinge joint."""
        return self._joint

    @property
    def actuator(self) -> str:
        """Name of the motor actuator that applies ``u``."""
        return self._actuator

    @property
    def xml(self) -> str:
        """The MJCF text of the model."""
        return self._source

    def _replaceable(self) -> tuple[str, ...]:
        if self._params is None:
            return ("b", "coulomb", "timestep")
        return ("J", "b", "coulomb", "link_mass", "link_length", "timestep", "integrator", "wall")

    def replace(self, **changes) -> MujocoServo:
        """Return a copy with some parameters changed (validated like the constructor).

        Parameters
        ----------
        **changes
            A built servo accepts its constructor's parameters; a wrapped model
            (``from_xml``) accepts ``b``, ``coulomb`` (set on the joint after compiling) and
            ``timestep``.

        Returns
        -------
        MujocoServo

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For a parameter it does not accept, or a value the constructor rejects.
        """
        valid = self._replaceable()
        unknown = sorted(set(changes) - set(valid))
        if unknown:
            raise ParameterTypeError(
                f"replace() got unknown parameter(s) {unknown}; valid: {sorted(valid)}"
            )
        timestep = _check_timestep(changes.pop("timestep", self._timestep))
        if self._params is not None:
            values = {**self._params, **changes}
            return MujocoServo(values.pop("J"), values.pop("b"), timestep=timestep, **values)
        overrides = dict(self._overrides)
        if "b" in changes:
            overrides["b"] = nonnegative(
                changes["b"], "b", "a non-negative finite viscous friction [N m s/rad]"
            )
        if "coulomb" in changes:
            overrides["coulomb"] = nonnegative(
                changes["coulomb"], "coulomb", "a non-negative finite dry friction torque [N m]"
            )
        servo = object.__new__(MujocoServo)
        servo._set(self._source, self._path, self._joint, self._actuator, timestep, None, overrides)
        return servo

    def _key(self):
        return (self._source, self._path, self._joint, self._actuator, self._timestep,
                tuple(sorted(self._overrides.items())))  # fmt: skip

    def __eq__(self, other) -> bool:
        if not isinstance(other, MujocoServo):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __repr__(self) -> str:
        if self._params is not None:
            p = self._params
            return (
                f"MujocoServo(J={p['J']!r}, b={p['b']!r}, coulomb={p['coulomb']!r}, "
                f"link_mass={p['link_mass']!r}, link_length={p['link_length']!r}, "
                f"timestep={self._timestep!r}, integrator={p['integrator']!r}"
                + ("" if p["wall"] is None else f", wall={p['wall']!r}")
                + ")"
            )
        source = self._path or "<MJCF string>"
        extra = "".join(f", {k}={v!r}" for k, v in sorted(self._overrides.items()))
        return (
            f"MujocoServo.from_xml({source!r}, joint={self._joint!r}, "
            f"actuator={self._actuator!r}, timestep={self._timestep!r}{extra})"
        )

    def __reduce__(self):
        return (_rebuild, (self._source, self._path, self._joint, self._actuator,
                           self._timestep, self._params, self._overrides))  # fmt: skip

    # -- running ----------------------------------------------------------------------------

    def steps_per_sample(self, Ts: float, substeps: int | None = None) -> int | None:
        """MuJoCo steps per sampling period ``Ts``.

        Parameters
        ----------
        Ts : float
            Sampling period [s].
        substeps : int, optional
            Steps asked for (``simulate(..., substeps=)``).

        Returns
        -------
        int or None
            ``Ts/timestep``, or ``substeps`` if the servo has no ``timestep``.

        Raises
        ------
        ValueError
            If ``Ts`` is not an integer multiple of ``timestep``, or ``substeps`` is given and
            differs from ``Ts/timestep``.
        """
        if self._timestep is None:
            return substeps
        n = round(Ts / self._timestep)
        if n < 1 or abs(n * self._timestep - Ts) > 1e-9 * Ts:
            raise ParameterValueError(
                f"Ts must be an integer multiple of the plant's MuJoCo timestep "
                f"{self._timestep!r} s, got Ts={Ts!r} s (Ts/timestep = {Ts / self._timestep:.6g})"
            )
        if substeps is not None and substeps != n:
            raise ParameterValueError(
                f"substeps must be None or Ts/timestep = {n} for a MujocoServo with "
                f"timestep={self._timestep!r} s, got {substeps!r}"
            )
        return n

    # -- the plant protocol (hpdob.models.Plant) --------------------------------------------
    @property
    def motor_inertia(self) -> float:
        """Inertia of the joint [kg m^2] (:attr:`inertia`)."""
        return self.inertia

    def substeps(self, Ts: float, substeps: int | None) -> int:
        """MuJoCo steps per sample.

        Parameters
        ----------
        Ts : float
            Sampling period [s].
        substeps : int or None
            Steps asked for, or None.

        Returns
        -------
        int
            :meth:`steps_per_sample`; 8 without a timestep and without ``substeps``.
        """
        if substeps is not None:
            substeps = Plant.substeps(self, Ts, substeps)
        n = self.steps_per_sample(Ts, substeps)
        return DEFAULT_SUBSTEPS if n is None else n

    def sampler(self, Ts: float, substeps: int) -> MujocoSampler:
        """Runs advanced from Python by MuJoCo with ``substeps`` steps of ``Ts/substeps``.

        Parameters
        ----------
        Ts : float
            Sampling period [s].
        substeps : int
            MuJoCo steps per sample.

        Returns
        -------
        MujocoSampler
            Its ``start(x)`` opens a run (:meth:`open`) at the plant state ``x``.
        """
        return MujocoSampler(self, Ts / substeps, substeps)

    def open(self, timestep: float) -> MujocoHandle:
        """Compile a fresh model and its data at ``qpos0``, for one run.

        Each run gets its own, so runs can go on in parallel threads.

        Parameters
        ----------
        timestep : float
            MuJoCo time step [s] of the compiled model.

        Returns
        -------
        MujocoHandle
            ``(mujoco, model, data, qpos, dof, actuator, scale)``: the module, ``MjModel`` and
            ``MjData``, the joint's ``qpos``/``dof`` addresses, the actuator's id and the
            factor from torque [N m] to its ``ctrl``.
        """
        return open_handle(
            self._source, self._path, self._joint, self._actuator, self._overrides, timestep
        )

    def bias_torque(self, theta, omega=0.0) -> np.ndarray:
        """MuJoCo's bias torque ``qfrc_bias`` on the joint [N m] at angles ``theta`` [rad].

        For the built model this is the link's gravity torque ``m g L sin(theta)`` (a single
        hinge has no Coriolis term); other joints of a wrapped model stay at ``qpos0``, at rest.

        Parameters
        ----------
        theta : float or array_like
            Joint angles [rad].
        omega : float, optional
            Joint velocity [rad/s] (matters only for multi-joint models). Default 0.

        Returns
        -------
        ndarray, shape (n,)
            ``qfrc_bias`` [N m] at each angle (one entry for a scalar ``theta``).

        Raises
        ------
        ParameterTypeError, ParameterValueError
            If an angle or ``omega`` is not finite.
        """
        if np.ndim(theta) == 0:
            angles = np.array([as_real(theta, "theta", "a finite joint angle [rad]")])
        else:
            angles = as_real_vector(theta, "theta", "a 1-D array of finite joint angles [rad]")
        omega = as_real(omega, "omega", "a finite joint velocity [rad/s]")
        handle = self.open(1e-3)
        mujoco, model, data = handle.mujoco, handle.model, handle.data
        out = np.empty(angles.size)
        for i, angle in enumerate(angles):
            mujoco.mj_resetData(model, data)
            data.qpos[handle.qpos] = angle
            data.qvel[handle.dof] = omega
            mujoco.mj_forward(model, data)
            out[i] = data.qfrc_bias[handle.dof]
        return out


def _rebuild(source, path, joint, actuator, timestep, params, overrides) -> MujocoServo:
    servo = object.__new__(MujocoServo)
    servo._set(source, path, joint, actuator, timestep, params, overrides)
    return servo
