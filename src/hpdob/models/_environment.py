r"""A unilateral spring-damper contact the axis presses against."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import ParameterTypeError, as_real, nonnegative, positive
from ._plant import replace_parameters

__all__ = ["Environment", "check_environment"]


@dataclass(frozen=True)
class Environment:
    r"""A unilateral contact: a spring and damper that only push, beyond a position.

    .. math::

        \tau_{env} = \begin{cases} k_e(\theta - \theta_e) + c_e\,\omega
            & \text{if } \theta > \theta_e \text{ and } k_e(\theta - \theta_e) + c_e\,\omega > 0,\\
            0 & \text{otherwise,}\end{cases}

    acting against the motion on the rigid servo's axis, or on the load of a two-mass drive
    (``ServoModel(..., environment=Environment(...))``). On a linear axis the units are N/m,
    N s/m and m.

    Parameters
    ----------
    stiffness : float
        Contact stiffness :math:`k_e` [N m/rad], positive and finite.
    damping : float, optional
        Contact damping :math:`c_e` [N m s/rad], non-negative. Default 0.
    position : float, optional
        Angle :math:`\theta_e` of the contact surface [rad]. Default 0.

    Raises
    ------
    TypeError
        If a parameter is not a real number.
    ValueError
        If a parameter is out of range or not finite.

    References
    ----------
    S. Katsura, Y. Matsumoto, K. Ohnishi, "Modeling of force sensing and validation of
    disturbance observer for force control", IEEE Trans. Ind. Electron. 54(1), 2007 (the
    spring-damper environment of force control).

    Examples
    --------
    >>> from hpdob import Environment
    >>> wall = Environment(10.0, position=0.1)
    >>> round(float(wall.torque(0.105, 0.0)), 12), float(wall.torque(0.09, 1.0))
    (0.05, 0.0)
    """

    stiffness: float
    damping: float = 0.0
    position: float = 0.0

    def __post_init__(self) -> None:
        stiffness = positive(
            self.stiffness, "stiffness", "a positive finite contact stiffness [N m/rad]"
        )
        damping = nonnegative(
            self.damping, "damping", "a non-negative finite contact damping [N m s/rad]"
        )
        position = as_real(self.position, "position", "a finite contact position [rad]")
        object.__setattr__(self, "stiffness", stiffness)
        object.__setattr__(self, "damping", damping)
        object.__setattr__(self, "position", position)

    def torque(self, theta, omega):
        """The contact torque at an angle and velocity (0 out of contact).

        Parameters
        ----------
        theta : float or array_like
            Angle of the contacting axis [rad].
        omega : float or array_like
            Its velocity [rad/s].

        Returns
        -------
        ndarray
            :math:`\\tau_{env}` [N m], non-negative, the broadcast shape of the inputs.

        Examples
        --------
        >>> from hpdob import Environment
        >>> Environment(10.0, damping=1.0).torque([0.01, 0.01], [0.0, -0.2])
        array([0.1, 0. ])
        """
        theta = np.asarray(theta, dtype=float)
        omega = np.asarray(omega, dtype=float)
        push = self.stiffness * (theta - self.position) + self.damping * omega
        return np.where((theta > self.position) & (push > 0.0), push, 0.0)

    def replace(self, **changes) -> Environment:
        """Return a copy with some parameters changed (validated like the constructor).

        Parameters
        ----------
        **changes
            New values of ``stiffness``, ``damping`` or ``position``.

        Returns
        -------
        Environment

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For an unknown parameter or a value the constructor rejects.

        Examples
        --------
        >>> from hpdob import Environment
        >>> Environment(10.0).replace(stiffness=0.1)
        Environment(stiffness=0.1, damping=0.0, position=0.0)
        """
        return replace_parameters(self, changes)


def check_environment(environment, name: str = "environment"):
    """``environment`` if it is None, an :class:`Environment` or a dict of its arguments."""
    if environment is None or isinstance(environment, Environment):
        return environment
    if isinstance(environment, dict):
        return Environment(**environment)
    raise ParameterTypeError(
        f"{name} must be an Environment (or None), got {type(environment).__name__}"
    )
