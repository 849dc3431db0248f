"""The shipped Franka Emika Panda model (``data/panda.xml``; sources in ``data/README.md``)."""

from __future__ import annotations

import math
from importlib import resources

from ._mujoco_arm import MujocoArm

__all__ = ["PANDA_READY", "PANDA_TORQUE_LIMITS", "panda"]

#: Franka's torque limits [N m] of joints 1-7 ("Limits for Panda",
#: https://frankaemika.github.io/docs/control_parameters.html).
PANDA_TORQUE_LIMITS = (87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0)
#: The "ready" pose of libfranka's examples [rad]: (0, -pi/4, 0, -3 pi/4, 0, pi/2, pi/4).
PANDA_READY = (0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4)


def panda(*, payload: float = 0.0, inertia_scale: float = 1.0, integrator=None) -> MujocoArm:
    """The Franka Emika Panda arm (7 hinges, ideal torque motors, no hand) as a :class:`MujocoArm`.

    Kinematics: Franka's modified Denavit-Hartenberg parameters; inertial parameters: Gaz et
    al., IEEE RA-L 2019, as published in ``franka_ros`` (Apache-2.0); see ``docs/robots.md``.
    The end-effector site is ``flange`` (0.107 m beyond joint 7's frame).

    Parameters
    ----------
    payload : float, optional
        A point mass at the flange [kg] (e.g. an unknown 1 kg payload). Default 0.
    inertia_scale : float, optional
        Factor on every link's mass and inertia (a wrong nominal model). Default 1.
    integrator : str, optional
        MuJoCo's integrator (default the file's, ``"Euler"``: its first step is split around
        the command so that the ground truth's acceleration costs no extra ``mj_forward``;
        ``"RK4"`` integrates more accurately at about twice the cost, ``docs/robots.md``).

    Returns
    -------
    MujocoArm

    Examples
    --------
    >>> from hpdob.robots import panda
    >>> arm = panda()
    >>> arm.n_joints, arm.end_effector
    (7, 'flange')
    >>> # at q = 0 the flange is at x = a7, z = d1 + d3 + d5 - d_flange (Franka's DH) [m]
    >>> [round(float(v), 6) for v in arm.end_effector_position([0.0] * 7)]
    [0.088, 0.0, 0.926]
    """
    path = resources.files("hpdob.robots").joinpath("data", "panda.xml")
    with resources.as_file(path) as file:
        return MujocoArm.from_xml(file, end_effector="flange", payload=payload,
                                  inertia_scale=inertia_scale, integrator=integrator)  # fmt: skip
