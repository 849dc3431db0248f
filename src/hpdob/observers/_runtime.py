"""The stateful runtime object for the observer sample loop."""

from __future__ import annotations

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError
from . import _core
from ._synthesis import ObserverDesign, design_observer

__all__ = ["DisturbanceObserver", "as_design", "check_designed_on"]


def as_design(observer, name: str = "observer") -> ObserverDesign:
    """Return the :class:`ObserverDesign` of a ``DisturbanceObserver`` or a design itself."""
    if isinstance(observer, DisturbanceObserver):
        return observer.design
    if isinstance(observer, ObserverDesign):
        return observer
    raise ParameterTypeError(
        f"{name} must be a DisturbanceObserver or an ObserverDesign, got {type(observer).__name__}"
    )


def check_designed_on(design: ObserverDesign, nominal, Ts: float, name: str = "observer") -> None:
    """Raise unless ``design`` was synthesised on ``nominal.discretize(Ts)`` (same J, b, Ts)."""
    model = design.model
    if (model.J, model.b, model.Ts) != (nominal.J, nominal.b, Ts):
        raise ParameterValueError(
            f"{name} must be designed on nominal.discretize(Ts): its model has J={model.J}, "
            f"b={model.b}, Ts={model.Ts} but nominal has J={nominal.J}, b={nominal.b} and Ts={Ts}"
        )


