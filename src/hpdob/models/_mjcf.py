r"""MJCF for :class:`hpdob.MujocoServo`: the built servo model, and finding the joint and motor
of a user's model (with errors that list the valid names).

MuJoCo is imported on first use only (:func:`import_mujoco`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError

__all__ = [
    "GRAVITY",
    "INTEGRATORS",
    "MujocoHandle",
    "compile_model",
    "find_actuator",
    "find_joint",
    "import_mujoco",
    "integrator_name",
    "joint_and_actuator",
    "joint_inertia",
    "object_names",
    "open_handle",
    "read_mjcf",
    "servo_xml",
    "wall_geometry",
]

#: MuJoCo's integrators, by their MJCF name (``<option integrator=...>``).
INTEGRATORS = ("RK4", "Euler", "implicit", "implicitfast")
#: Gravitational acceleration of the built model [m/s^2] (MuJoCo's default, along -z).
GRAVITY = 9.81
#: The rotor body carries this fraction of ``J`` as its own inertia (MuJoCo needs a moving body
#: to have positive mass and inertia); the joint's ``armature`` is ``J`` minus it.
_BODY_INERTIA_FRACTION = 1e-6
_BODY_MASS = 1e-6  # kg, on the axis: no gravity torque, no inertia about the axis


def import_mujoco():
    """Import and return the ``mujoco`` module, or raise an ImportError saying how to get it."""
    try:
        import mujoco
    except ImportError as err:
        raise ImportError("hpdob.MujocoServo needs MuJoCo: pip install 'hpdob[mujoco]'") from err
    return mujoco


class MujocoHandle(NamedTuple):
    """A compiled MuJoCo model and its data, ready for one run (see :meth:`MujocoServo.open`)."""

    mujoco: object
    model: object
    data: object
    qpos: int  # address of the joint angle in data.qpos
    dof: int  # address of the joint velocity in data.qvel / qacc / qfrc_*
    actuator: int  # index of the motor in data.ctrl
    ctrl_per_torque: float  # ctrl = u * ctrl_per_torque gives the joint torque u [N m]


#: Radius of the link's tip (the geom that touches the wall) as a fraction of ``link_length``.
TIP_RADIUS = 0.1
#: Names of the wall's two geoms in the built model.
TIP_GEOM, WALL_GEOM = "tip", "wall"


def wall_geometry(link_length: float, wall: float) -> tuple[float, float]:
    r"""``(tip radius, phi)``: the wall is the radial plane at angle :math:`\phi` (a box face
    through the hinge axis), so that the tip's sphere (radius :math:`\rho`, centre at
    ``link_length`` :math:`L`) touches it exactly at :math:`\theta = \theta_e`:
    :math:`L \sin(\phi - \theta_e) = \rho`."""
    radius = TIP_RADIUS * link_length
    return radius, wall + float(np.arcsin(radius / link_length))


def servo_xml(J, b, coulomb, link_mass, link_length, integrator, wall=None) -> str:
    body_inertia = min(J * _BODY_INERTIA_FRACTION, 0.5 * J)
    armature = J - body_inertia
    link = wall_geom = ""
    if link_mass > 0.0 or wall is not None:
        inertial = (f'\n        <inertial pos="0 0 0" mass="{link_mass!r}" diaginertia="0 0 0"/>'
                    if link_mass > 0.0 else "")  # fmt: skip
        tip = ""
        if wall is not None:
            radius, phi = wall_geometry(link_length, wall)
            tip = f'\n        <geom name="{TIP_GEOM}" type="sphere" size="{radius!r}" mass="0"/>'
            # a box whose face x = 0 (in the frame turned by phi about the axis) is the wall
            half = 2.0 * radius
            x, z = -half, -link_length  # the box's centre in the turned frame
            cx, cz = x * np.cos(phi) + z * np.sin(phi), -x * np.sin(phi) + z * np.cos(phi)
            wall_geom = (
                f'\n    <geom name="{WALL_GEOM}" type="box" size="{half!r} {half!r} {half!r}"'
                f' pos="{float(cx)!r} 0 {float(cz)!r}" euler="0 {phi!r} 0"/>'
            )
        body = f'\n      <body name="link" pos="0 0 {-link_length!r}">'
        link = f"{body}{inertial}{tip}\n      </body>"
    i = repr(body_inertia)
    return f"""<mujoco model="hpdob_servo">
  <compiler angle="radian" inertiafromgeom="false"/>
  <option timestep="0.001" integrator="{integrator}" gravity="0 0 {-GRAVITY!r}"/>
  <worldbody>
    <body name="rotor">
      <joint name="hinge" type="hinge" axis="0 1 0" armature="{armature!r}"
             damping="{b!r}" frictionloss="{coulomb!r}"/>
      <inertial pos="0 0 0" mass="{_BODY_MASS!r}" diaginertia="{i} {i} {i}"/>{link}
    </body>{wall_geom}
  </worldbody>
  <actuator>
    <motor name="motor" joint="hinge" gear="1"/>
  </actuator>
