"""
The paper's Figs. 2-5
=====================

``hpdob reproduce`` simulates the paper's section IV set-up (:mod:`hpdob.paper`): a PD
controller alone, conventional DObs at 50, 100 and 200 rad/s, the HPDOb at 100 rad/s and a
virtual experiment (a simulation with an encoder, a torque limit and a delay, standing in for
the paper's hardware test). The same runs and figures from Python:
"""

import matplotlib.pyplot as plt

from hpdob import paper

results = {name: paper.run(name) for name in paper.RUNS}
print(paper.summary_table({name: res.metrics() for name, res in results.items()}))

# %%
# Figs. 2 to 5, as ``hpdob reproduce`` writes them. In the estimation-error panels the
# y-range is set by the steady-state error; the transient at the 1.5 s disturbance step
# goes off scale, a triangle in each clipped series' colour marks where, and the note above
# the panel gives every clipped series' extremes under its legend label.

figures = paper.figures(results)
plt.show()
