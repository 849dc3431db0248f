r"""An arm simulated by MuJoCo: any MJCF whose joints are hinges, each driven by a ``<motor>``.

MuJoCo is imported on first use only. The sample loop advances it from Python
(:func:`hpdob.robots.simulate_arm`): per sample one :func:`mujoco.mj_forward` for the ground
truth (the joint accelerations just after the command, eq. 3 per joint) and ``substeps`` calls
of :func:`mujoco.mj_step`. An end-effector force enters through ``xfrc_applied`` of the
end-effector site's body, with the torque that moves its point of application from the body's
centre of mass to the site.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from dataclasses import KW_ONLY, dataclass, field

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, nonnegative, positive
from ..models import compile_model, import_mujoco, object_names, read_mjcf

__all__ = ["MujocoArm"]


def _with_payload(source: str, site: str, mass: float) -> str:
    """``source`` with a point mass ``mass`` [kg] at the site ``site`` (a child body of the
    site's body, at the site's position)."""
    root = ET.fromstring(source)
    for body in root.iter("body"):
        for child in body.findall("site"):
            if child.get("name") == site:
                payload = ET.SubElement(body, "body", name="hpdob_payload",
                                        pos=child.get("pos", "0 0 0"))  # fmt: skip
                ET.SubElement(payload, "inertial", pos="0 0 0", mass=repr(mass),
                              diaginertia="1e-9 1e-9 1e-9")  # fmt: skip
                return ET.tostring(root, encoding="unicode")
    raise ParameterValueError(
        f"payload needs the end-effector site {site!r} inside a <body> of the MJCF"
    )


def _listed(names) -> str:
    return ", ".join(map(repr, names)) or "none"


def _kind(enum, value) -> str:
    return enum(value).name.split("_", 1)[1].lower()


def _check_joints(mujoco, model) -> list:
    """The joint names, every joint a hinge (one rotational dof)."""
    names = object_names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt)
    for j, name in enumerate(names):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            raise ParameterValueError(
                f"path_or_string must be an MJCF whose joints are all hinges (1 rotational "
                f"dof each), got joint {name!r}, a {_kind(mujoco.mjtJoint, model.jnt_type[j])} "
                "joint"
            )
    if not names:
        raise ParameterValueError("path_or_string must be an MJCF with hinge joints, got none")
    return names


def _check_actuators(mujoco, model, joints) -> tuple:
    """Each joint's actuator index and ``ctrl`` per N m: every actuator a ``<motor>`` on one
    hinge, every hinge driven by exactly one."""
    names = object_names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu)
    on_joint = mujoco.mjtTrn.mjTRN_JOINT
    for a, name in enumerate(names):
        if model.actuator_trntype[a] != on_joint:
            raise ParameterValueError(
                f"path_or_string must drive only its hinges, each by one <motor>, got actuator "
                f"{name!r} on a {_kind(mujoco.mjtTrn, model.actuator_trntype[a])} transmission"
            )
    actuators, scale = [], []
    for j, joint in enumerate(joints):
        drivers = [a for a in range(model.nu) if model.actuator_trnid[a, 0] == j]
        if len(drivers) != 1:
            raise ParameterValueError(
                f"path_or_string must drive every joint by exactly one <motor>, got "
                f"{len(drivers)} on joint {joint!r} ({_listed([names[a] for a in drivers])}); "
                f"actuators: {_listed(names)}"
            )
        a = drivers[0]
        gain = float(model.actuator_gear[a, 0] * model.actuator_gainprm[a, 0])
        motor = (
            model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
            and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE
            and model.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_NONE
        )
        if not motor or gain == 0.0:
            raise ParameterValueError(
                f"path_or_string must drive joint {joint!r} by a torque source (a <motor>: "
                f"fixed nonzero gain, no bias, no activation dynamics), got actuator "
                f"{names[a]!r} with gain {_kind(mujoco.mjtGain, model.actuator_gaintype[a])}, "
                f"bias {_kind(mujoco.mjtBias, model.actuator_biastype[a])}, dynamics "
                f"{_kind(mujoco.mjtDyn, model.actuator_dyntype[a])}, gear x gain = {gain!r}"
            )
        actuators.append(a)
        scale.append(1.0 / gain)
    return actuators, scale


@dataclass(frozen=True)
class MujocoArm:
    r"""An N-joint arm simulated by MuJoCo, the ``plant`` (or ``nominal``) of an :class:`ArmLoop`.

    Every joint of the model must be a hinge driven directly by one ``<motor>`` (fixed gain, no
    bias, no activation dynamics); ``u`` [N m] is applied as ``ctrl = u / (gear gain)``.
    Build it with :meth:`from_xml` or :func:`panda`.

    Parameters
    ----------
    xml : str
        The MJCF text (``model_xml`` adds the payload body, if any).
    end_effector : str, optional
        Name of the end-effector site (Jacobian, external force); default the only site.
    path : str, optional
        The MJCF file ``xml`` was read from (its assets resolve relative to it).
    inertia_scale : float, optional
        Factor on every body's mass and inertia (a wrong nominal model). Default 1.
    payload : float, optional
        Point mass at the end-effector site [kg]. Default 0.
    integrator : {"RK4", "Euler", "implicit", "implicitfast"}, optional
        MuJoCo's integrator; default the model's.

    Attributes
    ----------
    joint_names : tuple of str
        The hinge joints, in MuJoCo's order (the order of every per-joint array).
    """

    xml: str
    end_effector: str | None = None
    _: KW_ONLY
    path: str | None = None
    inertia_scale: float = 1.0
    payload: float = 0.0
    integrator: str | None = None
    joint_names: tuple = field(init=False)
    _cache: dict = field(init=False, repr=False, compare=False)

    @classmethod
    def from_xml(cls, path_or_string, *, end_effector=None, payload=0.0, inertia_scale=1.0,
                 integrator=None) -> MujocoArm:  # fmt: skip
        """Wrap an MJCF file or string.

        Parameters
        ----------
        path_or_string : str or os.PathLike
            MJCF text, or the path of an MJCF file.
        end_effector : str, optional
            Name of the site where the end-effector force acts; default the model's only site.
        payload : float, optional
            Extra point mass at the end-effector site [kg], a body added to the MJCF text
            (which is then compiled from a string: assets given by relative paths, e.g.
            meshes, must then resolve from the working directory). Default 0.
        inertia_scale : float, optional
            Factor on every body's mass and inertia, positive. Default 1.
        integrator : {"RK4", "Euler", "implicit", "implicitfast"}, optional
            MuJoCo's integrator; default the model's.

        Returns
        -------
        MujocoArm

        Raises
        ------
        ParameterValueError
            Checked in this order, the first failure named in one line: a joint that is not a
            hinge (``path_or_string must be an MJCF whose joints are all hinges ...``); an
            actuator not on a joint, a hinge without exactly one actuator, an actuator that is
            not a ``<motor>``; then an unknown or ambiguous end-effector site; a bad payload or
            scale.
        """
        source, path = read_mjcf(path_or_string)
        return cls(source, end_effector, path=path, inertia_scale=inertia_scale,
                   payload=payload, integrator=integrator)  # fmt: skip

    def __post_init__(self):
        set_ = object.__setattr__
        set_(
            self, "payload", nonnegative(self.payload, "payload", "a non-negative finite mass [kg]")
        )
        set_(self, "inertia_scale", positive(self.inertia_scale, "inertia_scale",
                                             "a positive finite factor"))  # fmt: skip
        mujoco = import_mujoco()
        model = compile_model(self.xml, self.path)
        # joints, then their actuators, then the site: the first error names the first thing
        # wrong with the model, not a site the user could not yet know is needed
        names = _check_joints(mujoco, model)
        actuators, scale = _check_actuators(mujoco, model, names)
        sites = object_names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite)
        site = self.end_effector
        if site is None:
            if len(sites) != 1:
                raise ParameterValueError(
                    f"end_effector must name the end-effector site: the model has {len(sites)} "
                    f"sites ({_listed(sites)})"
                )
            site = sites[0]
        if not isinstance(site, str):
            raise ParameterTypeError(
                f"end_effector must be a site name (str), got {type(site).__name__}"
            )
        if site not in sites:
            raise ParameterValueError(
                f"end_effector must be a site of the model, got {site!r}; sites: {_listed(sites)}"
            )
        set_(self, "end_effector", site)
        source, path = self.xml, self.path
        if self.payload > 0.0:
            source, path = _with_payload(self.xml, site, self.payload), None
            compile_model(source, None)  # the added body keeps the joints and actuators
        set_(self, "joint_names", tuple(names))
        set_(self, "_cache", {"actuators": np.array(actuators), "ctrl_per_torque": np.array(scale),
                              "site": sites.index(site), "source": (source, path)})  # fmt: skip
        if self.integrator is not None:
            from .._validation import check_choice
            from ..models import INTEGRATORS

            check_choice(self.integrator, "integrator", INTEGRATORS)

    # -- the model ---------------------------------------------------------------------------
    @property
    def model_xml(self) -> str:
        """The MJCF that is compiled (``xml`` with the payload body, if any)."""
        return self._cache["source"][0]

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return len(self.joint_names)

    def compile(self, timestep: float = 1e-3):
        """A fresh compiled model with the scale and integrator applied.

        Parameters
        ----------
        timestep : float, optional
            MuJoCo's time step [s]. Default 1e-3.

        Returns
        -------
        tuple
            ``(mujoco, MjModel, MjData)``.
        """
        mujoco = import_mujoco()
        model = compile_model(*self._cache["source"])
        if self.inertia_scale != 1.0:
            model.body_mass[:] *= self.inertia_scale
            model.body_inertia[:] *= self.inertia_scale
        model.opt.timestep = timestep
        if self.integrator is not None:
            model.opt.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + self.integrator.upper())
        return mujoco, model, mujoco.MjData(model)

    def _probe(self):
        if "probe" not in self._cache:
            self._cache["probe"] = self.compile()
        return self._cache["probe"]

    def _set(self, q, qd=None):
        mujoco, model, data = self._probe()
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n_joints,):
            raise ParameterValueError(
                f"q must have one entry per joint ({self.n_joints}), got shape {q.shape}"
            )
        data.qpos[:] = q
        data.qvel[:] = 0.0 if qd is None else qd
        data.qacc[:] = 0.0
        return mujoco, model, data

    def mass_matrix(self, q) -> np.ndarray:
        """:math:`M(q)` [kg m^2] (MuJoCo's, armature included).

        Parameters
        ----------
        q : sequence of float
            Joint angles [rad].

        Returns
        -------
        ndarray, shape (N, N)
        """
        mujoco, model, data = self._set(q)
        mujoco.mj_forward(model, data)
        M = np.zeros((model.nv, model.nv))
        unit, column = np.zeros(model.nv), np.zeros(model.nv)
        for j in range(model.nv):
            unit[:] = 0.0
            unit[j] = 1.0
            mujoco.mj_mulM(model, data, column, unit)
            M[:, j] = column
        return M

    def inverse_dynamics(self, q, qd, qdd) -> np.ndarray:
        r""":math:`M\ddot q + C\dot q + g + B\dot q` [N m] (``mj_inverse``).

        Parameters
        ----------
        q, qd, qdd : sequence of float
            Joint angles [rad], velocities [rad/s], accelerations [rad/s^2].

        Returns
        -------
        ndarray, shape (N,)
        """
        mujoco, model, data = self._set(q, qd)
        data.qacc[:] = qdd
        mujoco.mj_inverse(model, data)
        return data.qfrc_inverse.copy()

    def gravity_torque(self, q) -> np.ndarray:
        """:math:`g(q)` [N m]: the bias force at rest.

        Parameters
        ----------
        q : sequence of float

        Returns
        -------
        ndarray, shape (N,)
        """
        mujoco, model, data = self._set(q)
        mujoco.mj_forward(model, data)
        return data.qfrc_bias.copy()

    def friction(self, qd) -> np.ndarray:
        """The joints' viscous damping torques ``dof_damping * qd`` [N m].

        Parameters
        ----------
        qd : sequence of float

        Returns
        -------
        ndarray, shape (N,)
        """
        _, model, _ = self._probe()
        return model.dof_damping * np.asarray(qd, dtype=float)

    def coriolis(self, q, qd) -> np.ndarray:
        r""":math:`C(q,\dot q)\dot q` [N m]: the bias force minus gravity.

        Parameters
        ----------
        q, qd : sequence of float

        Returns
        -------
        ndarray, shape (N,)
        """
        bias = self._bias(q, qd)
        return bias - self.gravity_torque(q)

    def _bias(self, q, qd):
        mujoco, model, data = self._set(q, qd)
        mujoco.mj_forward(model, data)
        return data.qfrc_bias.copy()

    def coriolis_transpose(self, q, qd, *, step: float = 1e-6) -> np.ndarray:
        r""":math:`C^T(q,\dot q)\dot q` [N m] (Christoffel ``C``): the gradient in ``q`` of the
        kinetic energy :math:`\tfrac12 \dot q^T M(q) \dot q`, by central differences.

        Parameters
        ----------
        q, qd : sequence of float
        step : float, optional
            Difference step [rad]. Default 1e-6.

        Returns
        -------
        ndarray, shape (N,)
        """
        mujoco, model, data = self._probe()
        q = np.array(q, dtype=float)
        qd = np.array(qd, dtype=float)
        out = np.zeros(self.n_joints)
        Mqd = np.zeros(model.nv)
        for i in range(self.n_joints):
            energy = []
            for sign in (1.0, -1.0):
                data.qpos[:] = q
                data.qpos[i] += sign * step
                mujoco.mj_kinematics(model, data)
                mujoco.mj_comPos(model, data)
                mujoco.mj_crb(model, data)
                mujoco.mj_mulM(model, data, Mqd, qd)
                energy.append(0.5 * qd @ Mqd)
            out[i] = (energy[0] - energy[1]) / (2.0 * step)
        return out

    def end_effector_position(self, q) -> np.ndarray:
        """Position of the end-effector site in the world [m].

        Parameters
        ----------
        q : sequence of float

        Returns
        -------
        ndarray, shape (3,)
        """
        mujoco, model, data = self._set(q)
        mujoco.mj_kinematics(model, data)
        return data.site_xpos[self._cache["site"]].copy()

    def jacobian(self, q, *, rotational: bool = False) -> np.ndarray:
        """The end-effector site's Jacobian (``mj_jacSite``, world frame).

        Parameters
        ----------
        q : sequence of float
            Joint angles [rad].
        rotational : bool, optional
            Also the rotational rows (the wrench's moment). Default False.

        Returns
        -------
        ndarray, shape (3, N) or (6, N)
            Translational rows [m/rad], then rotational rows [rad/rad].
        """
        mujoco, model, data = self._set(q)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        jac = np.zeros((6, model.nv))
        mujoco.mj_jacSite(model, data, jac[:3], jac[3:], self._cache["site"])
        return jac if rotational else jac[:3].copy()

    def replace(self, **changes) -> MujocoArm:
        """A copy with ``payload``, ``inertia_scale`` or ``integrator`` changed.

        Parameters
        ----------
        **changes

        Returns
        -------
        MujocoArm
        """
        allowed = {"payload", "inertia_scale", "integrator"}
        unknown = set(changes) - allowed
        if unknown:
            raise ParameterValueError(
                f"replace takes {', '.join(sorted(allowed))}, got {', '.join(sorted(unknown))}"
            )
        return dataclasses.replace(self, **changes)

    def start(self, q0, Ts: float, substeps: int):
        """A MuJoCo run at rest at ``q0`` with time step ``Ts/substeps`` (the loop's session).

        Parameters
        ----------
        q0 : sequence of float
            Initial joint angles [rad].
        Ts : float
            Sampling period [s].
        substeps : int
            MuJoCo steps per sample.

        Returns
        -------
        MujocoArmSession
        """
        from ._mujoco_arm_session import MujocoArmSession

        return MujocoArmSession(self, q0, Ts, substeps)
