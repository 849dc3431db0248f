"""Models and plants: the servo's continuous model, its exact ZOH discretisation, MuJoCo.

Plant, ExactSubsteps, PlantSession
    The plant protocol: what the sampled-data loop needs from a plant.
ServoModel, DiscreteServoModel
    Rigid single-axis servo (eq. 1) and its exact zero-order-hold discretisation (eqs. 4-8).
MujocoServo
    A servo (optionally with a pendulum link) simulated by MuJoCo, usable as ``plant=``.
"""

from ._mujoco import MujocoServo
from ._plant import ExactSubsteps, Plant, PlantSession
from ._servo import DiscreteServoModel, ServoModel

__all__ = [
    "DiscreteServoModel",
    "ExactSubsteps",
    "MujocoServo",
    "Plant",
    "PlantSession",
    "ServoModel",
]
