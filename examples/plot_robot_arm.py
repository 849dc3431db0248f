"""
An observer per joint on a Franka Panda
=======================================

:func:`hpdob.robots.simulate_arm` runs the N-joint loop: every joint of the arm is the paper's
single-axis servo with its own nominal inertia (here the diagonal of the mass matrix at the
start pose), its own PD and its own disturbance observer; gravity, the coupling to the other
joints and a 1 kg payload nobody told the controller about are each joint's disturbance. The
plant is the shipped Franka Panda model (:func:`hpdob.robots.panda`) simulated by MuJoCo, with
an 18-bit encoder and Franka's torque limits on every joint; every joint swings 0.5 rad at
1.4 Hz (2.2 rad/s peak). The DOb at 100 rad/s and the HPDOb at 49 rad/s have the same encoder
noise in their estimates (``benchmarks/bench_robots.py`` finds the 49 by bisection on
:func:`hpdob.observer_noise_gain`).
"""

import matplotlib.pyplot as plt
import numpy as np

from hpdob import PD, Actuator, Encoder
from hpdob.robots import (
    PANDA_READY,
    PANDA_TORQUE_LIMITS,
    ArmLoop,
    ComputedTorque,
    JointSines,
    momentum_observer,
    panda,
    simulate_arm,
)

q0 = np.array(PANDA_READY)
reference = JointSines(center=q0, amplitude=0.5, frequency=1.4)
nominal = panda()  # what the controllers know: no payload
loop = ArmLoop(
    panda(payload=1.0),
    1e-3,
    PD(400.0, 40.0),
    nominal=nominal,
    q0=q0,
    actuator=[Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS],
    sensor=Encoder(2**18),
)
runs = {
    "PD + DOb 100": loop.replace(observers={"order": 0, "bandwidth": 100.0}),
    "PD + HPDOb 49": loop.replace(observers={"order": 1, "bandwidth": 49.0}),
    "computed torque": loop.replace(controller=ComputedTorque(nominal, 400.0, 40.0)),
}
results = {
    name: simulate_arm(run, duration=3.0, reference=reference, tau0="gravity", label=name)
    for name, run in runs.items()
}

fig, ax = plt.subplots(figsize=(7.0, 3.2), layout="constrained")
joints = np.arange(1, 8)
for i, (name, result) in enumerate(results.items()):
    rms = 1e3 * np.array(result.metrics(start=1.0)["rms_position_error"])
    ax.bar(joints + (i - 1) * 0.27, rms, width=0.27, label=name)
ax.set_xlabel("joint")
ax.set_ylabel("RMS tracking error, t >= 1 s [mrad]")
ax.set_yscale("log")
ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
ax.set_title("Panda, fast trajectory, unknown 1 kg payload")

# %%
# The HPDOb's traces: position error, torque and each joint's estimate against the ground
# truth of eq. (3) per joint, ``tau_dn,i = u_i - J_n,i qdd_i``.

results["PD + HPDOb 49"].plot()

# %%
# External force: a 10 N push along x at the flange from 1 s while the arm holds its pose;
# the momentum observer (``K_o = 50`` 1/s) on the nominal model estimates ``J^T F`` and, through
# the damped pseudo-inverse of the Jacobian, the force. Here the nominal model is exact and
# the sensor ideal: the estimate settles on 10 N within 5 / K_o = 0.1 s.


def push(t):
    return np.where(np.asarray(t)[:, None] >= 1.0, [10.0, 0.0, 0.0], 0.0)


def hold(t):
    return np.tile(q0, (len(t), 1)), np.zeros((len(t), 7)), np.zeros((len(t), 7))


rest = simulate_arm(
    loop.replace(plant=nominal, sensor=None, observers={"order": 0, "bandwidth": 100.0}),
    duration=1.5,
    reference=hold,
    external=push,
    tau0="gravity",
)
estimate = momentum_observer(nominal, rest, gain=50.0)
fig, ax = plt.subplots(figsize=(7.0, 3.0), layout="constrained")
for axis, name in enumerate("xyz"):
    ax.plot(rest.t, rest.force[:, axis], color=f"C{axis}", linewidth=2.5, alpha=0.4,
            label=f"applied F_{name}")  # fmt: skip
    ax.plot(rest.t, estimate.force[:, axis], color=f"C{axis}", label=f"estimated F_{name}")
ax.set_xlabel("time [s]")
ax.set_ylabel("force at the flange [N]")
ax.set_xlim(0.8, 1.5)
ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
plt.show()
