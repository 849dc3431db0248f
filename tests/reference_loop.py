"""An independent, straightforward closed-loop simulator for cross-checking ``hpdob.simulate``.

Plain Python floats, the runtime ``DisturbanceObserver`` object and the sample loop written out
step by step (measure, estimate, control, limit, update, delay, integrate). It shares only the
ZOH matrices (``ServoModel.discretize``, tested on its own) and the integration *scheme*
(exponential midpoint on sub-steps), not a line of the kernel.
"""

from __future__ import annotations

import math

import numpy as np

from hpdob.signals import Signal, trajectory


def reference_loop(
    *,
    plant,
    nominal,
    Ts,
    duration,
    controller,
    observer=None,
    reference,
    disturbance=None,
    substeps,
    sensor=None,
    actuator=None,
):
    n, S = round(duration / Ts), substeps
    h = Ts / S
    full, half = plant.discretize(h), plant.discretize(h / 2)
    (a00, a01), (a10, a11) = full.A.tolist()
    b0, b1 = full.B.tolist()
    (_, _), (c10, c11) = half.A.tolist()
    _, d1 = half.B.tolist()
    if isinstance(reference, Signal):
        reference = trajectory(reference)
    obs = observer.copy() if observer is not None else None
    friction = plant.coulomb
    vel = plant.coulomb_velocity
    tau_ext = disturbance if disturbance is not None else (lambda t: np.zeros_like(t))
    limit = math.inf if actuator is None or actuator.torque_limit is None else actuator.torque_limit
    delay = 0 if actuator is None else actuator.delay_samples
    noise = np.zeros(n)
    if sensor is not None and sensor.noise_std > 0:
        noise = sensor.noise_std * np.random.default_rng(sensor.seed or 0).standard_normal(n)
    th, om, prev = 0.0, 0.0, None
    commands, rows = [], []
    for k in range(n):
        t = k * Ts
        r, rd, rdd = (float(v[0]) for v in reference(np.array([t])))
        if sensor is None:
            thm, omm = th, om
        else:
            q = sensor.resolution
            thm = q * math.floor((th + noise[k]) / q + 0.5)
            omm = om if sensor.velocity == "exact" else 0.0 if prev is None else (thm - prev) / Ts
            prev = thm
        measured = (thm, omm) if obs is None or len(obs.measures) == 2 else thm
        tau_hat = obs.estimate(measured) if obs is not None else 0.0
        om_ctl = obs.velocity if controller.velocity == "observer" else omm
        u = controller.torque(
            J_n=nominal.J, r=r, r_dot=rd, r_ddot=rdd, theta=thm, omega=om_ctl, tau_hat=tau_hat
        )
        u = min(max(u, -limit), limit)
        if obs is not None:
            obs.update(measured, u)
        commands.append(u)
        applied = commands[k - delay] if k >= delay else 0.0
        d_now = float(tau_ext(np.array([t]))[0])
        accel = (applied - plant.b * om - friction * math.tanh(om / vel) - d_now) / plant.J
        rows.append((t, th, om, u, tau_hat, u - nominal.b * om - nominal.J * accel, d_now))
        mids = tau_ext(t + (np.arange(S) + 0.5) * h)
        for j in range(S):
            f = applied - friction * math.tanh(om / vel) - mids[j]
            om_half = c10 * th + c11 * om + d1 * f
            f = applied - friction * math.tanh(om_half / vel) - mids[j]
            th, om = a00 * th + a01 * om + b0 * f, a10 * th + a11 * om + b1 * f
    names = ("t", "theta", "omega", "u", "tau_hat", "tau_dn", "tau_ext")
    return dict(zip(names, np.array(rows).T, strict=True))
