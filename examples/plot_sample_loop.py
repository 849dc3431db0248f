"""
The sample loop by hand
=======================

An HPDOb (order 1) designed for the paper's nominal motor runs sample by sample against the
exact zero-order-hold model of that motor, with a load torque of a step plus a sine. At every
sample: ``estimate`` from the measured state, the PD law with the compensation, then
``update`` with the torque applied. This is the README's quick start, with its signals kept
for the figure.
"""

import matplotlib.pyplot as plt
import numpy as np

from hpdob import DisturbanceObserver, ServoModel

Ts = 1e-3  # sampling period [s]
J_n = 2.8e-4  # nominal inertia [kg m^2]
nominal = ServoModel(J=J_n).discretize(Ts)  # exact ZOH of the nominal servo
obs = DisturbanceObserver(nominal, order=1, bandwidth=100.0)  # HPDOb, poles at exp(-100 Ts)

n = 3000
t = np.arange(n) * Ts
tau = 0.05 + 0.02 * np.sin(4 * np.pi * t)  # load torque on the motor [N m]
tau_hat, theta = np.zeros(n), np.zeros(n)
x = np.zeros(2)  # [theta (rad), omega (rad/s)]
for k in range(n):
    tau_hat[k] = obs.estimate(x)  # 1. estimate from the measured x_k
    u = -J_n * (50 * x[0] + 5 * x[1]) + tau_hat[k]  # 2. PD + disturbance compensation
    obs.update(x, u)  # 3. feed back the torque applied
    theta[k] = x[0]
    x = nominal.step(x, u, tau[k])  # the plant over one sample

# %%
# The estimate follows the load after a transient of a few times ``1/g = 10 ms``; the
# position error that remains is the compensation's residual.

fig, (a, b) = plt.subplots(2, 1, figsize=(7.0, 4.8), sharex=True, layout="constrained")
a.plot(t, tau, "k", linewidth=1.0, label=r"load torque $\tau$")
a.plot(t, tau_hat, color="tab:blue", linewidth=1.0, label=r"estimate $\hat\tau$ (HPDOb)")
a.set_ylabel("torque [N m]")
a.legend(loc="lower right", fontsize="small")
b.plot(t, theta, color="tab:blue", linewidth=1.0)
b.set_ylabel(r"position $\theta$ [rad]")
b.set_xlabel("time [s]")
for ax in (a, b):
    ax.grid(True, linewidth=0.4, alpha=0.5)
    ax.margins(x=0)
fig.suptitle("The sample loop: estimate, control, update", fontsize="medium")
plt.show()
