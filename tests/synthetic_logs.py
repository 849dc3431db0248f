"""Synthetic logs for the identification tests and benchmark (issue 23): made with hpdob's own
``simulate`` and plant models, so the truth is known. Every log here is SYNTHETIC.

Open loop: the torque is applied through a PD with zero gains and feed-forward (the torque is
``J_n r_ddot``, so ``r_ddot = u / J_n``). Closed loop: hpdob's PD tracking a two-sine
reference. Step responses (the most common logs): hpdob's PD answering reference steps of
1 rad every second, one way (a staircase) or both ways, and open-loop torque pulses of 0.1 s
every second that leave the axis to coast to rest, one way or alternating; each rests between
moves. The encoder quantises the position; 1 % (of the input's RMS) white noise is added to
the *logged* input, as a current measurement would carry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import hpdob
from hpdob import PD, Encoder, ServoModel
from hpdob.identification import FeedbackLoop, Log

#: The issue's motor: J [kg m^2], b [N m s/rad].
J_TRUE, B_TRUE = 1.2e-3, 2e-3
#: The open-loop excitations' bandwidth [Hz] (chirp end, PRBS clock 1/(2 B), top multisine line).
EXCITATION_BANDWIDTH = 10.0
#: Torque amplitude [N m] of the open-loop excitations.
TORQUE = 0.1
#: The step-response logs: one move every STEP_PERIOD [s]; torque pulses last PULSE [s].
STEP_PERIOD, PULSE = 1.0, 0.1
#: The kinds of log: open loop, closed-loop tracking, and step responses.
KINDS = ("chirp+prbs", "chirp", "prbs", "multisine", "pd")
STEP_KINDS = ("steps", "steps-down", "steps-both", "pulses", "pulses-one-way")


@dataclass(frozen=True)
class SyntheticLog:
    """A synthetic log and its truth."""

    log: Log
    J: float
    b: float
    coulomb: float
    bandwidth: float  # excitation bandwidth [Hz]
    input_rms: float  # RMS of the applied input [N m]
    loop: FeedbackLoop | None = None  # the logged loop (closed-loop logs)


def _torque(kind: str, t: np.ndarray, rng) -> np.ndarray:
    B, duration = EXCITATION_BANDWIDTH, t[-1] + (t[1] - t[0])
    if kind == "chirp+prbs":
        f0 = 0.2
        chirp = np.sin(2 * np.pi * (f0 * t + (B - f0) * t**2 / (2 * duration)))
        clock = 1.0 / (2 * B)
        bits = rng.choice([-1.0, 1.0], size=math.ceil(duration / clock) + 1)
        prbs = bits[(t / clock).astype(int)]
        return TORQUE * np.where(t < duration / 2, chirp, prbs)
    if kind == "chirp":
        f0 = 0.2
        return TORQUE * np.sin(2 * np.pi * (f0 * t + (B - f0) * t**2 / (2 * duration)))
    if kind == "prbs":
        clock = 1.0 / (2 * B)
        bits = rng.choice([-1.0, 1.0], size=math.ceil(duration / clock) + 1)
        return TORQUE * bits[(t / clock).astype(int)]
    if kind == "multisine":
        f = np.geomspace(0.2, B, 12)
        phase = -np.pi * np.arange(1, f.size + 1) ** 2 / f.size  # Schroeder phases
        u = np.sin(2 * np.pi * f[:, None] * t + phase[:, None]).sum(axis=0)
        return TORQUE * math.sqrt(2) * u / np.sqrt(np.mean(u**2))
    if kind in ("pulses", "pulses-one-way"):
        move = np.floor(t / STEP_PERIOD)
        way = 1.0 if kind == "pulses-one-way" else np.where(move % 2 == 0, 1.0, -1.0)
        return TORQUE * np.where(t - move * STEP_PERIOD < PULSE, way, 0.0)
    raise ValueError(f"unknown excitation {kind!r}")


def synthetic_log(
    *,
    kind: str = "chirp+prbs",
    counts: int = 4096,
    Ts: float = 5e-4,
    coulomb: float | None = 0.03,
    coulomb_fraction: float | None = None,
    duration: float = 20.0,
    input_noise: float = 0.01,
    seed: int = 0,
    J: float = J_TRUE,
    b: float = B_TRUE,
) -> SyntheticLog:
    """One synthetic log. ``kind``: ``"chirp+prbs"``, ``"chirp"``, ``"prbs"``, ``"multisine"``
    (open loop) or ``"pd"`` (closed-loop PD tracking). ``coulomb_fraction`` sets the Coulomb
    friction as a fraction of the input's RMS instead of ``coulomb`` [N m]."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration / Ts)) * Ts
    if kind == "pd":
        omega = 2 * np.pi * 5.0  # closed-loop bandwidth 5 Hz
        controller = PD(omega**2, 2 * omega)
        r = (1.0 - np.cos(np.pi * t)) + 0.3 * (1.0 - np.cos(4 * np.pi * t))
        r_dot = np.pi * np.sin(np.pi * t) + 1.2 * np.pi * np.sin(4 * np.pi * t)
        r_ddot = np.pi**2 * np.cos(np.pi * t) + 4.8 * np.pi**2 * np.cos(4 * np.pi * t)
        bandwidth = 5.0
        rms = J * math.sqrt(np.mean(r_ddot**2))  # the input's RMS without friction
    elif kind in ("steps", "steps-down", "steps-both"):
        omega = 2 * np.pi * 5.0
        controller = PD(omega**2, 2 * omega)
        move = np.floor(t / STEP_PERIOD)
        r = {"steps": move + 1.0, "steps-down": -(move + 1.0)}.get(
            kind, np.where(move % 2 == 0, 1.0, 0.0)
        )
        r_dot, r_ddot = np.zeros_like(t), np.zeros_like(t)
        bandwidth = 5.0
        rms = None  # measured below: the input's RMS
    else:
        controller = PD(0.0, 0.0, feedforward=True)
        u_open = _torque(kind, t, rng)
        r, r_dot, r_ddot = np.zeros_like(t), np.zeros_like(t), u_open / J
        bandwidth = EXCITATION_BANDWIDTH
        rms = math.sqrt(np.mean(u_open**2))
    if rms is None:  # steps: the frictionless run's input RMS
        rms = _steps_rms(controller, r, J, b, counts, Ts)
    if coulomb_fraction is not None:
        coulomb = coulomb_fraction * rms
    coulomb = coulomb or 0.0
    plant = ServoModel(J, b, coulomb=coulomb, coulomb_velocity=1e-3)
    table = {"r": r, "r_dot": r_dot, "r_ddot": r_ddot}

    def reference(times):
        k = np.rint(np.asarray(times) / Ts).astype(int)
        return table["r"][k], table["r_dot"][k], table["r_ddot"][k]

    result = hpdob.simulate(
        plant=plant,
        nominal=ServoModel(J),
        Ts=Ts,
        controller=controller,
        sensor=Encoder(counts),
        reference=reference,
        duration=t.size * Ts,
    )
    u_rms = math.sqrt(np.mean(result.u**2))
    logged = result.u + input_noise * u_rms * rng.standard_normal(result.u.size)
    loop = None
    if kind in ("pd", "steps", "steps-down", "steps-both"):
        loop = FeedbackLoop.from_pd(
            controller, J_n=J, reference=r, reference_velocity=r_dot, reference_acceleration=r_ddot
        )
    log = Log(result.t, result.theta_measured, logged, reference=r, source=f"synthetic-{kind}")
    return SyntheticLog(log, J, b, coulomb, bandwidth, u_rms, loop)


