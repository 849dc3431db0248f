"""Robots: an observer per joint on an N-joint arm, and the model-based peers.

TwoLinkArm
    The built-in two-link planar arm, its dynamics written out (checked against MuJoCo).
MujocoArm, panda
    Any MJCF arm of hinge joints and motors simulated by MuJoCo; the Franka Panda with its
    published parameters.
ArmLoop, JointSines, simulate_arm, ArmResult
    The N-joint loop: per-joint observers and controllers, encoder, delay and limits per joint.
load_arm_scenario, ArmScenario
    An N-joint TOML scenario (``[plant] type = "mujoco-arm"`` or ``"two-link-arm"``: plant
    types registered with :mod:`hpdob.simulation` on import, so that
    :func:`hpdob.simulation.load_scenario` and ``hpdob simulate`` read them).
ComputedTorque
    Computed-torque control on a nominal model.
momentum_observer, joint_observer_external, end_effector_force, ExternalEstimate
    External joint torques (De Luca's momentum observer, or the per-joint observers) and the
    end-effector force through the damped pseudo-inverse of the Jacobian.
"""

from ._arm_loop import ArmLoop, JointSines
from ._computed_torque import ComputedTorque
from ._external import (
    ExternalEstimate,
    end_effector_force,
    joint_observer_external,
    momentum_observer,
)
from ._mujoco_arm import MujocoArm
from ._panda import PANDA_READY, PANDA_TORQUE_LIMITS, panda
from ._result import ArmResult
from ._scenario import ArmScenario, load_arm_scenario
from ._simulate import simulate_arm
from ._two_link import TwoLinkArm

__all__ = [
    "PANDA_READY",
    "PANDA_TORQUE_LIMITS",
    "ArmLoop",
    "ArmResult",
    "ArmScenario",
    "ComputedTorque",
    "ExternalEstimate",
    "JointSines",
    "MujocoArm",
    "TwoLinkArm",
    "end_effector_force",
    "joint_observer_external",
    "load_arm_scenario",
    "momentum_observer",
    "panda",
    "simulate_arm",
]
