"""Robots: an observer per joint on an N-joint arm, and the model-based peers.

TwoLinkArm
    The built-in two-link planar arm, its dynamics written out (checked against MuJoCo).
MujocoArm, panda
    Any MJCF arm of hinge joints and motors simulated by MuJoCo; the Franka Panda with its
    published parameters.
ArmLoop, JointSines, simulate_arm, ArmResult
    The N-joint loop: per-joint observers and controllers, encoder, delay and limits per joint.
ComputedTorque
    Computed-torque control on a nominal model.
"""

from ._arm_loop import ArmLoop, JointSines
from ._computed_torque import ComputedTorque
from ._mujoco_arm import MujocoArm
from ._panda import PANDA_READY, PANDA_TORQUE_LIMITS, panda
from ._result import ArmResult
from ._simulate import simulate_arm
from ._two_link import TwoLinkArm

__all__ = [
    "PANDA_READY",
    "PANDA_TORQUE_LIMITS",
    "ArmLoop",
    "ArmResult",
    "ComputedTorque",
    "JointSines",
    "MujocoArm",
    "TwoLinkArm",
    "panda",
    "simulate_arm",
]
