r"""Simulation of a rigid axis with Coulomb friction in a sampled position loop.

Written in the subset of Python that numba compiles (:func:`loop_kernel` compiles it lazily,
with the machine code cached on disk); :func:`run_loop` also runs as plain Python, which the
tests use as a cross-check.

Plant (EMPS description, eq. 3, with stiction):

.. math:: J\dot v = F - b v - c\,\mathrm{sign}(v),\qquad F = u - \mathrm{offset},

where at :math:`v = 0` the axis sticks while :math:`|F| \le c`. With ``F`` held over each
sample (zero-order hold) and the sign fixed, the solution is exact: with :math:`a = b/J`,
:math:`G = (F - c\,s)/J`,

.. math::

    v(t) = v_0 e^{-a t} + G\,\varphi_1(t),\qquad
    q(t) = q_0 + v_0\,\varphi_1(t) + G\,\varphi_2(t),

:math:`\varphi_1 = (1 - e^{-a t})/a`, :math:`\varphi_2 = (t - \varphi_1)/a`. When the friction
decelerates the axis to rest inside a sample (at :math:`t_c = \ln(1 - a v_0/G)/a`) the
sample is split there and the stick condition is checked for the rest of it.

Per sample ``k``: the position ``y_k = q(t_k)`` is measured (no quantisation), the velocity
estimate is ``sum_i c_i y_{k-i} / Ts`` (positions before the start equal ``y_0``) or the
exact velocity, the command is
``u_k = kp (r_k - y_k) + kd (rdot_k - v_k) + ff_k`` clipped to ``+-limit``, and the plant is
advanced over ``[t_k, t_{k+1})``. With a controller program (``signal_rows`` not empty: a
:class:`hpdob.controllers.LinearController`'s :meth:`~hpdob.controllers.ControllerProgram.arrays`)
the command is instead its last signal plus ``ff_k``, the signal rows evaluated in order from
its state and its inputs ``[r, r_dot, r_ddot, y, v, 0]`` (``source`` picks them; the last is
``tau_hat``, 0 without an observer), and after the clip its state is updated with the clipped
command: the rows summed left to right, as :func:`hpdob.simulate`'s kernel and exported C do.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np

__all__ = ["loop_kernel", "run_loop"]


def run_loop(
    J,
    b,
    coulomb,
    offset,
    Ts,
    q0,
    v0,
    r,
    r_dot,
    feedforward,
    kp,
    kd,
    velocity_filter,
    exact_velocity,
    limit,
    divergence_limit,
    q_out,
    u_out,
    r_ddot,
    state,
    source,
    signal_rows,
    update_rows,
):
    """Simulate ``q_out.size`` samples; fill ``q_out`` and ``u_out``; return the samples
    completed.

    ``r``, ``r_dot``, ``feedforward``, ``r_ddot`` and ``u_out`` hold one value per sample, or a
    single one: a constant input (0 for one the loop lacks, without an array of zeros of the
    log's length) or, for ``u_out``, a command not recorded. A return value below
    ``q_out.size`` means ``|q|`` or ``|v|`` left ``divergence_limit`` (or
    became non-finite) at the end of the last completed sample. ``state`` (the controller's
    initial state, updated in place), ``source`` and the ``(pointer, coefficient, operand)``
    rows are those of a controller program; no signal rows (``pointer == [0]``): the PD law.
    """
    n = q_out.shape[0]
    # the stride of each per-sample array: 1, or 0 for an array of a single value
    sr = 1 if r.shape[0] == n else 0
    srd = 1 if r_dot.shape[0] == n else 0
    sff = 1 if feedforward.shape[0] == n else 0
    srdd = 1 if r_ddot.shape[0] == n else 0
    su = 1 if u_out.shape[0] == n else 0
    m = velocity_filter.shape[0]
    history = np.empty(m)
    for i in range(m):
        history[i] = q0
    q = q0
    v = v0
    a = b / J
    sig_ptr, sig_c, sig_i = signal_rows
    up_ptr, up_c, up_i = update_rows
    nc, pc, qc = state.shape[0], source.shape[0], sig_ptr.shape[0] - 1
    programmed = qc > 0
    first = nc + pc + 1  # operands [c, v, u_bar, signals]
    operands = np.zeros(first + qc)
    inputs = np.zeros(6)
    new_state = np.empty(nc)
    for k in range(n):
        y = q
        for i in range(m - 1, 0, -1):
            history[i] = history[i - 1]
        history[0] = y
        if exact_velocity:
            velocity = v
        else:
            velocity = 0.0
            for i in range(m):
                velocity += velocity_filter[i] * history[i]
            velocity /= Ts
        if programmed:
            inputs[0] = r[k * sr]
            inputs[1] = r_dot[k * srd]
            inputs[2] = r_ddot[k * srdd]
            inputs[3] = y
            inputs[4] = velocity
            for i in range(nc):
                operands[i] = state[i]
            for j in range(pc):
                operands[nc + j] = inputs[source[j]]
            for j in range(qc):  # a row: its terms summed left to right (0 if empty)
                acc = 0.0
                for t in range(sig_ptr[j], sig_ptr[j + 1]):
                    term = sig_c[t] * operands[sig_i[t]]
                    acc = term if t == sig_ptr[j] else acc + term
                operands[first + j] = acc
            uk = operands[first + qc - 1] + feedforward[k * sff]
        else:
            uk = kp * (r[k * sr] - y) + kd * (r_dot[k * srd] - velocity) + feedforward[k * sff]
        if uk > limit:
            uk = limit
        elif uk < -limit:
            uk = -limit
        if programmed and nc > 0:
            operands[nc + pc] = uk
            for i in range(nc):
                acc = 0.0
                for t in range(up_ptr[i], up_ptr[i + 1]):
                    term = up_c[t] * operands[up_i[t]]
                    acc = term if t == up_ptr[i] else acc + term
                new_state[i] = acc
            for i in range(nc):
                state[i] = new_state[i]
        q_out[k] = y
        u_out[k * su] = uk
        force = uk - offset
        h = Ts
        for _segment in range(2):  # at most: slide to rest, then the rest of the sample
            if v == 0.0:
                if abs(force) <= coulomb:
                    break  # sticks for the rest of the sample
                s = 1.0 if force > 0.0 else -1.0
            else:
                s = 1.0 if v > 0.0 else -1.0
            G = (force - coulomb * s) / J
            step = h
            stops = False
            if v != 0.0 and G * s < 0.0:
                # decelerating: time to rest
                t_rest = math.log1p(-a * v / G) / a if a > 0.0 else -v / G
                if t_rest < h:
                    step = t_rest
                    stops = True
            if a > 0.0:
                x = a * step
                phi1 = -math.expm1(-x) / a
                if x < 1e-4:
                    phi2 = step * step * (0.5 - x / 6.0 + x * x / 24.0)
                else:
                    phi2 = (step - phi1) / a
                decay = math.exp(-x)
            else:
                phi1 = step
                phi2 = 0.5 * step * step
                decay = 1.0
            q = q + v * phi1 + G * phi2
            if stops:
                v = 0.0
                h -= step
            else:
                v = v * decay + G * phi1
                break
        if not (abs(q) <= divergence_limit and abs(v) <= divergence_limit):
            return k + 1
    return n


@functools.cache
def loop_kernel():
    """:func:`run_loop` compiled with numba (plain Python if numba is missing)."""
    try:
        import numba
    except ImportError:  # pragma: no cover - numba is a core dependency
        warnings.warn(
            "numba is not installed: the IDIM-IV loop simulation runs as plain Python, "
            "about 50x slower; install numba to fix this",
            RuntimeWarning,
            stacklevel=3,
        )
        return run_loop
    return numba.njit(cache=True, nogil=True)(run_loop)
