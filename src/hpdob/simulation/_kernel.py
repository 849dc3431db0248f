r"""The compiled sample loop: one definition of the sample step, for every plant.

:func:`run_samples` is compiled by numba (``cache=True``: the machine code is cached on disk, so
only the first run on a machine pays the compilation); ``NUMBA_DISABLE_JIT=1`` runs the same
code as plain Python. This module is imported on the first simulation, never by
``import hpdob``.

Per sample ``k`` (``t_k = k Ts``) the loop runs, for every plant:

1. measure: ideal, or encoder (quantised angle with optional noise, backward-difference or
   exact velocity);
2. estimate: the observer's outputs :math:`\hat\tau_k (, \hat\omega_k) = H s_k + E v_k`
   (0 without observer), from its program (:class:`hpdob.observers.Program`), in exactly the
   operation order of the Python observer and the exported C; then an RTOB's Coulomb term
   (``LinearObserver.coulomb``) is subtracted from ``tau_reac``;
3. control: the controller's signal rows in order (:class:`hpdob.controllers.ControllerProgram`),
   from its state and its inputs wired by name (reference, measurement, observer outputs); the
   last signal is the command :math:`u_k` (or, for a controller with a latching
   :class:`~hpdob.controllers.Switch` that is on, its ``after`` signal plus ``offset``; the PD:
   :math:`J_n(k_p(r_k-\theta_{m,k}) + k_d(\dot r_k-\omega_{m,k}) + \ddot r_k) + \hat\tau_k`),
   clipped to the actuator limit;
4. observer update :math:`s_{k+1} = F s_k + G [v_k, u_k]` and controller update
   :math:`c_{k+1} = F_c c_k + G_c [v_k, \bar u_k]` with the clipped command;
5. the plant receives :math:`u_{k-d}` (``d`` samples of delay; 0 before the first command);
6. ground truth (eq. 3) just after :math:`u_{k-d}` is applied:
   :math:`\tau_{dn,k} = u_k - b_n\omega_k - J_n\ddot\theta(t_k^+)` (:func:`ground_truth`);
7. the plant's advance over :math:`[t_k, t_{k+1})`.

A plant with an :class:`~hpdob.Environment` records the contact torque and the in-contact flag
at :math:`t_k` with step 1 (``Outputs.tau_contact``, ``in_contact``); the contact torque is part
of the external torque :math:`F` below, evaluated like the Coulomb friction at the start and the
exponential midpoint of each sub-step (the angle and velocity of the contacting body there),
so a contact onset inside a sub-step is resolved to second order
(``tests/models/test_environment.py``: halving the default sub-step changes the contact torque by
< 1 % of its peak, measured 0.2 % on a 0.014 N m impact).

Only the plant's part (the acceleration of step 6 and step 7) differs per plant. For plants with
a linear part (:class:`~hpdob.ServoModel`, :class:`~hpdob.TwoMassServo`;
``plant.linear``) the loop does it in sub-steps of ``h = Ts/S``: the linear part exactly (ZOH
over the sub-step), the Coulomb friction and the external disturbance by an exponential
midpoint rule. With :math:`F(\omega, t) = c\tanh(\omega/v) + \tau_{ext}(t)` and
:math:`t_{j+1/2}` the sub-step midpoint:

.. math::

    x_{j+1/2} = A_{h/2} x_j + B_{h/2}\,(u - F(\omega_j, t_{j+1/2})),\qquad
    x_{j+1} = A_h x_j + B_h\,(u - F(\omega_{j+1/2}, t_{j+1/2})),

second order in ``h`` for smooth forcing, and exact for disturbance steps on sub-step
boundaries (the canonical ones are at half samples, so any even ``S`` aligns them). The plant's
sampler names the path that advances it (``ExactSubsteps.path``): ``"rigid"`` and
``"two-mass"`` hold the state in registers, ``"generic"`` loops over any state size
(``tests/models/test_plant.py`` checks it against the exact ZOH recurrence). A plant
advanced from Python (MuJoCo) calls :func:`run_samples` for one sample at a time, which then
stops after step 5 and leaves steps 6-7 to the plant
(``hpdob.simulation._python_plant``).

The step is written once, inline in the loop: a per-sample call of a numba function taking
the run's records costs more than the step itself (their arrays are reference-counted at every
call boundary).
"""

from __future__ import annotations

import math

import numba