</mujoco>
"""


def compile_model(source: str, path: str | None):
    mujoco = import_mujoco()
    try:
        if path is not None:
            return mujoco.MjModel.from_xml_path(path)
        return mujoco.MjModel.from_xml_string(source)
    except ValueError as err:
        where = f"the MJCF file {path!r}" if path is not None else "the MJCF XML string"
        raise ParameterValueError(f"MuJoCo could not compile {where}: {err}") from None


def object_names(model, obj, count: int) -> list[str]:
    mujoco = import_mujoco()
    return [mujoco.mj_id2name(model, obj, i) or f"#{i} (unnamed)" for i in range(count)]


def _listed(names) -> str:
    return ", ".join(repr(n) for n in names) if names else "none"


def find_joint(model, joint) -> int:
    mujoco = import_mujoco()
    names = object_names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt)
    hinge = mujoco.mjtJoint.mjJNT_HINGE
    hinges = [n for i, n in enumerate(names) if model.jnt_type[i] == hinge]
    if joint is None:
        if len(hinges) != 1:
            raise ParameterValueError(
                f"joint must name the servo's hinge joint: the model has {len(hinges)} hinge "
                f"joints ({_listed(hinges)}); joints: {_listed(names)}"
            )
        joint = hinges[0]
    if not isinstance(joint, str):
        raise ParameterTypeError(f"joint must be a joint name (str), got {type(joint).__name__}")
    if joint not in names:
        raise ParameterValueError(
            f"joint must be the name of a hinge joint of the model, got {joint!r}; "
            f"hinge joints: {_listed(hinges)}"
        )
    index = names.index(joint)
    if model.jnt_type[index] != hinge:
        kind = mujoco.mjtJoint(model.jnt_type[index]).name.removeprefix("mjJNT_").lower()
        raise ParameterValueError(
            f"joint must be a hinge joint (1 rotational dof), got {joint!r}, a {kind} joint; "
            f"hinge joints: {_listed(hinges)}"
        )
    return index


def find_actuator(model, joint_id: int, joint_name: str, actuator) -> tuple[int, float]:
    mujoco = import_mujoco()
    names = object_names(model, mujoco.mjtObj.mjOBJ_ACTUATOR, model.nu)
    drivers = [
        n
        for i, n in enumerate(names)
        if model.actuator_trntype[i] == mujoco.mjtTrn.mjTRN_JOINT
        and model.actuator_trnid[i, 0] == joint_id
    ]
    if actuator is None:
        if len(drivers) != 1:
            raise ParameterValueError(
                f"actuator must name the motor of joint {joint_name!r}: {len(drivers)} "
                f"actuators drive it ({_listed(drivers)}); actuators: {_listed(names)}"
            )
        actuator = drivers[0]
    if not isinstance(actuator, str):
        raise ParameterTypeError(
            f"actuator must be an actuator name (str), got {type(actuator).__name__}"
        )
    if actuator not in names:
        raise ParameterValueError(
            f"actuator must be the name of an actuator of the model, got {actuator!r}; "
            f"actuators driving joint {joint_name!r}: {_listed(drivers)}; "
            f"all actuators: {_listed(names)}"
        )
    index = names.index(actuator)
    if actuator not in drivers:
        raise ParameterValueError(
            f"actuator must drive joint {joint_name!r} directly, got {actuator!r}, which "
            f"does not; actuators driving it: {_listed(drivers)}"
        )
    motor = (
        model.actuator_gaintype[index] == mujoco.mjtGain.mjGAIN_FIXED
        and model.actuator_biastype[index] == mujoco.mjtBias.mjBIAS_NONE
        and model.actuator_dyntype[index] == mujoco.mjtDyn.mjDYN_NONE
    )
    scale = float(model.actuator_gear[index, 0] * model.actuator_gainprm[index, 0])
    if not motor or scale == 0.0:
        kinds = (
            mujoco.mjtGain(model.actuator_gaintype[index]).name,
            mujoco.mjtBias(model.actuator_biastype[index]).name,
            mujoco.mjtDyn(model.actuator_dyntype[index]).name,
        )
        raise ParameterValueError(
            f"actuator must be a torque source (a <motor>: fixed nonzero gain, no bias, no "
            f"activation dynamics), got {actuator!r} with gain type {kinds[0]}, bias type "
            f"{kinds[1]}, dynamics {kinds[2]} and gear x gain = {scale!r}"
        )
    return index, 1.0 / scale


def open_handle(source: str, path, joint, actuator, overrides: dict, timestep: float):
    """A fresh compiled model with MuJoCo time step ``timestep`` [s] and its data at ``qpos0``
    (:meth:`MujocoServo.open`); ``overrides`` may set the joint's ``b`` and ``coulomb``."""
    mujoco = import_mujoco()
    model = compile_model(source, path)
    model.opt.timestep = timestep
    joint_id = find_joint(model, joint)
    actuator_id, scale = find_actuator(model, joint_id, joint, actuator)
    dof = int(model.jnt_dofadr[joint_id])
    if "b" in overrides:
        model.dof_damping[dof] = overrides["b"]
    if "coulomb" in overrides:
        model.dof_frictionloss[dof] = overrides["coulomb"]
    data = mujoco.MjData(model)
    return MujocoHandle(
        mujoco, model, data, int(model.jnt_qposadr[joint_id]), dof, actuator_id, scale
    )


