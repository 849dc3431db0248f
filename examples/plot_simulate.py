"""
A closed-loop simulation of your own set-up
===========================================

:func:`hpdob.simulate` runs the sampled-data loop: a continuous plant with Coulomb friction
between samples, a sampled PD controller, an encoder, an actuator with a torque limit and the
observer in the inner loop. Here a motor 30 % heavier than its nominal model follows a smooth
step and carries a load that steps and then oscillates.
"""

import matplotlib.pyplot as plt

from hpdob import PD, Encoder, ServoModel, design_observer, simulate
from hpdob.signals import Sine, SmoothStep, Step

Ts = 1e-3  # sampling period [s]
nominal = ServoModel(J=2.0e-4)
plant = ServoModel(J=2.6e-4, b=1e-4, coulomb=0.005, coulomb_velocity=0.01)
result = simulate(
    plant=plant,
    nominal=nominal,
    Ts=Ts,
    duration=3.0,
    controller=PD(kp=60.0, kd=6.0, feedforward=True),
    observer=design_observer(nominal.discretize(Ts), order=1, bandwidth=150.0),
    reference=SmoothStep(0.1, 0.6, 0.5),
    disturbance=Step(1.0, 0.03) + Sine(0.01, 3.0, start=2.0),
    sensor=Encoder(65536),
    label="HPDOb-150, 16-bit encoder",
)
metrics = result.metrics()
print(
    f"RMS estimation error {metrics['rms_estimation_error']:.2e} N m, RMS position error "
    f"while holding {metrics['rms_position_error_regulation']:.2e} rad"
)
result.plot()
plt.show()
