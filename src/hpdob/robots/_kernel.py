r"""The compiled sample step of the N-joint loop: every joint's sensor, observer, controller,
limit and delay in one numba call per sample (no Python per joint).

The joints' observers run as one stacked program (:func:`hpdob.robots._stack.stack_programs`):
the work vector is ``w = [s (all joints' states), theta_m (N), omega_m (N), u (N)]`` and every
joint's rows index into it, so each row is summed in the order of that joint's own
:class:`~hpdob.observers.Program`, exactly as the single-axis kernel sums it.

Per sample ``k`` and joint ``i`` (the single-axis steps of ``docs/architecture.md``):

1. measure (ideal, or encoder: quantised angle with noise, backward-difference or exact
   velocity);
2. estimate (the joint's output rows);
3. control: each joint's controller rows (:mod:`hpdob.robots._controllers`; the PD
   :math:`u_i = J_{n,i}(k_{p,i} e_i + k_{d,i} \dot e_i + \ddot r_i) + \hat\tau_i`), or
   :math:`u = \tau_{model}(\theta_m, \omega_m, a) + \hat\tau` with
   :math:`a = \ddot r + K_p e + K_d \dot e` (computed torque: the model torque is computed
   between the two phases, from Python); clipped to the joint's limit;
4. observer and controller updates with the clipped command;
5. each joint's actuator delay.

Phase 1 is steps 1-2 (and ``a``), phase 2 steps 3-5. The built-in two-link arm is then advanced
here too (ground truth of eq. 3 per joint, RK4 sub-steps of the written-out dynamics), so its
whole run is one call; other plants (MuJoCo) are advanced from Python between calls.
"""

from __future__ import annotations

import math

import numba

from ..simulation import program_row as _row
from ._two_link import two_link_derivative, two_link_rk4

__all__ = ["PHASE_CONTROL", "PHASE_MEASURE", "PLANT_PYTHON", "PLANT_TWO_LINK", "run_arm"]

_jit = numba.njit(cache=True, nogil=True)

PHASE_MEASURE = 1  # steps 1-2
PHASE_CONTROL = 2  # steps 3-5
PLANT_PYTHON = 0
PLANT_TWO_LINK = 1

# rows of fpar (KP, KD, FEEDFORWARD: computed torque's gains)
KP, KD, JN, BN, LIMIT, RESOLUTION, FEEDFORWARD = range(7)
# rows of ipar
MODE, DELAY, TAU_ROW, OMEGA_ROW = range(4)
# rows of rec
THETA, OMEGA, THETA_M, OMEGA_M, U, TAU_HAT, OMEGA_HAT, TAU_DN = range(8)
# sensor modes (as hpdob.simulation's)
IDEAL, DIFFERENCE, EXACT = 0, 1, 2


