"""The canonical loop and run of the paper's section IV, as data (:mod:`hpdob.paper` shows
them; the defaults of ``tune`` and ``compare_observers`` read them here, below the layers
that use them).

True plant J = 3.06e-4 kg m^2 (Maxon EC 90 flat class), b = 5e-5 N m s/rad, Coulomb friction
0.01 N m (tanh scale 0.01 rad/s); nominal model J_n = 2.8e-4 kg m^2, b_n = 0; Ts = 1 ms;
10 s; PD(kp=50, kd=5) with feed-forward; the virtual experiment's 16384-count encoder,
0.444 N m limit and one sample of delay.
"""

from __future__ import annotations

import math

from .._signals import SmoothStep, Step
from .._waveforms import Sine
from ..controllers import PD
from ..models import ServoModel
from ._devices import Actuator, Encoder

__all__ = [
    "CONTROLLER",
    "DISTURBANCE",
    "DURATION",
    "NOMINAL",
    "PLANT",
    "REFERENCE",
    "TS",
    "VIRTUAL_ACTUATOR",
    "VIRTUAL_SENSOR",
    "canonical_run",
]

#: The true plant: J = 3.06e-4 kg m^2, b = 5e-5 N m s/rad, Coulomb friction 0.01 N m.
PLANT = ServoModel(J=3.06e-4, b=5e-5, coulomb=0.01, coulomb_velocity=0.01)
#: The nominal model of controller and observer: J_n = 2.8e-4 kg m^2, b_n = 0.
NOMINAL = ServoModel(J=2.8e-4, b=0.0)
#: Sampling period [s].
TS = 1e-3  # s
#: Simulated time [s].
DURATION = 10.0  # s
#: PD controller (kp [1/s^2], kd [1/s]) with feed-forward of the reference acceleration.
CONTROLLER = PD(kp=50.0, kd=5.0, feedforward=True)
#: Reference [rad]: quintic step 0 -> 1 rad over 0.2-1.2 s, then 1 + 0.5 (1 - cos(pi (t - 4))).
REFERENCE = SmoothStep(0.2, 1.2, 1.0) + Sine(-0.5, 0.5, start=4.0, phase=math.pi / 2, offset=0.5)
#: External torque [N m]: 0.05 N m step at 1.5005 s plus 0.02 sin(4 pi (t - 2.5005)) from 2.5005 s.
DISTURBANCE = Step(1.5005, 0.05) + Sine(0.02, 2.0, start=2.5005)

#: Encoder and actuator of the virtual experiment standing in for the paper's Fig. 5 (a
#: simulation, not hardware): 16384 counts/rev with backward-difference velocity, the
#: EC 90 flat class's nominal torque as limit (0.444 N m), one sample of transport delay.
VIRTUAL_SENSOR = Encoder(16384, velocity="backward-difference")
VIRTUAL_ACTUATOR = Actuator(torque_limit=0.444, delay_samples=1)


def canonical_run() -> dict:
    """The canonical scenario's ``simulate`` keyword arguments (what ``hpdob.paper.scenario``
    returns): plant, nominal, Ts, duration, controller, reference, disturbance."""
    return {
        "plant": PLANT,
        "nominal": NOMINAL,
        "Ts": TS,
        "duration": DURATION,
        "controller": CONTROLLER,
        "reference": REFERENCE,
        "disturbance": DISTURBANCE,
    }
