"""The force step the friction tests run (a test helper, importable by name): the paper's
motor on a 10 N m/rad wall, ``ForceControl(1000, kv=40)``, the virtual experiment's encoder
and actuator, a 0.05 N m step of ``tau_ref`` at 0.1 s from 0.01 rad before the wall."""

from __future__ import annotations

import numpy as np

from hpdob import Environment, ServoLoop, paper, simulate
from hpdob.controllers import ForceControl


def force_step_run(observer, duration=0.6):
    """``simulate`` of the force step with ``observer`` (the RTOB composition)."""
    loop = ServoLoop(plant=paper.PLANT.replace(environment=Environment(10.0)),
                     nominal=paper.NOMINAL, Ts=paper.TS, observer=observer,
                     controller=ForceControl(1000.0, kv=40.0), sensor=paper.VIRTUAL_SENSOR,
                     actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip

    def reference(t):
        return np.where(t >= 0.1, 0.05, 0.0), 0 * t, 0 * t

    return simulate(loop, reference=reference, duration=duration, x0=(-0.01, 0.0))
