"""One MuJoCo run of a :class:`~hpdob.robots.MujocoArm`, stepped by the N-joint loop."""

from __future__ import annotations

import numpy as np

__all__ = ["MujocoArmSession"]


class MujocoArmSession:
    """One MuJoCo run of a :class:`MujocoArm`, advanced by the N-joint loop.

    With MuJoCo's ``Euler`` integrator the first MuJoCo step of each sample is split
    (``mj_step1``, the command, ``mj_step2``): its ``qacc`` is the acceleration just after the
    command, so the ground truth costs no extra ``mj_forward``. Other integrators take one
    ``mj_forward`` for it, then ``substeps`` calls of ``mj_step``.
    """

    def __init__(self, arm, q0, Ts: float, substeps: int):
        self.mujoco, self.model, self.data = arm.compile(Ts / substeps)
        mujoco = self.mujoco
        self.substeps = substeps
        self.actuators = arm._cache["actuators"]
        self.ctrl_per_torque = arm._cache["ctrl_per_torque"]
        self.site = arm._cache["site"]
        self.body = int(self.model.site_bodyid[self.site])
        self.data.qpos[:] = q0
        self.jac = np.zeros((6, self.model.nv))
        self.split = self.model.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
        # the motors in joint order are all of ctrl: write it in place (no fancy indexing)
        self.direct = self.model.nu == len(self.actuators) and bool(
            np.all(self.actuators == np.arange(len(self.actuators)))
        )
        self.h = Ts / substeps
        self._steps = 0

    def state(self):
        return self.data.qpos, self.data.qvel

    def _force(self, wrench):
        """``wrench``: a force [N] (3) or a force and a moment [N m] (6) at the site."""
        data = self.data
        frc = data.xfrc_applied[self.body]
        force = wrench[:3]
        frc[:3] = force
        # xfrc_applied acts at the body's centre of mass: add the moment that moves it to the site
        frc[3:] = np.cross(data.site_xpos[self.site] - data.xipos[self.body], force)
        if len(wrench) == 6:
            frc[3:] += wrench[3:]

    def _external_torque(self, wrench):
        mujoco = self.mujoco
        mujoco.mj_jacSite(self.model, self.data, self.jac[:3], self.jac[3:], self.site)
        tau = self.jac[:3].T @ wrench[:3]
        if len(wrench) == 6:
            tau += self.jac[3:].T @ wrench[3:]
        return tau

    def sample(self, applied, force, forces, qdd):
        """Apply ``applied`` [N m] over one sample (``force`` [N] at the site at the sample
        instant, ``forces`` at each MuJoCo step's midpoint; None: no force). Writes the joint
        accelerations just after the command into ``qdd``; returns the external joint torques
        ``J^T F`` [N m] (None without force)."""
        mujoco, model, data = self.mujoco, self.model, self.data
        if self.direct:
            np.multiply(applied, self.ctrl_per_torque, out=data.ctrl)
        else:
            data.ctrl[self.actuators] = applied * self.ctrl_per_torque
        tau_e = None
        first = 0
        if self.split:
            mujoco.mj_step1(model, data)
            if force is not None:
                self._force(force)
                tau_e = self._external_torque(force)
            mujoco.mj_step2(model, data)
            qdd[:] = data.qacc
            first = 1
        else:
            if force is not None:
                mujoco.mj_kinematics(model, data)
                self._force(force)
            mujoco.mj_forward(model, data)
            qdd[:] = data.qacc
            if force is not None:
                tau_e = self._external_torque(force)
        for j in range(first, self.substeps):
            if forces is not None:
                self._force(forces[j])
            mujoco.mj_step(model, data)
        self._steps += self.substeps
        return tau_e

    def diverged(self) -> bool:
        """True if MuJoCo reset the simulation (its time went back: it does so after an
        instability warning); the loop's kernel checks ``|q|, |qd| <= limit`` itself."""
        return self.data.time < (self._steps - 0.5) * self.h
