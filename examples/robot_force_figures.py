"""
External force on a Franka Panda: the estimators against the applied force (a command-line script)
====================================================================================================

Two figures of docs/robots.md, from the set-up of ``benchmarks/bench_robots.py``: the shipped
Panda model (MuJoCo) at 1 kHz, PD ``k_p = 400 1/s^2``, ``k_d = 40 1/s`` on the diagonal of
``M(q0)`` at the ready pose, Franka's torque limits, the nominal model exact. The estimators:
De Luca's momentum observer (``K_o = 50 1/s``) and the per-joint observers' external-torque
estimates (the DOb at 100 rad/s and the HPDOb at 49 rad/s, its equal-noise bandwidth), each
mapped to the flange force through the damped pseudo-inverse of the Jacobian::

    python examples/robot_force_figures.py [OUT_DIR]

writes (100 dpi) into OUT_DIR (default docs/figures), in about ten seconds:

- ``robot_external_force.png``: a 10 N step along x at the flange from 0.5 s, the robot at
  rest, ideal sensing; each estimate of ``F_x`` over the applied step, and the error
  ``|F_hat - F|`` against the 2 % band (0.2 N) and ``5/K_o``;
- ``robot_false_force.png``: no contact, the fast trajectory (every joint 0.5 rad at 1.4 Hz),
  ideal sensing and an 18-bit encoder: the "force" each estimator reads, ``|F_hat|``.

The figures as committed in ``docs/figures/`` (this page does not run the script):

.. image:: ../figures/robot_external_force.png
   :alt: Momentum observer and per-joint observers' estimates of a 10 N step at the Panda's flange

.. image:: ../figures/robot_false_force.png
   :alt: False force read by each estimator with no contact during the fast trajectory
"""

# sphinx_gallery_thumbnail_path = 'figures/robot_external_force.png'

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hpdob import PD, Actuator, Encoder
from hpdob.robots import (
    PANDA_READY,
    PANDA_TORQUE_LIMITS,
    ArmLoop,
    JointSines,
    joint_observer_external,
    momentum_observer,
    panda,
    simulate_arm,
)

TS = 1e-3
Q0 = np.array(PANDA_READY)
K_O = 50.0
F = np.array([10.0, 0.0, 0.0])
T_STEP = 0.5
OBSERVERS = {"DOb 100 rad/s": {"order": 0, "bandwidth": 100.0},
             "HPDOb 49 rad/s": {"order": 1, "bandwidth": 49.0}}  # fmt: skip
STYLE = {
    "momentum observer": {"color": "C3", "linestyle": "-"},
    "per-joint DOb 100 rad/s": {"color": "C0", "linestyle": "--"},
    "per-joint HPDOb 49 rad/s": {"color": "C2", "linestyle": "-."},
}


def hold(t):
    return np.tile(Q0, (len(t), 1)), np.zeros((len(t), 7)), np.zeros((len(t), 7))


def step(t):
    return np.where(np.asarray(t)[:, None] >= T_STEP, F, 0.0)


def estimates(reference, *, external=None, sensor=None, duration):
    """{estimator: (t, force estimate (K, 3))} of one run per per-joint observer (the momentum
    observer from the DOb's run; it does not depend on the observers' estimates)."""
    arm = panda()
    limits = [Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS]
    out = {}
    for name, spec in OBSERVERS.items():
        loop = ArmLoop(arm, TS, PD(400.0, 40.0), observers=spec, q0=Q0, actuator=limits,
                       sensor=sensor)  # fmt: skip
        res = simulate_arm(loop, duration=duration, reference=reference, external=external,
                           tau0="gravity")  # fmt: skip
        if not out:
            out["momentum observer"] = (res.t, momentum_observer(arm, res, gain=K_O).force)
        out[f"per-joint {name}"] = (res.t, joint_observer_external(res, arm, loop=loop).force)
    return out


def external_force_figure():
    runs = estimates(hold, external=step, duration=1.0)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8.5, 5.4), sharex=True,
                                      layout="constrained")  # fmt: skip
    t = next(iter(runs.values()))[0]
    top.plot(t, step(t)[:, 0], color="0.6", linewidth=4.0, alpha=0.6,
             label="applied F_x (MuJoCo xfrc_applied)")  # fmt: skip
    for name, (t, force) in runs.items():
        top.plot(t, force[:, 0], linewidth=1.2, label=name, **STYLE[name])
        error = np.linalg.norm(force - step(t), axis=1)
        late = t >= T_STEP
        bottom.semilogy(t[late], np.maximum(error[late], 1e-6), linewidth=1.2, label=name,
                        **STYLE[name])  # fmt: skip
    bottom.axhline(0.02 * np.linalg.norm(F), color="k", linewidth=0.8, linestyle=":",
                   label="2 % of |F| (0.2 N)")  # fmt: skip
    bottom.axvline(T_STEP + 5.0 / K_O, color="0.4", linewidth=0.8, label="step + 5/K_o")
    top.set_ylabel("force at the flange F_x [N]")
    bottom.set_ylabel("error |F_hat - F| [N]")
    bottom.set_xlabel("time [s]")
    bottom.set_ylim(1e-5, 20.0)
    top.set_xlim(0.4, 1.0)
    for ax in (top, bottom):
        ax.grid(True, linewidth=0.4, alpha=0.5)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    fig.suptitle("Panda at rest, a 10 N step along x at the flange (ideal sensing, exact model)")
    return fig


def false_force_figure():
    reference = JointSines(center=Q0, amplitude=0.5, frequency=1.4)
    sensors = {"ideal sensing": None, "18-bit encoder": Encoder(2**18)}
    fig, axes = plt.subplots(2, 1, figsize=(8.5, 5.4), sharex=True, layout="constrained")
    window = np.ones(50) / 50  # 50 ms
    for ax, (label, sensor) in zip(axes, sensors.items(), strict=True):
        for name, (t, force) in estimates(reference, sensor=sensor, duration=2.0).items():
            late = t >= 0.5
            magnitude = np.linalg.norm(force[late], axis=1)
            rms = np.sqrt(np.mean(magnitude**2))
            text = f"{name} (RMS {rms:.2g} N)"
            if sensor is None:
                ax.semilogy(t[late], np.maximum(magnitude, 1e-4), linewidth=1.0, label=text,
                            **STYLE[name])  # fmt: skip
                continue
            # noise-dominated: the samples thin and light, their 50 ms moving RMS on top
            ax.semilogy(t[late], magnitude, linewidth=0.4, alpha=0.25, color=STYLE[name]["color"])
            moving = np.sqrt(np.convolve(magnitude**2, window, mode="same"))
            ax.semilogy(t[late][25:-25], moving[25:-25], linewidth=1.6,
                        label=f"{text}, 50 ms moving RMS", **STYLE[name])  # fmt: skip
        ax.set_ylabel(f"{label}\n|F_hat| [N]")
        ax.set_ylim(*((1e-4, 10.0) if sensor is None else (0.05, 100.0)))
        ax.grid(True, linewidth=0.4, alpha=0.5)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    axes[-1].set_xlabel("time [s]")
    axes[0].set_xlim(0.5, 2.0)
    fig.suptitle("No contact: the false force during the fast trajectory (exact model)")
    return fig


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for name, make in (("robot_external_force", external_force_figure),
                       ("robot_false_force", false_force_figure)):  # fmt: skip
        fig = make()
        path = out / f"{name}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        print(f"wrote {path}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parents[1] / "docs/figures")