def _steps_rms(controller, r: np.ndarray, J: float, b: float, counts: int, Ts: float) -> float:
    """RMS [N m] of the input of a PD step-response run without Coulomb friction."""
    table = {"r": r, "z": np.zeros_like(r)}

    def reference(times):
        k = np.rint(np.asarray(times) / Ts).astype(int)
        return table["r"][k], table["z"][k], table["z"][k]

    result = hpdob.simulate(
        plant=ServoModel(J, b), nominal=ServoModel(J), Ts=Ts, controller=controller,
        sensor=Encoder(counts), reference=reference, duration=r.size * Ts,
    )  # fmt: skip
    return math.sqrt(np.mean(result.u**2))


def within_targets(fit, s) -> dict:
    """Issue 23's targets, per parameter, for ``fit`` of the synthetic log ``s``: J within
    3 %, b within 10 % or 0.02 J 2 pi B, Coulomb within 5 % or 2 % of the input's RMS."""
    b_allow = max(0.1 * s.b, 0.02 * s.J * 2 * math.pi * s.bandwidth)
    c_allow = max(0.05 * s.coulomb, 0.02 * s.input_rms)
    return {
        "J": abs(fit.J / s.J - 1.0) <= 0.03,
        "b": abs(fit.b - s.b) <= b_allow,
        "coulomb": abs(fit.coulomb - s.coulomb) <= c_allow,
    }
