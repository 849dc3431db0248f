r"""The Coulomb part of the RTOB's friction model: the one nonlinear term of an observer.

The reaction-torque observer subtracts a friction model from a disturbance estimate,
:math:`\hat\tau_{reac,k} = \hat\tau^R_k - \hat f(\omega_k)` with
:math:`\hat f(\omega) = \Delta b\,\omega + c_n\tanh(\omega/v_n)`. The viscous part is linear and
lives in the :class:`~hpdob.LinearObserver`'s ``tau_reac`` row; the Coulomb part cannot, so it
is this term, applied after the linear outputs of the sample (:attr:`LinearObserver.coulomb`).
:func:`coulomb_torque` is its one definition: the Python runtime calls it, the compiled
kernel compiles it with numba, and ``export_c`` prints the same three operations
(``c * tanh(omega / v)``, libm's ``tanh``), so the three agree bit for bit in double.
The smooth shape is the plant's own (:meth:`hpdob.ServoModel.coulomb_torque`), so with the
plant's ``coulomb`` and ``coulomb_velocity`` the model is exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .._validation import ParameterValueError, nonnegative, positive

__all__ = ["CoulombFriction", "coulomb_torque"]

#: Where the Coulomb term reads its velocity: the measured ``omega`` or the ``omega_hat`` output.
VELOCITY_SOURCES = ("omega", "omega_hat")


def coulomb_torque(c: float, v: float, omega: float, deadband: float = 0.0) -> float:
    r"""The smoothed Coulomb friction :math:`c\tanh(\omega/v)` [N m] (the plant's shape).

    With a ``deadband`` :math:`d > 0` the velocity is first passed through a dead zone,
    :math:`c\tanh(\operatorname{dz}_d(\omega)/v)` with
    :math:`\operatorname{dz}_d(\omega) = \omega - d` above :math:`d`, :math:`\omega + d` below
    :math:`-d` and 0 between (``0 * omega``: a NaN velocity stays NaN).

    Parameters
    ----------
    c : float
        Coulomb torque [N m].
    v : float
        Velocity scale [rad/s] of the smoothing.
    omega : float
        Velocity [rad/s].
    deadband : float, optional
        :math:`d` [rad/s], the dead zone's half-width. Default 0: none, and the result is
        ``c * math.tanh(omega / v)`` itself (the same operations, bit for bit).

    Returns
    -------
    float
        ``c * math.tanh(omega / v)`` (dead-zoned ``omega`` with a ``deadband``), in that
        operation order (the numba kernel and the exported C evaluate the same expression).

    Examples
    --------
    >>> from hpdob.observers import coulomb_torque
    >>> coulomb_torque(0.01, 0.01, 1.0)   # tanh(100) = 1 to double precision
    0.01
    >>> coulomb_torque(0.01, 0.01, 0.03, deadband=0.04)   # inside the dead zone
    0.0
    """
    if deadband > 0.0:  # the dead zone; with none the expression is the plain one
        if omega > deadband:
            omega = omega - deadband
        elif omega < -deadband:
            omega = omega + deadband
        else:
            omega = 0.0 * omega
    return c * math.tanh(omega / v)


@dataclass(frozen=True)
class CoulombFriction:
    r"""The Coulomb term :math:`c_n\tanh(\omega/v_n)` an RTOB subtracts from ``tau_reac``.

    Parameters
    ----------
    c : float
        :math:`c_n` [N m], non-negative.
    v : float
        :math:`v_n` [rad/s], positive: the smoothing's velocity scale.
    velocity : {"omega", "omega_hat"}
        The velocity it reads: the measured ``omega`` (an observer measuring the state) or the
        observer's ``omega_hat`` output (a position-only observer).
    deadband : float, optional
        :math:`d` [rad/s], non-negative: the dead zone on that velocity
        (:func:`coulomb_torque`), e.g. the velocity resolution of the measurement path
        (:func:`hpdob.observers.coulomb_velocity_resolution`). Default 0: none.

    Examples
    --------
    >>> from hpdob.observers import CoulombFriction
    >>> CoulombFriction(0.01, 0.01, "omega").torque(-1.0)
    -0.01
    """

    c: float
    v: float
    velocity: str = "omega"
    deadband: float = 0.0

    def __post_init__(self):
        object.__setattr__(
            self, "c", nonnegative(self.c, "coulomb", "a non-negative finite Coulomb torque [N m]")
        )
        object.__setattr__(
            self,
            "v",
            positive(self.v, "coulomb_velocity", "a positive finite velocity scale [rad/s]"),
        )
        object.__setattr__(
            self,
            "deadband",
            nonnegative(
                self.deadband, "coulomb_deadband", "a non-negative finite dead band [rad/s]"
            ),
        )
        if self.velocity not in VELOCITY_SOURCES:
            raise ParameterValueError(
                f"velocity must be one of {list(VELOCITY_SOURCES)}, got {self.velocity!r}"
            )

    def torque(self, omega: float) -> float:
        r""":func:`coulomb_torque` with this term's ``c`` and ``v``.

        Parameters
        ----------
        omega : float
            Velocity [rad/s].

        Returns
        -------
        float
            :math:`c\tanh(\operatorname{dz}_d(\omega)/v)` [N m] (:math:`c\tanh(\omega/v)`
            without a dead band).
        """
        return coulomb_torque(self.c, self.v, omega, self.deadband)
