"""Models and plants: the servo's continuous model, its exact ZOH discretisation, MuJoCo.

ServoModel, DiscreteServoModel
    Rigid single-axis servo (eq. 1) and its exact zero-order-hold discretisation (eqs. 4-8).
MujocoServo
    A servo (optionally with a pendulum link) simulated by MuJoCo, usable as ``plant=``.
"""

from ._mujoco import MujocoServo
from ._servo import DiscreteServoModel, ServoModel

__all__ = ["DiscreteServoModel", "MujocoServo", "ServoModel"]
