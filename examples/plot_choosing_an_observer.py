"""
Choosing an observer: order and bandwidth
=========================================

A higher truncation order ``m`` cancels disturbances whose samples are polynomials of degree
``m``: at low frequency the estimation error ``|1 - Q|`` falls with ``m + 1`` powers of the
frequency instead of one. The price is noise: at the same bandwidth a higher order passes
more measurement noise into the estimate. The fair comparison is therefore at equal noise.
"""

import matplotlib.pyplot as plt
import numpy as np

from hpdob import ServoModel, design_observer, estimation_response, noise_tradeoff

Ts = 1e-3  # sampling period [s]
nominal = ServoModel(J=2.8e-4)
model = nominal.discretize(Ts)
f = np.geomspace(0.1, 0.5 / Ts, 400)  # frequency [Hz], up to Nyquist

fig, ax = plt.subplots(figsize=(7.0, 3.8), layout="constrained")
for m, name in enumerate(["DOb (m=0)", "HPDOb (m=1)", "order m=2", "order m=3"]):
    design = design_observer(model, order=m, bandwidth=100.0)
    error = estimation_response(design, f, error=True)
    ax.semilogx(f, 20 * np.log10(np.abs(error)), label=name)
ax.axvline(2.0, color="0.5", linestyle=":", linewidth=1.0)
ax.set_xlabel("disturbance frequency [Hz]")
ax.set_ylabel(r"$|1-Q|$ (estimation error) [dB]")
ax.grid(True, linewidth=0.4, alpha=0.5)
ax.margins(x=0)
ax.legend(loc="lower right", fontsize="small")
ax.set_title("Estimation error at 100 rad/s (closed form)", fontsize="medium")

# %%
# At equal noise gain (the RMS of the estimate per unit velocity noise) the orders compare
# fairly: each curve runs over the bandwidths, the labels are bandwidths [rad/s]. Below about
# 25 rad/s the DOb is as good as any; above it, the HPDOb and higher orders win by orders of
# magnitude at 2 Hz.

tradeoff = noise_tradeoff(
    nominal=nominal, Ts=Ts, frequency=2.0, bandwidths=np.geomspace(12.5, 3200.0, 65)
)
tradeoff.plot()
j = int(np.argmin(np.abs(tradeoff.bandwidths - 100.0)))
print(
    f"at the noise of a {tradeoff.bandwidths[j]:.0f} rad/s DOb, the HPDOb's error at 2 Hz is "
    f"{tradeoff.improvement(1)[j]:.2f} times smaller"
)
plt.show()
