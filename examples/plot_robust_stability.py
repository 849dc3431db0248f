"""
Robust stability over an inertia error
======================================

How far may the true inertia ``J`` be from the nominal ``J_n`` before the loop with an
observer goes unstable? :func:`hpdob.robust_stability_map` computes the closed loop's
spectral radius over a grid of ``J / J_n`` and observer bandwidths; the black line is its
stability boundary. The star marks a design you pass to ``plot(mark=...)``: here an HPDOb at
150 rad/s on a motor whose true inertia is 20 % above the nominal one.
"""

import matplotlib.pyplot as plt
import numpy as np

from hpdob import PD, ServoModel, robust_stability_map

nominal = ServoModel(J=2.8e-4)
common = {"nominal": nominal, "Ts": 1e-3, "controller": PD(50.0, 5.0), "order": 1}
wide = robust_stability_map(
    J_ratio=np.geomspace(0.1, 10.0, 41), bandwidth=np.geomspace(10.0, 2000.0, 41), **common
)
wide.plot(mark=(150.0, 1.2))

# %%
# A narrow grid, ``J / J_n`` within +-30 %, at a one-sample actuator delay the observer does
# not know: the loop loses its margin above a few hundred rad/s.

narrow = robust_stability_map(
    J_ratio=np.geomspace(0.7, 1.3, 31),
    bandwidth=np.geomspace(50.0, 1000.0, 31),
    delay_samples=1,
    **common,
)
narrow.plot(mark=(150.0, 1.2))
for edge in narrow.boundary()[:3]:
    print(edge)
plt.show()
