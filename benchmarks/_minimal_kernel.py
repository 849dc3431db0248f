"""A minimal hand-written numba kernel of one canonical sweep scenario (benchmarks only).

The reference of ``bench_sweep.py``: the canonical loop (rigid plant with viscous and Coulomb
friction, ideal sensor and actuator, PD with feed-forward, an observer of the canonical family)
written out by hand as one plain loop, with the scenario's row computed inline: the RMS
estimation error over the run, the RMS position errors in the two windows and the largest
position error. It reads the reference and the disturbance from arrays sampled once per time
grid, as ``hpdob.sweep`` shares them; the observer as its dense matrices ``F, G, H, E``; the
plant's zero-order-hold matrices over ``h`` and ``h/2`` from ``scipy.linalg.expm`` (not from
hpdob). It does the same arithmetic as hpdob's kernel in a different order, so its rows agree
with hpdob's to rounding, not bit for bit: ``check`` compares them first.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy.linalg import expm

__all__ = ["check", "minimal_row", "sampled", "scenario_inputs"]


@numba.njit(cache=True, nogil=True)
def minimal_row(n, S, Ts, Ah, Bh, Aq, Bq, b, J, c, v, F, G, H, E, J_n, kp, kd,
                r, r_dot, r_ddot, tau_sample, tau_mid, windows):  # fmt: skip
    """The scenario's row ``(rms_estimation_error, rms regulation, rms tracking, max |e|)``.

    ``Ah, Bh`` (``Aq, Bq``): the plant's ZOH matrices over ``h = Ts/S`` (``h/2``); ``F, G,
    H, E``: the observer (``s' = F s + G [theta, omega, u]``, ``tau_hat = H s + E [...]``);
    ``windows``: ``[start, stop)`` of the regulation and tracking windows [s].
    """
    m = F.shape[0]
    s = np.zeros(m)
    s_new = np.zeros(m)
    th, om = 0.0, 0.0
    sum_est, sum_reg, sum_trk, n_reg, n_trk, peak = 0.0, 0.0, 0.0, 0, 0, 0.0
    for k in range(n):
        tk = k * Ts
        est = E[0, 0] * th + E[0, 1] * om
        for i in range(m):
            est += H[0, i] * s[i]
        u = J_n * (kp * (r[k] - th) + kd * (r_dot[k] - om) + r_ddot[k]) + est
        for i in range(m):
            acc = G[i, 0] * th + G[i, 1] * om + G[i, 2] * u
            for j in range(m):
                acc += F[i, j] * s[j]
            s_new[i] = acc
        for i in range(m):
            s[i] = s_new[i]
        accel = (u - b * om - c * math.tanh(om / v) - tau_sample[k]) / J
        tau_dn = u - J_n * accel  # b_n = 0
        e = est - tau_dn
        sum_est += e * e
        pe = th - r[k]
        if abs(pe) > peak:
            peak = abs(pe)
        if windows[0] <= tk < windows[1]:
            sum_reg += pe * pe
            n_reg += 1
        if windows[2] <= tk < windows[3]:
            sum_trk += pe * pe
            n_trk += 1
        for j in range(S):
            tau = tau_mid[k * S + j]
            force = u - c * math.tanh(om / v) - tau
            om_half = Aq[1, 0] * th + Aq[1, 1] * om + Bq[1] * force
            force = u - c * math.tanh(om_half / v) - tau
            th, om = (
                Ah[0, 0] * th + Ah[0, 1] * om + Bh[0] * force,
                (Ah[1, 0] * th + Ah[1, 1] * om + Bh[1] * force),
            )
    nan = math.nan
    return (
        math.sqrt(sum_est / n),
        math.sqrt(sum_reg / n_reg) if n_reg else nan,
        math.sqrt(sum_trk / n_trk) if n_trk else nan,
        peak,
    )


def _zoh(J: float, b: float, h: float):
    """ZOH matrices of ``J theta'' = u - b omega`` over ``h`` by the augmented exponential."""
    M = np.zeros((3, 3))
    M[0, 1], M[1, 1], M[1, 2] = 1.0, -b / J, 1.0 / J
    E = expm(M * h)
    return np.ascontiguousarray(E[:2, :2]), np.ascontiguousarray(E[:2, 2])


def sampled(reference, disturbance, *, Ts: float, n: int, S: int) -> dict:
    """The reference ``(r, r_dot, r_ddot)`` at ``k Ts`` and the disturbance there and at the
    sub-step midpoints ``k Ts + (j + 1/2) Ts/S`` (what ``hpdob.simulate`` documents)."""
    from hpdob.signals import trajectory

    t = np.arange(n) * Ts
    r, r_dot, r_ddot = (np.asarray(x, dtype=float) for x in trajectory(reference)(t))
    t_mid = (t[:, None] + (np.arange(S) + 0.5) * (Ts / S)).ravel()
    return {"Ts": Ts, "S": S, "n": n, "r": r, "r_dot": r_dot, "r_ddot": r_ddot,
            "tau_sample": disturbance(t), "tau_mid": disturbance(t_mid)}  # fmt: skip


def scenario_inputs(loop, signals: dict, windows: dict) -> tuple:
    """The arguments of :func:`minimal_row` for ``loop`` (an hpdob ``ServoLoop`` of the
    canonical family) on ``signals`` (:func:`sampled`)."""
    plant, system, pd = loop.plant, loop.system, loop.controller
    Ts, S = signals["Ts"], signals["S"]
    h = Ts / S
    Ah, Bh = _zoh(plant.J, plant.b, h)
    Aq, Bq = _zoh(plant.J, plant.b, h / 2)
    win = np.array([*windows["regulation"], *windows["tracking"]])
    return (signals["n"], S, Ts, Ah, Bh, Aq, Bq, plant.b, plant.J, plant.coulomb,
            plant.coulomb_velocity, system.F, system.G, system.H, system.E, loop.nominal.J,
            pd.kp, pd.kd, signals["r"], signals["r_dot"], signals["r_ddot"],
            signals["tau_sample"], signals["tau_mid"], win)  # fmt: skip


def check(rows, inputs, *, rtol: float = 1e-6) -> float:
    """The largest relative difference between hpdob's rows and the minimal kernel's on the
    same scenarios; raises if above ``rtol`` (a wrong reference would be worthless)."""
    columns = ("rms_estimation_error", "rms_position_error_regulation",
               "rms_position_error_tracking", "max_abs_position_error")  # fmt: skip
    worst = 0.0
    for (_, row), args in zip(rows.iterrows(), inputs, strict=True):
        mine = minimal_row(*args)
        for name, value in zip(columns, mine, strict=True):
            theirs = float(row[name])
            if math.isnan(theirs) and math.isnan(value):
                continue
            worst = max(worst, abs(value - theirs) / max(abs(theirs), 1e-300))
    if not worst <= rtol:
        raise AssertionError(f"the minimal kernel differs from hpdob by {worst:.3g} (relative)")
    return worst
