"""Models and plants: the servo's continuous model, its exact ZOH discretisation, MuJoCo.

Plant, ExactSubsteps, PlantSession
    The plant protocol: what the sampled-data loop needs from a plant.
ServoModel, DiscreteServoModel
    Rigid single-axis servo (eq. 1) and its exact zero-order-hold discretisation (eqs. 4-8).
TwoMassServo, DiscreteTwoMassServo
    Motor and load coupled by a torsional spring and damper, and its exact ZOH discretisation.
Environment
    A unilateral spring-damper contact the rigid servo or a two-mass load presses against.
InContact
    A plant bonded to its environment: the linear model of the loop in contact.
MujocoServo
    A servo (optionally with a pendulum link) simulated by MuJoCo, usable as ``plant=``.
"""

from ._contact import InContact
from ._environment import Environment
from ._lti import is_lti as is_lti

# Names imported "as" themselves and absent from __all__ are hpdob-internal: for the other
# subpackages, not part of the public API (docs/architecture.md, "Dependency order").
from ._mjcf import INTEGRATORS as INTEGRATORS
from ._mjcf import compile_model as compile_model
from ._mjcf import import_mujoco as import_mujoco
from ._mjcf import object_names as object_names
from ._mjcf import read_mjcf as read_mjcf
from ._mujoco import MujocoServo
from ._plant import DEFAULT_SUBSTEPS as DEFAULT_SUBSTEPS
from ._plant import MAX_PLANT_STEPS as MAX_PLANT_STEPS
from ._plant import ExactSubsteps, Plant, PlantSession
from ._servo import DiscreteServoModel, ServoModel
from ._servo import as_discrete_model as as_discrete_model
from ._servo import as_servo_model as as_servo_model
from ._two_mass import DiscreteTwoMassServo, TwoMassServo

__all__ = [
    "DiscreteServoModel",
    "DiscreteTwoMassServo",
    "Environment",
    "ExactSubsteps",
    "InContact",
    "MujocoServo",
    "Plant",
    "PlantSession",
    "ServoModel",
    "TwoMassServo",
]