from ..observers import coulomb_torque as _coulomb_torque
from ._records import PATH_RIGID, PATH_TWO_MASS, SENSOR_ENCODER_EXACT, SENSOR_IDEAL

__all__ = ["ground_truth", "program_row", "run_samples"]

_jit = numba.njit(cache=True, nogil=True)

#: The RTOB's Coulomb term, compiled from its one definition (``hpdob.observers._friction``).
coulomb_torque = _jit(_coulomb_torque)


@_jit
def program_row(pointer, coefficient, operand, w, row):
    """Row ``row`` of an observer's program: the left-to-right sum of
    ``coefficient[t] * w[operand[t]]`` over its terms (0 for an empty row)."""
    start, stop = pointer[row], pointer[row + 1]
    if start == stop:
        return 0.0
    acc = coefficient[start] * w[operand[start]]
    for t in range(start + 1, stop):
        acc += coefficient[t] * w[operand[t]]
    return acc


@_jit
def ground_truth(uk, om, accel, J_n, b_n):
    r"""Eq. (3) at :math:`t_k^+`: :math:`\tau_{dn,k} = u_k - b_n\omega_k - J_n\ddot\theta`."""
    return uk - b_n * om - J_n * accel


@_jit
def contact_torque(th, om, k_e, c_e, th_e):
    r"""The unilateral environment's torque: :math:`k_e(\theta-\theta_e) + c_e\omega` where
    :math:`\theta > \theta_e` and that pushes, else 0 (:class:`hpdob.Environment`)."""
    if th <= th_e:
        return 0.0
    push = k_e * (th - th_e) + c_e * om
    return push if push > 0.0 else 0.0


