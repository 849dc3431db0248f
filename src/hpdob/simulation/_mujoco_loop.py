r"""The sample loop of :func:`hpdob.simulate` for a :class:`~hpdob.MujocoServo` plant.

Plain Python around MuJoCo, with the per-sample order, sensor, controller, limit, delay and
observer arithmetic of the compiled kernel (``_kernel``); only the plant differs.
Per sample ``k``:

1. read ``theta_k, omega_k`` from MuJoCo's ``qpos``/``qvel`` and measure them;
2. estimate, control, clip, observer update (the observer through the functional core, which
   the kernel matches bit for bit);
3. the actuator delay gives the applied command ``u_{k-d}``: ``ctrl = u_{k-d} / (gear gain)``,
   and ``qfrc_applied = -tau_ext(t_k)``;
4. ground truth (eq. 3): ``mj_forward``, then :math:`\tau_{dn,k} = u_k - b_n\omega_k -
   J_n\ddot\theta(t_k^+)` with MuJoCo's own ``qacc``;
5. ``substeps`` calls of ``mj_step``, each with ``qfrc_applied = -tau_ext`` at the midpoint of
   that MuJoCo step (the values hpdob's integrator uses) and ``ctrl`` held (ZOH).

The run stops after a sample whose end state has ``|theta|`` or ``|omega|`` above the
divergence limit, is not finite, or for which MuJoCo flagged an unstable simulation (it then
resets its state, so the flag is what tells).
"""

from __future__ import annotations

import math

from ..observers import _core
from ._kernel import SENSOR_ENCODER_EXACT, SENSOR_IDEAL

__all__ = ["run_mujoco_loop"]

#: MuJoCo warnings that mean the simulation blew up (MuJoCo then resets the state).
_UNSTABLE = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC", "mjWARN_BADCTRL")


def run_mujoco_loop(
    plant,
    *,
    n_samples,
    substeps,
    Ts,
    x0,
    J_n,
    b_n,
    kp,
    kd,
    feedforward,
    r,
    r_dot,
    r_ddot,
    tau_mid,
    tau_sample,
    sensor_mode,
    resolution,
    position_noise,
    torque_limit,
    delay,
    design,
    z0,
    divergence_limit,
    out,
):
    """Simulate ``n_samples`` samples on ``plant``; fill ``out`` (the kernel's output arrays,
    by name); return the number of samples completed (as ``_kernel.run_closed_loop``).
    """
    handle = plant.open(Ts / substeps)
    mujoco, model, data = handle.mujoco, handle.model, handle.data
    mj_forward, mj_step = mujoco.mj_forward, mujoco.mj_step
    q, v, a, scale = handle.qpos, handle.dof, handle.actuator, handle.ctrl_per_torque
    ctrl, applied_force, qpos, qvel, qacc = (
        data.ctrl, data.qfrc_applied, data.qpos, data.qvel, data.qacc
    )  # fmt: skip
    flags = [data.warning[int(getattr(mujoco.mjtWarning, name))] for name in _UNSTABLE]

    def unstable() -> int:
        return sum(flag.number for flag in flags)

    qpos[q], qvel[v] = x0[0], x0[1]
    theta, omega, theta_m, omega_m = out["theta"], out["omega"], out["theta_m"], out["omega_m"]
    u, tau_hat, tau_dn = out["u"], out["tau_hat"], out["tau_dn"]
    state = None if design is None else tuple(float(value) for value in z0)
    th, om = float(x0[0]), float(x0[1])
    th_m_prev = 0.0
    warnings_before = unstable()
    for k in range(n_samples):
        theta[k] = th
        omega[k] = om
        # 1. measurement (as the kernel)
        if sensor_mode == SENSOR_IDEAL:
            thm, omm = th, om
        else:
            thm = resolution * math.floor((th + position_noise[k]) / resolution + 0.5)
            if sensor_mode == SENSOR_ENCODER_EXACT:
                omm = om
            elif k == 0:
                omm = 0.0
            else:
                omm = (thm - th_m_prev) / Ts
            th_m_prev = thm
        theta_m[k] = thm
        omega_m[k] = omm
        # 2. estimate, control, limit, observer update
        est = 0.0 if state is None else _core.estimate(design, state, (thm, omm))
        tau_hat[k] = est
        acc = kp * (r[k] - thm) + kd * (r_dot[k] - omm)
        if feedforward:
            acc += r_ddot[k]
        uk = J_n * acc + est
        if uk > torque_limit:
            uk = torque_limit
        elif uk < -torque_limit:
            uk = -torque_limit
        u[k] = uk
        if state is not None:
            state = _core.update(design, state, (thm, omm), uk)
        # 3. actuator delay; 4. ground truth from MuJoCo's acceleration just after u is applied
        applied = u[k - delay] if k >= delay else 0.0
        ctrl[a] = applied * scale
        applied_force[v] = -tau_sample[k]
        mj_forward(model, data)
        tau_dn[k] = uk - b_n * om - J_n * float(qacc[v])
        # 5. MuJoCo integrates over [t_k, t_{k+1}), tau_ext at each step's midpoint
        base = k * substeps
        for j in range(substeps):
            applied_force[v] = -tau_mid[base + j]
            mj_step(model, data)
        th, om = float(qpos[q]), float(qvel[v])
        if unstable() != warnings_before or not (
            abs(th) <= divergence_limit and abs(om) <= divergence_limit
        ):
            return k + 1
    return n_samples
