r"""The sampled-data closed-loop kernel: one function over arrays and floats only.

Written in the subset of Python that numba compiles (:mod:`~hpdob.simulation._compiled`
compiles it;
:func:`run_closed_loop` also runs as plain Python, which the tests use as a cross-check).

Per sample ``k`` (``t_k = k Ts``):

1. measure: ideal, or encoder (quantised angle with optional noise, backward-difference or
   exact velocity);
2. estimate: :math:`\hat\tau_k = \hat z_{m+1} - L_{m+1}^T x_{m,k}` (0 without observer);
3. control: :math:`u_k = J_n(\ddot r_k + k_p(r_k-\theta_{m,k}) + k_d(\dot r_k-\omega_{m,k}))
   + \hat\tau_k`, clipped to the actuator limit;
4. observer update with :math:`(x_{m,k}, u_k)`;
5. the plant receives :math:`u_{k-d}` (``d`` samples of delay; 0 before the first command);
6. ground truth :math:`\tau_{dn,k} = u_k - b_n\omega_k - J_n\ddot\theta(t_k^+)` (eq. 3);
7. the plant is advanced over ``[t_k, t_{k+1})`` in ``S`` sub-steps of ``h = Ts/S``: the linear
   part exactly (ZOH over the sub-step), the Coulomb friction and the external disturbance by
   an exponential midpoint rule. With :math:`F(\omega, t) = c\tanh(\omega/v) + \tau_{ext}(t)`
   and :math:`t_{j+1/2}` the sub-step midpoint:

   .. math::

       x_{j+1/2} = A_{h/2} x_j + B_{h/2}\,(u - F(\omega_j, t_{j+1/2})),\qquad
       x_{j+1} = A_h x_j + B_h\,(u - F(\omega_{j+1/2}, t_{j+1/2})),

   second order in ``h`` for smooth forcing, and exact for disturbance steps on sub-step
   boundaries (the canonical ones are at half samples, so any even ``S`` aligns them).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["SENSOR_ENCODER_DIFFERENCE", "SENSOR_ENCODER_EXACT", "SENSOR_IDEAL", "run_closed_loop"]

SENSOR_IDEAL = 0
SENSOR_ENCODER_DIFFERENCE = 1
SENSOR_ENCODER_EXACT = 2


def run_closed_loop(
    n_samples,
    substeps,
    Ts,
    x0,
    A_h,
    B_h,
    A_half,
    B_half,
    J,
    b,
    coulomb,
    coulomb_velocity,
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
    has_observer,
    k_gain,
    p_weight,
    Kx,
    Ku,
    last_gain,
    z0,
    divergence_limit,
    theta,
    omega,
    theta_m,
    omega_m,
    u,
    tau_hat,
    tau_dn,
):
    """Simulate ``n_samples`` samples; fill the output arrays; return the samples completed.

    A return value below ``n_samples`` means the state left ``|x| <= divergence_limit`` (or
    became non-finite) at the end of the last completed sample. All arrays are float64; the
    output arrays (``theta`` ... ``tau_dn``) have length ``n_samples``; ``tau_mid`` has
    ``n_samples * substeps`` entries (disturbance at the sub-step midpoints).
    """
    n = z0.shape[0]
    z = z0.copy()
    z_new = np.empty(n)
    th = x0[0]
    om = x0[1]
    th_m_prev = 0.0
    for k in range(n_samples):
        theta[k] = th
        omega[k] = om
        # 1. measurement
        if sensor_mode == SENSOR_IDEAL:
            thm = th
            omm = om
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
        # 2. estimate
        est = 0.0
        if has_observer:
            est = z[n - 1] - last_gain[0] * thm - last_gain[1] * omm
        tau_hat[k] = est
        # 3. control
        acc = kp * (r[k] - thm) + kd * (r_dot[k] - omm)
        if feedforward:
            acc += r_ddot[k]
        uk = J_n * acc + est
        if uk > torque_limit:
            uk = torque_limit
        elif uk < -torque_limit:
            uk = -torque_limit
        u[k] = uk
        # 4. observer update, z <- M z + Kx x + Ku u with M = C - k e_last^T, in exactly the
        #    operation order of hpdob.observers._core.update (so both agree bit for bit)
        if has_observer:
            last = z[n - 1]
            for i in range(n - 1):
                z_new[i] = (
                    z[i + 1] - k_gain[i] * last + Kx[i, 0] * thm + Kx[i, 1] * omm + Ku[i] * uk
                )
            s = -k_gain[n - 1] * last + Kx[n - 1, 0] * thm + Kx[n - 1, 1] * omm + Ku[n - 1] * uk
            for j in range(n):
                s += p_weight[j] * z[j]
            z_new[n - 1] = s
            for i in range(n):
                z[i] = z_new[i]
        # 5. actuator delay
        applied = u[k - delay] if k >= delay else 0.0
        # 6. ground truth (eq. 3) just after u_k is applied
        accel = (applied - b * om - coulomb * math.tanh(om / coulomb_velocity) - tau_sample[k]) / J
        tau_dn[k] = uk - b_n * om - J_n * accel
        # 7. plant over [t_k, t_{k+1})
        base = k * substeps
        for j in range(substeps):
            tau_e = tau_mid[base + j]
            force = applied - coulomb * math.tanh(om / coulomb_velocity) - tau_e
            om_half = A_half[1, 0] * th + A_half[1, 1] * om + B_half[1] * force
            force = applied - coulomb * math.tanh(om_half / coulomb_velocity) - tau_e
            th_next = A_h[0, 0] * th + A_h[0, 1] * om + B_h[0] * force
            om = A_h[1, 0] * th + A_h[1, 1] * om + B_h[1] * force
            th = th_next
        if not (abs(th) <= divergence_limit and abs(om) <= divergence_limit):
            return k + 1
    return n_samples