@_jit
def run_samples(k_start, k_stop, substeps, Ts, plant, ctl, sen, act, obs, sig, out, work, limit):
    """Run samples ``k_start <= k < k_stop``; return the number of samples completed.

    With a linear plant the plant is advanced here and a return value below ``k_stop`` means
    its state left ``|x| <= limit`` (or became non-finite) at the end of the last completed
    sample. Otherwise one sample's steps 1-5 run (the plant's state ``work.x`` set by the
    caller) and ``work.applied[0]`` holds the torque to apply.
    """
    r, r_dot, r_ddot, tau_sample, tau_mid, noise = sig
    theta, omega, theta_m, omega_m, u, tau_hat, tau_dn, omega_hat, states = out[:9]
    tau_contact, in_contact, tau_reac = out[9], out[10], out[11]
    s, s_new, w, c_s, c_new, cw, sv, previous, x, x_next, applied_out = work
    up_ptr, up_c, up_i = obs.update_pointer, obs.update_coefficient, obs.update_operand
    out_ptr, out_c, out_i = obs.output_pointer, obs.output_coefficient, obs.output_operand
    n, p, q = obs.n, obs.p, obs.q
    has_observer, velocity_row, reaction_row = obs.present, obs.velocity_row, obs.reaction_row
    c_source, c_n, v_n = obs.coulomb_source, obs.coulomb, obs.coulomb_velocity
    J_n, b_n = ctl.J_n, ctl.b_n
    nc, pc, qc, source = ctl.n, ctl.p, ctl.q, ctl.source
    sig_ptr, sig_c, sig_i = ctl.signal_pointer, ctl.signal_coefficient, ctl.signal_operand
    cup_ptr, cup_c, cup_i = ctl.update_pointer, ctl.update_coefficient, ctl.update_operand
    first = nc + pc + 1  # operand index of the controller's first signal
    latch, trigger, threshold = ctl.switch_latch, ctl.switch_trigger, ctl.switch_threshold
    after, offset = ctl.switch_after, ctl.switch_offset
    mode, resolution = sen.mode, sen.resolution
    torque_limit, delay = act.torque_limit, act.delay
    A_h, B_h, D_h = plant.A_h, plant.B_h, plant.D_h
    A_half, B_half, D_half = plant.A_half, plant.B_half, plant.D_half
    internal, shared, v, path = plant.internal, plant.shared, plant.velocity_index, plant.path
    c, c_scale, J_motor = plant.coulomb, plant.coulomb_velocity, plant.J_motor
    wall, ci = plant.contact, plant.contact_index
    k_e, c_e, th_e = plant.contact_stiffness, plant.contact_damping, plant.contact_position
    nx = x.shape[0]
    record = states.shape[0] > 0
    for k in range(k_start, k_stop):
        th = x[0]
        om = x[v]
        theta[k] = th
        omega[k] = om
        if record:
            for i in range(nx):
                states[k, i] = x[i]
        f_env = 0.0
        if wall:
            f_env = contact_torque(x[ci], x[ci + 1], k_e, c_e, th_e)
            tau_contact[k] = f_env
            in_contact[k] = 1.0 if f_env > 0.0 else 0.0
        # 1. measurement
        if mode == SENSOR_IDEAL:
            thm = th
            omm = om
        else:
            thm = resolution * math.floor((th + noise[k]) / resolution + 0.5)
            if mode == SENSOR_ENCODER_EXACT:
                omm = om
            elif k == 0:
                omm = 0.0
            else:
                omm = (thm - previous[0]) / Ts
            previous[0] = thm
        theta_m[k] = thm
        omega_m[k] = omm
        # 2. estimate: output rows of the observer's program, left to right
        est = 0.0
        if has_observer:
            for i in range(n):
                w[i] = s[i]
            w[n] = thm
            if p == 2:
                w[n + 1] = omm
            est = program_row(out_ptr, out_c, out_i, w, 0)
            if q > 1:
                for j in range(1, q):
                    sv[5 + j] = program_row(out_ptr, out_c, out_i, w, j)
                if c_source > 0:  # the RTOB's Coulomb term, after the linear rows
                    speed = omm if c_source == 1 else sv[5 + velocity_row]
                    sv[5 + reaction_row] = sv[5 + reaction_row] - coulomb_torque(c_n, v_n, speed)
                if velocity_row > 0:
                    omega_hat[k] = sv[5 + velocity_row]
                if reaction_row > 0:
                    tau_reac[k] = sv[5 + reaction_row]
        tau_hat[k] = est
        sv[0] = r[k]
        sv[1] = r_dot[k]
        sv[2] = r_ddot[k]
        sv[3] = thm
        sv[4] = omm
        sv[5] = est
        # 3. control: the controller's signal rows in order, the last is the command; limited
        for i in range(nc):
            cw[i] = c_s[i]
        for j in range(pc):
            cw[nc + j] = sv[source[j]]
        for j in range(qc):
            cw[first + j] = program_row(sig_ptr, sig_c, sig_i, cw, j)
        uk = cw[first + qc - 1]
        on = False
        if latch >= 0:  # a latching switch (hpdob.controllers.Switch), after the signal rows
            on = c_s[latch] != 0.0 or cw[trigger] >= threshold
            if on:
                uk = cw[first + after] + offset
        if uk > torque_limit:
            uk = torque_limit
        elif uk < -torque_limit:
            uk = -torque_limit
        u[k] = uk
        # 4. observer and controller updates with the command really given, left to right
        if has_observer:
            w[n + p] = uk
            for i in range(n):
                s_new[i] = program_row(up_ptr, up_c, up_i, w, i)
            for i in range(n):
                s[i] = s_new[i]
        if nc > 0:
            cw[nc + pc] = uk
            for i in range(nc):
                c_new[i] = program_row(cup_ptr, cup_c, cup_i, cw, i)
            if latch >= 0:
                c_new[latch] = 1.0 if on else 0.0
            for i in range(nc):
                c_s[i] = c_new[i]
        # 5. actuator delay
        applied = u[k - delay] if k >= delay else 0.0
        if not plant.linear:
            applied_out[0] = applied
            return k + 1
        # 6. ground truth just after u is applied: the motor's acceleration
        tau = tau_sample[k]
        accel = applied
        for i in range(nx):
            if internal[i] != 0.0:
                accel -= internal[i] * x[i]
        accel -= c * math.tanh(om / c_scale)
        if shared:
            accel -= tau + f_env
        tau_dn[k] = ground_truth(uk, om, accel / J_motor, J_n, b_n)
        # 7. the plant over [t_k, t_{k+1}): exponential midpoint sub-steps
        base = k * substeps
        if path == PATH_RIGID:  # the rigid servo, kept in registers
            a00, a01, a10, a11 = A_h[0, 0], A_h[0, 1], A_h[1, 0], A_h[1, 1]
            h10, h11, b0, b1, g1 = A_half[1, 0], A_half[1, 1], B_h[0], B_h[1], B_half[1]
            h00, h01, g0 = A_half[0, 0], A_half[0, 1], B_half[0]
            for j in range(substeps):
                tau_e = tau_mid[base + j]
                start = tau_e
                if wall:
                    start += contact_torque(th, om, k_e, c_e, th_e)
                force = applied - c * math.tanh(om / c_scale) - start
                om_half = h10 * th + h11 * om + g1 * force
                if wall:
                    th_half = h00 * th + h01 * om + g0 * force
                    tau_e += contact_torque(th_half, om_half, k_e, c_e, th_e)
                force = applied - c * math.tanh(om_half / c_scale) - tau_e
                th, om = a00 * th + a01 * om + b0 * force, a10 * th + a11 * om + b1 * force
            x[0] = th
            x[1] = om
        elif path == PATH_TWO_MASS:  # the two-mass drive, kept in registers
            x0, x1, x2, x3 = x[0], x[1], x[2], x[3]
            h0, h1, h2, h3 = A_half[1, 0], A_half[1, 1], A_half[1, 2], A_half[1, 3]
            gb, gd = B_half[1], D_half[1]
            for j in range(substeps):
                tau_e = tau_mid[base + j]
                start = tau_e
                if wall:
                    start += contact_torque(x2, x3, k_e, c_e, th_e)
                force = applied - c * math.tanh(x1 / c_scale)
                om_half = h0 * x0 + h1 * x1 + h2 * x2 + h3 * x3 + gb * force - gd * start
                if wall:
                    load_th = (
                        A_half[2, 0] * x0
                        + A_half[2, 1] * x1
                        + A_half[2, 2] * x2
                        + A_half[2, 3] * x3
                        + B_half[2] * force
                        - D_half[2] * start
                    )
                    load_om = (
                        A_half[3, 0] * x0
                        + A_half[3, 1] * x1
                        + A_half[3, 2] * x2
                        + A_half[3, 3] * x3
                        + B_half[3] * force
                        - D_half[3] * start
                    )
                    tau_e += contact_torque(load_th, load_om, k_e, c_e, th_e)
                force = applied - c * math.tanh(om_half / c_scale)
                y0 = A_h[0, 0] * x0 + A_h[0, 1] * x1 + A_h[0, 2] * x2 + A_h[0, 3] * x3
                y1 = A_h[1, 0] * x0 + A_h[1, 1] * x1 + A_h[1, 2] * x2 + A_h[1, 3] * x3
                y2 = A_h[2, 0] * x0 + A_h[2, 1] * x1 + A_h[2, 2] * x2 + A_h[2, 3] * x3
                y3 = A_h[3, 0] * x0 + A_h[3, 1] * x1 + A_h[3, 2] * x2 + A_h[3, 3] * x3
                x0 = y0 + B_h[0] * force - D_h[0] * tau_e
                x1 = y1 + B_h[1] * force - D_h[1] * tau_e
                x2 = y2 + B_h[2] * force - D_h[2] * tau_e
                x3 = y3 + B_h[3] * force - D_h[3] * tau_e
            x[0], x[1], x[2], x[3] = x0, x1, x2, x3
        else:  # any plant (the path its sampler names)
            for j in range(substeps):
                tau_e = tau_mid[base + j]
                start = tau_e
                if wall:
                    start += contact_torque(x[ci], x[ci + 1], k_e, c_e, th_e)
                force = applied - c * math.tanh(x[v] / c_scale)
                for row in range(nx):
                    if row != v and not (wall and (row == ci or row == ci + 1)):
                        continue
                    acc = A_half[row, 0] * x[0]
                    for i in range(1, nx):
                        acc += A_half[row, i] * x[i]
                    if shared:
                        acc += B_half[row] * (force - start)
                    else:
                        acc += B_half[row] * force
                        acc -= D_half[row] * start
                    x_next[row] = acc
                om_half = x_next[v]
                if wall:
                    tau_e += contact_torque(x_next[ci], x_next[ci + 1], k_e, c_e, th_e)
                force = applied - c * math.tanh(om_half / c_scale)
                for row in range(nx):
                    acc = A_h[row, 0] * x[0]
                    for i in range(1, nx):
                        acc += A_h[row, i] * x[i]
                    if shared:
                        acc += B_h[row] * (force - tau_e)
                    else:
                        acc += B_h[row] * force
                        acc -= D_h[row] * tau_e
                    x_next[row] = acc
                for row in range(nx):
                    x[row] = x_next[row]
        for i in range(nx):
            if not abs(x[i]) <= limit:
                return k + 1
    return k_stop