class DisturbanceObserver:
    r"""Discrete disturbance observer of truncation order ``order`` with its runtime state.

    ``order=0`` is the conventional DOb (eqs. 9-13), ``order=1`` the HPDOb (eqs. 14-24) and
    ``order >= 2`` the generalisation with disturbance model :math:`\Delta^{m+1}\tau = 0`.

    Parameters
    ----------
    model : DiscreteServoModel
        Nominal discrete model, ``ServoModel(J_n, b_n).discretize(Ts)``.
    order : int
        Truncation order ``m >= 0``.
    poles : sequence of complex, optional
        ``order + 1`` eigenvalues of the error matrix, strictly inside the unit circle,
        complex ones in conjugate pairs, repeats allowed.
    bandwidth : float, optional
        Bandwidth ``g > 0`` [rad/s]: all poles at ``exp(-g Ts)``. Give exactly one of
        ``poles`` and ``bandwidth``.
    gain_direction : sequence of 2 floats, optional
        Direction ``d`` of the gains, ``L_i = k_i d / (d^T D_Dn)``; default ``(1, 1)`` is
        eq. (25).

    Attributes
    ----------
    design : ObserverDesign
        The immutable synthesis result; ``model``, ``order``, ``poles``, ``gains`` (row ``i``
        is :math:`L_{i+1}^T`) and ``error_matrix`` are read from it.
    state : ndarray, shape (order + 1,)
        Copy of the auxiliary-variable estimate :math:`\hat z_k`.

    Raises
    ------
    TypeError, ValueError
        See :func:`hpdob.design_observer`.

    Notes
    -----
    The sample loop, in this order at every sample ``k``::

        x_k = measure()                      # [theta (rad), omega (rad/s)]
        tau_hat = obs.estimate(x_k)          # eq. (13) / (23): uses the state from k-1
        u_k = u_pd + tau_hat                 # compensate the estimated disturbance
        apply(u_k)                           # zero-order hold over [k Ts, (k+1) Ts)
        obs.update(x_k, u_k)                 # eq. (11) / (20)-(21): prepares sample k+1

    ``update`` must receive the torque that was really applied, including ``tau_hat``. The
    state starts as ``reset(x0=(0, 0), tau0=0)``. The same loop exists as pure
    functions (``initial_state``, ``estimate``, ``update``) that this class calls.

    Examples
    --------
    >>> import numpy as np
    >>> from hpdob import DisturbanceObserver, ServoModel
    >>> model = ServoModel(J=2.8e-4).discretize(1e-3)
    >>> obs = DisturbanceObserver(model, order=1, bandwidth=100.0)
    >>> x, tau = np.zeros(2), 0.01                     # constant load torque [N m]
    >>> for k in range(300):
    ...     tau_hat = obs.estimate(x)
    ...     u = -2.8e-4 * (50 * x[0] + 5 * x[1]) + tau_hat
    ...     obs.update(x, u)
    ...     x = model.step(x, u, tau)
    >>> round(obs.estimate(x), 6)
    0.01
    """

    __slots__ = ("_design", "_state")

    def __init__(self, model, *, order, poles=None, bandwidth=None, gain_direction=(1.0, 1.0)):
        self._design = design_observer(
            model, order=order, poles=poles, bandwidth=bandwidth, gain_direction=gain_direction
        )
        self._state = _core.initial_state(self._design)

    @classmethod
    def from_design(
        cls, design: ObserverDesign, *, x0=(0.0, 0.0), tau0: float = 0.0
    ) -> DisturbanceObserver:
        """Runtime observer for an existing :class:`ObserverDesign`, reset at ``x0, tau0``."""
        if not isinstance(design, ObserverDesign):
            raise ParameterTypeError(
                f"design must be an ObserverDesign, got {type(design).__name__}"
            )
        return cls._with_state(design, _core.initial_state(design, x0, tau0))

    @classmethod
    def _with_state(cls, design: ObserverDesign, state: tuple) -> DisturbanceObserver:
        obs = cls.__new__(cls)
        obs._design = design
        obs._state = state
        return obs

    # -- the design, read-only ---------------------------------------------------------
    @property
    def design(self) -> ObserverDesign:
        """The immutable synthesis result."""
        return self._design

    @property
    def model(self):
        """Nominal :class:`DiscreteServoModel`."""
        return self._design.model

    @property
    def order(self) -> int:
        """Truncation order ``m``."""
        return self._design.order

    @property
    def poles(self) -> np.ndarray:
        """Eigenvalues of the error matrix that were placed."""
        return self._design.poles

    @property
    def bandwidth(self) -> float | None:
        """Bandwidth [rad/s] if the poles came from one, else ``None``."""
        return self._design.bandwidth

    @property
    def gain_direction(self) -> np.ndarray:
        """Direction ``d`` of the gain vectors."""
        return self._design.gain_direction

    @property
    def gains(self) -> np.ndarray:
        r"""Gains, shape ``(order + 1, 2)``; row ``i`` is :math:`L_{i+1}^T`."""
        return self._design.gains

    @property
    def error_matrix(self) -> np.ndarray:
        """Estimation-error matrix ``M`` (eqs. 12, 22)."""
        return self._design.error_matrix

    @property
    def state(self) -> np.ndarray:
        r"""Copy of :math:`\hat z_k`, shape ``(order + 1,)``."""
        return np.array(self._state)

    # -- the sample loop -----------------------------------------------------------------
    def estimate(self, x) -> float:
        """Disturbance estimate [N m] at the current sample from the measured ``x``.

        Eq. (13) (DOb) / eq. (23) (HPDOb). Does not change the state.
        """
        return _core.estimate(self._design, self._state, x)

    def update(self, x, u) -> None:
        """Advance the state with the measured ``x_k`` and the applied torque ``u_k`` [N m].

        Eq. (11) (DOb) / eqs. (20)-(21) (HPDOb). A non-finite ``x`` or ``u`` raises
        :class:`ValueError` and leaves the state unchanged.
        """
        self._state = _core.update(self._design, self._state, x, u)

    def reset(self, x0=(0.0, 0.0), tau0: float = 0.0) -> None:
        """Set the state a constant disturbance ``tau0`` [N m] at rest in ``x0`` would give.

        :math:`\\hat z_i = \\tau_0 + L_i^T x_0`, so ``estimate(x0)`` returns ``tau0``.
        """
        self._state = _core.initial_state(self._design, x0, tau0)

    def to_statespace(self):
        """The observer as a discrete python-control ``StateSpace`` (``dt = Ts``).

        Inputs ``theta, omega, u``, output ``tau_hat``, state the auxiliary variables:
        ``A = M``, ``B = [K_x, K_u]``, ``C = e_{m+1}^T``, ``D = [-L_{m+1}^T, 0]``. From a zero
        initial state it reproduces this object after ``reset()`` sample by sample. See
        :func:`hpdob.analysis._estimation.observer_statespace`.

        Examples
        --------
        >>> from hpdob import DisturbanceObserver, ServoModel
        >>> obs = DisturbanceObserver(ServoModel(2.8e-4).discretize(1e-3), order=0, poles=[0.9])
        >>> obs.to_statespace().A
        array([[0.9]])
        """
        from ..analysis._estimation import observer_statespace

        return observer_statespace(self._design)

    def copy(self) -> DisturbanceObserver:
        """Independent observer with the same design and the same current state."""
        return self._with_state(self._design, self._state)

    def __repr__(self) -> str:
        poles = np.array2string(np.asarray(self.poles), precision=6, separator=", ")
        return (
            f"DisturbanceObserver(order={self.order}, poles={poles}, "
            f"Ts={self.model.Ts:g}, J_n={self.model.J:g}, b_n={self.model.b:g})"
        )