def read_mjcf(path_or_string) -> tuple[str, str | None]:
    """``(MJCF text, resolved path or None)`` of :meth:`MujocoServo.from_xml`'s argument."""
    if isinstance(path_or_string, os.PathLike) or (
        isinstance(path_or_string, str) and not path_or_string.lstrip().startswith("<")
    ):
        path = Path(path_or_string)
        if not path.is_file():
            raise ParameterValueError(
                f"path_or_string must be MJCF XML text or the path of an MJCF file, got "
                f"{str(path_or_string)!r}, which is not an existing file"
            )
        return path.read_text(), str(path.resolve())
    if isinstance(path_or_string, str):
        return path_or_string, None
    raise ParameterTypeError(
        f"path_or_string must be MJCF XML text or a file path, got {type(path_or_string).__name__}"
    )


def joint_and_actuator(model, joint, actuator) -> tuple[str, str]:
    """The names of the controlled hinge and of its motor (found or checked in ``model``)."""
    joint_id = find_joint(model, joint)
    name = object_names(model, import_mujoco().mjtObj.mjOBJ_JOINT, model.njnt)[joint_id]
    index, _ = find_actuator(model, joint_id, name, actuator)
    return name, object_names(model, import_mujoco().mjtObj.mjOBJ_ACTUATOR, model.nu)[index]


def joint_inertia(handle: MujocoHandle) -> float:
    """The joint-space inertia of the handle's joint at its pose [kg m^2] (``mj_mulM``)."""
    column = np.zeros(handle.model.nv)
    unit = np.zeros(handle.model.nv)
    unit[handle.dof] = 1.0
    handle.mujoco.mj_forward(handle.model, handle.data)
    handle.mujoco.mj_mulM(handle.model, handle.data, column, unit)
    return float(column[handle.dof])


def integrator_name(model) -> str:
    """The MJCF name of ``model``'s integrator (e.g. ``'RK4'``)."""
    name = import_mujoco().mjtIntegrator(model.opt.integrator).name.removeprefix("mjINT_")
    return next((i for i in INTEGRATORS if i.upper() == name), name)
