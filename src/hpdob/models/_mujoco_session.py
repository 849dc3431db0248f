"""One MuJoCo run of a :class:`~hpdob.MujocoServo`, advanced from Python by the sample loop."""

from __future__ import annotations

import numpy as np

from ._mjcf import MujocoHandle
from ._plant import PlantSession

__all__ = ["MujocoSampler", "MujocoSession"]

#: MuJoCo warnings that mean the simulation blew up (MuJoCo then resets the state).
_UNSTABLE = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")


class MujocoSampler:
    """Starts MuJoCo runs of a :class:`MujocoServo` (see :class:`MujocoSession`)."""

    def __init__(self, servo, timestep: float, substeps: int):
        self.servo, self.timestep, self.substeps = servo, timestep, substeps

    def start(self, x) -> MujocoSession:
        return MujocoSession(self.servo.open(self.timestep), x, self.substeps,
                             contact_geom=self.servo.contact_geom)  # fmt: skip


class MujocoSession(PlantSession):
    r"""One MuJoCo run: ``qpos/qvel`` of the joint are the motor's angle and velocity.

    The command is applied as ``ctrl = a / (gear gain)``, the external torque as
    ``qfrc_applied = -tau_ext``; the acceleration for the ground truth is MuJoCo's own ``qacc``
    after ``mj_forward``; each sample takes ``substeps`` calls of ``mj_step`` with the external
    torque at each step's midpoint. An unstable run (MuJoCo warnings, after which it resets its
    state) counts as diverged. With a ``contact_geom`` (the tip of a link that presses a wall),
    :meth:`contact` gives the ground-truth contact torque.
    """

    engine = "MuJoCo"

    def __init__(self, handle: MujocoHandle, x, substeps: int, *, contact_geom=None):
        self.handle, self.substeps = handle, substeps
        self._geom = -1
        if contact_geom is not None:
            mujoco, model = handle.mujoco, handle.model
            self._geom = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, contact_geom))
            self._body = int(model.geom_bodyid[self._geom])
            self._force = np.zeros(6)
            self._jacp, self._jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco, data = handle.mujoco, handle.data
        self._forward, self._step = mujoco.mj_forward, mujoco.mj_step
        self._flags = [data.warning[int(getattr(mujoco.mjtWarning, n))] for n in _UNSTABLE]
        data.qpos[handle.qpos], data.qvel[handle.dof] = x[0], x[1]
        self._warnings = self._unstable()

    def _unstable(self) -> int:
        return sum(flag.number for flag in self._flags)

    def motor(self) -> tuple[float, float]:
        h = self.handle
        return float(h.data.qpos[h.qpos]), float(h.data.qvel[h.dof])

    def acceleration(self, applied: float, tau: float) -> float:
        h = self.handle
        h.data.ctrl[h.actuator] = applied * h.ctrl_per_torque
        h.data.qfrc_applied[h.dof] = -tau
        self._forward(h.model, h.data)
        return float(h.data.qacc[h.dof])

    def advance(self, applied: float, tau_mid) -> None:
        h = self.handle
        model, data, step, dof = h.model, h.data, self._step, h.dof
        data.ctrl[h.actuator] = applied * h.ctrl_per_torque
        applied_force = data.qfrc_applied
        for j in range(self.substeps):
            applied_force[dof] = -tau_mid[j]
            step(model, data)

    def contact(self) -> tuple[float, float] | None:
        r"""The contact torque on the joint [N m] and the in-contact flag, from the last
        ``mj_forward`` (:meth:`acceleration`: just after the command is applied).

        Every contact of the contact geom: MuJoCo's contact force (``mj_contactForce``, in the
        contact frame, the force geom1 exerts on geom2) turned into the world frame, taken as
        the force on the contact geom, and mapped to the joint through the translational
        Jacobian of its body at the contact point (``mj_jac``): :math:`\tau = -J_p^T f`, so a
        wall that pushes back gives a positive torque, as :class:`~hpdob.Environment` does.
        Not ``qfrc_constraint``, which also holds the joint's friction loss and limits.
        None without a contact geom.
        """
        if self._geom < 0:
            return None
        h = self.handle
        mujoco, model, data = h.mujoco, h.model, h.data
        torque, touching = 0.0, 0.0
        for i in range(data.ncon):
            c = data.contact[i]
            if self._geom not in (c.geom1, c.geom2):
                continue
            mujoco.mj_contactForce(model, data, i, self._force)
            world = c.frame.reshape(3, 3).T @ self._force[:3]
            on_geom = -world if c.geom1 == self._geom else world
            mujoco.mj_jac(model, data, self._jacp, self._jacr, c.pos, self._body)
            torque -= float(self._jacp[:, h.dof] @ on_geom)
            touching = 1.0
        return torque, touching

    def diverged(self, limit: float) -> bool:
        th, om = self.motor()
        return self._unstable() != self._warnings or not (abs(th) <= limit and abs(om) <= limit)
