"""Built-in reference and disturbance signals (public namespace of the private signal modules).

All signals are immutable, vectorised functions of time that add and scale::

    from hpdob.signals import SmoothStep, Sine, Step, trajectory
    reference = trajectory(SmoothStep(0.2, 1.2, 1.0) + Sine(-0.5, 0.5, start=4.0, phase=1.5708,
                                                            offset=0.5))
    disturbance = Step(1.5005, 0.05) + Sine(0.02, 2.0, start=2.5005)
"""

from ._signals import Constant, Ramp, Signal, SmoothStep, Step, Sum, trajectory
from ._waveforms import Chirp, Noise, Sine

__all__ = [
    "Chirp",
    "Constant",
    "Noise",
    "Ramp",
    "Signal",
    "Sine",
    "SmoothStep",
    "Step",
    "Sum",
    "trajectory",
]
