r"""Computed-torque control: inverse dynamics of a nominal arm model with a PD on the error.

.. math::

    u = \hat M(q)\,(\ddot r + K_p (r - q) + K_d (\dot r - \dot q)) + \hat C(q, \dot q)\dot q
        + \hat g(q) + \hat B \dot q,

the right-hand side evaluated by the nominal model's inverse dynamics (MuJoCo's
``mj_inverse`` for a :class:`MujocoArm`, the written-out equations for a
:class:`TwoLinkArm`) at the measured ``q``, ``q̇`` and the commanded acceleration. With an exact
model the error obeys :math:`\ddot e + K_d \dot e + K_p e = 0` at every joint.
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, nonnegative

__all__ = ["ComputedTorque"]


@dataclass(frozen=True)
class ComputedTorque:
    """Computed-torque control on a nominal model (module docstring).

    Parameters
    ----------
    model : TwoLinkArm or MujocoArm
        The nominal arm (its ``inverse_dynamics`` gives the torque); may differ from the plant
        (unknown payload, inertias off by a factor).
    kp, kd : float or sequence of float
        Gains [1/s^2], [1/s], non-negative: one value for every joint or one per joint.
    feedforward : bool, optional
        Include the reference acceleration. Default True.

    Examples
    --------
    >>> from hpdob.robots import ComputedTorque, TwoLinkArm
    >>> arm = TwoLinkArm(m=(1.0, 1.0), l=(0.5, 0.5), lc=(0.25, 0.25), I=(0.02, 0.02))
    >>> ComputedTorque(arm, kp=400.0, kd=40.0).kp
    (400.0, 400.0)
    """

    model: object
    kp: object
    kd: object
    _: KW_ONLY
    feedforward: bool = True

    def __post_init__(self):
        n = getattr(self.model, "n_joints", None)
        if not isinstance(n, int) or not hasattr(self.model, "inverse_dynamics"):
            raise ParameterTypeError(
                f"model must be an arm model with inverse_dynamics (TwoLinkArm, MujocoArm), "
                f"got {type(self.model).__name__}"
            )
        for name, what in (("kp", "a non-negative finite gain [1/s^2]"),
                           ("kd", "a non-negative finite gain [1/s]")):  # fmt: skip
            value = getattr(self, name)
            values = np.full(n, value, dtype=float) if np.isscalar(value) else np.array(value)
            if values.shape != (n,):
                raise ParameterValueError(
                    f"{name} must have one entry per joint ({n}), got shape {values.shape}"
                )
            object.__setattr__(
                self,
                name,
                tuple(nonnegative(v, f"{name}[{i}]", what) for i, v in enumerate(values)),
            )
        if not isinstance(self.feedforward, bool):
            raise ParameterTypeError(f"feedforward must be True or False, got {self.feedforward!r}")

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return self.model.n_joints
