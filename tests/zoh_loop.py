"""A straightforward closed loop for checking controllers: a frictionless rigid plant advanced
by its exact ZOH recurrence over whole samples, an ideal sensor, the torque limit, and a
controller given as a plain Python step function written in the test from its equations.

Shares nothing with the kernel but ``ServoModel.discretize`` (tested on its own).
"""

from __future__ import annotations

import math

import numpy as np


def zoh_loop(plant, Ts, n, reference, step, *, disturbance=None, limit=None, x0=(0.0, 0.0)):
    """Run ``n`` samples. ``step(k, r, r_dot, r_ddot, theta, omega) -> (u, commit)``: ``u`` the
    unlimited command, ``commit(u_bar)`` advances the controller with the limited one.

    Returns ``(theta, omega, u)`` arrays (``u`` the limited command)."""
    model = plant.discretize(Ts)
    (a00, a01), (a10, a11) = model.A.tolist()
    b0, b1 = model.B.tolist()
    d0, d1 = model.D.tolist()
    t = np.arange(n) * Ts
    r, rd, rdd = reference(t)
    tau = np.zeros(n) if disturbance is None else disturbance(t + Ts / 2)
    lim = math.inf if limit is None else limit
    th, om = x0
    out = np.zeros((3, n))
    for k in range(n):
        u, commit = step(k, float(r[k]), float(rd[k]), float(rdd[k]), th, om)
        ub = min(max(u, -lim), lim)
        commit(ub)
        out[:, k] = th, om, ub
        th, om = (a00 * th + a01 * om + b0 * ub - d0 * tau[k],
                  a10 * th + a11 * om + b1 * ub - d1 * tau[k])  # fmt: skip
    return out[0], out[1], out[2]


def reference_step(t):
    """A smooth 1 rad step over 0.1-0.3 s (quintic), with its derivatives."""
    s = np.clip((t - 0.1) / 0.2, 0.0, 1.0)
    inside = (t > 0.1) & (t < 0.3)
    r = 10 * s**3 - 15 * s**4 + 6 * s**5
    rd = np.where(inside, (30 * s**2 - 60 * s**3 + 30 * s**4) / 0.2, 0.0)
    rdd = np.where(inside, (60 * s - 180 * s**2 + 120 * s**3) / 0.04, 0.0)
    return r, rd, rdd