@_jit
def run_arm(k_start, k_stop, phases, computed_torque, plant_kind, plant_par, substeps, Ts,
            fpar, ipar, ref, rec, noise, up_ptr, up_i, up_c, out_ptr, out_i, out_c, work, x,
            tau_sample, tau_mid, limit, cs_ptr, cs_i, cs_c, cu_ptr, cu_i, cu_c, command,
            cwork):  # fmt: skip
    """Run samples ``k_start <= k < k_stop``; return the number of samples completed.

    ``x = [q (N), qd (N)]`` is the true state; ``work`` holds ``[s, s_new, w, previous,
    acceleration a, model torque, applied torque]``; ``up_*``/``out_*`` are the stacked update
    and output rows (:meth:`~hpdob.observers.Program.arrays` layout); ``cs_*``/``cu_*`` the
    stacked controller signal and update rows, ``command`` each joint's command signal and
    ``cwork`` the controller work vector ``[c, inputs (7 N), u_bar (N), signals, c_new]``.
    """
    N = fpar.shape[1]
    S = up_ptr.shape[0] - 1
    s = work[0:S]
    s_new = work[S : 2 * S]
    w = work[2 * S : 3 * S + 3 * N]
    base = 3 * S + 3 * N
    previous = work[base : base + N]
    acc = work[base + N : base + 2 * N]
    model = work[base + 2 * N : base + 3 * N]
    applied = work[base + 3 * N : base + 4 * N]
    C = cu_ptr.shape[0] - 1
    Q = cs_ptr.shape[0] - 1
    bar = C + 7 * N
    first_signal = bar + N
    h = Ts / substeps
    for k in range(k_start, k_stop):
        if phases & PHASE_MEASURE:
            if plant_kind == PLANT_PYTHON:
                for i in range(2 * N):
                    if not abs(x[i]) <= limit:
                        return k  # the plant's state (set by the caller) left the limit
            for i in range(N):
                th = x[i]
                om = x[N + i]
                rec[THETA, k, i] = th
                rec[OMEGA, k, i] = om
                mode = ipar[MODE, i]
                if mode == IDEAL:
                    thm = th
                    omm = om
                else:
                    res = fpar[RESOLUTION, i]
                    thm = res * math.floor((th + noise[k, i]) / res + 0.5)
                    if mode == EXACT:
                        omm = om
                    elif k == 0:
                        omm = 0.0
                    else:
                        omm = (thm - previous[i]) / Ts
                    previous[i] = thm
                rec[THETA_M, k, i] = thm
                rec[OMEGA_M, k, i] = omm
                w[S + i] = thm
                w[S + N + i] = omm
            for j in range(S):
                w[j] = s[j]
            for i in range(N):
                est = 0.0
                om_hat = 0.0
                if ipar[TAU_ROW, i] >= 0:
                    est = _row(out_ptr, out_c, out_i, w, ipar[TAU_ROW, i])
                if ipar[OMEGA_ROW, i] >= 0:
                    om_hat = _row(out_ptr, out_c, out_i, w, ipar[OMEGA_ROW, i])
                    rec[OMEGA_HAT, k, i] = om_hat
                rec[TAU_HAT, k, i] = est
                # the controller's named inputs: r, r_dot, r_ddot, theta, omega, tau_hat, omega_hat
                cwork[C + i] = ref[0, k, i]
                cwork[C + N + i] = ref[1, k, i]
                cwork[C + 2 * N + i] = ref[2, k, i]
                cwork[C + 3 * N + i] = w[S + i]
                cwork[C + 4 * N + i] = w[S + N + i]
                cwork[C + 5 * N + i] = est
                cwork[C + 6 * N + i] = om_hat
                if computed_torque:
                    a = fpar[KP, i] * (ref[0, k, i] - w[S + i])
                    a += fpar[KD, i] * (ref[1, k, i] - w[S + N + i])
                    if fpar[FEEDFORWARD, i] != 0.0:
                        a += ref[2, k, i]
                    acc[i] = a
        if not phases & PHASE_CONTROL:
            return k + 1
        if not computed_torque:
            for j in range(Q):  # the joints' signal rows, in order
                cwork[first_signal + j] = _row(cs_ptr, cs_c, cs_i, cwork, j)
        for i in range(N):
            if computed_torque:
                uk = model[i] + rec[TAU_HAT, k, i]
            else:
                uk = cwork[first_signal + command[i]]
            lim = fpar[LIMIT, i]
            if uk > lim:
                uk = lim
            elif uk < -lim:
                uk = -lim
            rec[U, k, i] = uk
            w[S + 2 * N + i] = uk
            cwork[bar + i] = uk
        for j in range(S):
            s_new[j] = _row(up_ptr, up_c, up_i, w, j)
        for j in range(S):
            s[j] = s_new[j]
        for j in range(C):
            cwork[first_signal + Q + j] = _row(cu_ptr, cu_c, cu_i, cwork, j)
        for j in range(C):
            cwork[j] = cwork[first_signal + Q + j]
        for i in range(N):
            d = ipar[DELAY, i]
            applied[i] = rec[U, k - d, i] if k >= d else 0.0
        if plant_kind == PLANT_PYTHON:
            return k + 1
        # the two-link arm: ground truth just after the command, then RK4 sub-steps
        d = two_link_derivative(
            plant_par, x[0], x[1], x[2], x[3],
            applied[0] - tau_sample[k, 0], applied[1] - tau_sample[k, 1],
        )  # fmt: skip
        rec[TAU_DN, k, 0] = rec[U, k, 0] - fpar[BN, 0] * x[2] - fpar[JN, 0] * d[2]
        rec[TAU_DN, k, 1] = rec[U, k, 1] - fpar[BN, 1] * x[3] - fpar[JN, 1] * d[3]
        two_link_rk4(plant_par, x, applied[0], applied[1],
                     tau_mid[k * substeps : (k + 1) * substeps], h, substeps)  # fmt: skip
        for i in range(2 * N):
            if not abs(x[i]) <= limit:
                return k + 1
    return k_stop
