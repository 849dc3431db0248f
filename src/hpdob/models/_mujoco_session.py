"""One MuJoCo run of a :class:`~hpdob.MujocoServo`, advanced from Python by the sample loop."""

from __future__ import annotations

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
        return MujocoSession(self.servo.open(self.timestep), x, self.substeps)


class MujocoSession(PlantSession):
    r"""One MuJoCo run: ``qpos/qvel`` of the joint are the motor's angle and velocity.

    The command is applied as ``ctrl = a / (gear gain)``, the external torque as
    ``qfrc_applied = -tau_ext``; the acceleration for the ground truth is MuJoCo's own ``qacc``
    after ``mj_forward``; each sample takes ``substeps`` calls of ``mj_step`` with the external
    torque at each step's midpoint. An unstable run (MuJoCo warnings, after which it resets its
    state) counts as diverged.
    """

    engine = "MuJoCo"

    def __init__(self, handle: MujocoHandle, x, substeps: int):
        self.handle, self.substeps = handle, substeps
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

    def diverged(self, limit: float) -> bool:
        th, om = self.motor()
        return self._unstable() != self._warnings or not (abs(th) <= limit and abs(om) <= limit)
