"""The stateful runtime objects of the observer sample loop."""

from __future__ import annotations

import numpy as np

from .._validation import ParameterTypeError
from . import _core
from ._position import PositionObserverDesign
from ._synthesis import ObserverDesign, design_observer
from ._system import LinearObserver, as_system

__all__ = ["DisturbanceObserver", "Observer", "as_design"]


#: The design types of the order-m families (what :func:`hpdob.design_observer` returns).
DESIGNS = (ObserverDesign, PositionObserverDesign)


def as_design(observer, name: str = "observer"):
    """Return the design (:class:`ObserverDesign` or :class:`PositionObserverDesign`) of a
    ``DisturbanceObserver``, or a design itself."""
    if isinstance(observer, DisturbanceObserver):
        return observer.design
    if isinstance(observer, DESIGNS):
        return observer
    raise ParameterTypeError(
        f"{name} must be a DisturbanceObserver or an ObserverDesign, got {type(observer).__name__}"
    )


class Observer:
    r"""Runtime object of any observer: its :class:`LinearObserver` and the current state.

    The sample loop, in this order at every sample ``k``::

        y_k = measure()                      # [theta, omega], or theta alone (position-only)
        tau_hat = obs.estimate(y_k)          # uses the state from k-1; obs.velocity after it
        u_k = u_outer + tau_hat              # compensate the estimated disturbance
        apply(u_k)                           # zero-order hold over [k Ts, (k+1) Ts)
        obs.update(y_k, u_k)                 # prepares sample k+1

    Parameters
    ----------
    system : LinearObserver or observer-like
        The observer (anything with ``.system``, e.g. a design, is accepted).
    x0 : sequence of 2 floats, optional
        ``[theta (rad), omega (rad/s)]`` of the initial reset. Default ``(0, 0)``.
    tau0 : float, optional
        Disturbance [N m] of the initial reset. Default 0.

    Attributes
    ----------
    system : LinearObserver
    state : ndarray
        Copy of :math:`s_k`.

    Notes
    -----
    Every method validates its arguments before it changes anything: a rejected call leaves
    the state as it was. :func:`hpdob.estimate`, :func:`hpdob.update` and
    :func:`hpdob.initial_state` are the same loop as pure functions.
    """

    __slots__ = ("_outputs", "_state", "_system")

    def __init__(self, system, *, x0=(0.0, 0.0), tau0: float = 0.0):
        system = as_system(system, "system")
        state = _core.initial_state(system, x0, tau0)
        self._system = system
        self._state = state
        self._outputs = None

    @staticmethod
    def of(design, *, x0=(0.0, 0.0), tau0: float = 0.0) -> Observer:
        """The runtime object of a design, reset at ``x0, tau0``.

        Parameters
        ----------
        design : design or observer-like
            A design of any family, or any observer (a :class:`LinearObserver` or an object
            whose ``system`` is one).
        x0 : sequence of 2 floats, optional
            ``[theta (rad), omega (rad/s)]`` of the reset. Default ``(0, 0)``.
        tau0 : float, optional
            Disturbance [N m] of the reset. Default 0.

        Returns
        -------
        Observer
            The runtime class of the design's registered family
            (:func:`hpdob.observers.register_family`): a :class:`DisturbanceObserver` for the
            order-m families, an :class:`~hpdob.ExtendedStateObserver` or a
            :class:`~hpdob.KalmanDisturbanceObserver`; a plain :class:`Observer` for any other
            observer.
        """
        from ._registry import family_of

        family = family_of(design)  # a design of a registered family: its runtime class
        if family is not None and family.runtime is not None and isinstance(design, family.designs):
            return family.runtime(design, x0, tau0)
        return Observer(design, x0=x0, tau0=tau0)

    @classmethod
    def _with_state(cls, system: LinearObserver, state: tuple, *attrs):
        obs = cls.__new__(cls)
        obs._system = system
        obs._state = state
        obs._outputs = None
        for name, value in attrs:
            object.__setattr__(obs, name, value)
        return obs

    # -- read-only views -------------------------------------------------------------------
    @property
    def system(self) -> LinearObserver:
        """The observer as a linear system (the protocol every consumer runs)."""
        return self._system

    @property
    def model(self):
        """Nominal :class:`DiscreteServoModel` the observer was designed on (or None)."""
        return self._system.model

    @property
    def Ts(self) -> float:
        """Sampling period [s]."""
        return self._system.Ts

    @property
    def measures(self) -> tuple:
        """Measured signals: ``("theta", "omega")`` or ``("theta",)``."""
        return self._system.measures

    @property
    def state(self) -> np.ndarray:
        r"""Copy of the state :math:`s_k`."""
        return np.array(self._state)

    @property
    def velocity(self) -> float:
        r"""Velocity estimate :math:`\hat\omega_k` [rad/s] of the last :meth:`estimate`.

        Raises
        ------
        AttributeError
            If the observer has no velocity estimate or ``estimate`` was not called since the
            last ``update`` or ``reset``.
        """
        if not self._system.has_velocity:
            raise AttributeError(
                f"this observer has no velocity estimate (outputs: {self._system.outputs}); "
                "position-only observers have one"
            )
        if self._outputs is None:
            raise AttributeError("velocity is available after estimate() of the current sample")
        return self._outputs[1]

    # -- the sample loop -------------------------------------------------------------------
    def estimate(self, measurement) -> float:
        r"""Disturbance estimate at the current sample from the measurement.

        Does not change the state; afterwards :attr:`velocity` holds the velocity estimate
        where the observer has one.

        Parameters
        ----------
        measurement : sequence of 2 floats, or float
            ``[theta (rad), omega (rad/s)]`` for an observer that measures the state, the
            angle [rad] (a float) for a position-only one.

        Returns
        -------
        float
            :math:`\hat\tau_k` [N m] (eqs. 13, 23).

        Raises
        ------
        TypeError, ValueError
            If ``measurement`` is non-finite or of the wrong kind.
        """
        system = self._system
        values = _core.read_measurement(system, measurement)
        y = system.python[1](self._state, *values)
        self._outputs = y
        return y[0]

    def update(self, measurement, u) -> None:
        """Advance the state by one sample (eqs. 11, 20-21).

        Parameters
        ----------
        measurement : sequence of 2 floats, or float
            As for :meth:`estimate`, at the same sample.
        u : float
            The torque applied over the sample [N m], compensation included.

        Raises
        ------
        TypeError, ValueError
            If ``measurement`` or ``u`` is non-finite or malformed, or finite but so large that
            the next state overflows (never a silently poisoned state); the state is unchanged.
        """
        system = self._system
        values = _core.read_measurement(system, measurement)
        u = _core.read_control(u)
        new = system.checked_update(self._state, *values, u)
        if new is None:  # _core.checked_next_state inline: this is the per-sample path
            raise _core.overflow_error(system, values, u)
        self._state = new
        self._outputs = None

    def reset(self, x0=(0.0, 0.0), tau0: float = 0.0) -> None:
        r"""Set the state a constant disturbance ``tau0`` at ``x0`` would give.

        :math:`s = N [\theta_0, \omega_0, \tau_0]`, so ``estimate`` at ``x0`` returns
        ``tau0`` (:func:`hpdob.initial_state`).

        Parameters
        ----------
        x0 : sequence of 2 floats, optional
            ``[theta (rad), omega (rad/s)]``. Default ``(0, 0)``.
        tau0 : float, optional
            Disturbance [N m]. Default 0.

        Raises
        ------
        TypeError, ValueError
            If ``x0`` or ``tau0`` is non-finite or malformed; the state is unchanged.
        """
        self._state = _core.initial_state(self._system, x0, tau0)
        self._outputs = None

    def to_statespace(self):
        """The observer as a discrete python-control ``StateSpace`` (``dt = Ts``).

        Returns
        -------
        control.StateSpace
            See :meth:`LinearObserver.to_statespace`.
        """
        return self._system.to_statespace()

    def copy(self):
        """Independent observer with the same design and the same current state.

        Returns
        -------
        Observer
            Of the same class; updating one leaves the other unchanged.
        """
        other = self.__class__.__new__(self.__class__)
        for cls in type(self).__mro__:
            for slot in getattr(cls, "__slots__", ()):
                if hasattr(self, slot):
                    object.__setattr__(other, slot, getattr(self, slot))
        return other

    def __repr__(self) -> str:
        return f"Observer({self._system!r})"


class _DesignedObserver(Observer):
    """An :class:`Observer` that keeps the design it was built from (``.design``)."""

    __slots__ = ("_design",)

    def _start(self, design) -> None:
        """Initialise from ``design``, reset at rest."""
        self._design = design
        Observer.__init__(self, design.system)

    @classmethod
    def _of(cls, design, x0, tau0):
        """A runtime object of ``design``, reset at ``x0, tau0``."""
        state = _core.initial_state(design, x0, tau0)
        return cls._with_state(design.system, state, ("_design", design))

    @property
    def design(self):
        """The immutable design."""
        return self._design


class DisturbanceObserver(_DesignedObserver):
    r"""Discrete disturbance observer of truncation order ``order`` with its runtime state.

    ``order=0`` is the conventional DOb (eqs. 9-13), ``order=1`` the HPDOb (eqs. 14-24) and
    ``order >= 2`` the generalisation with disturbance model :math:`\Delta^{m+1}\tau = 0`.
    With ``measurement="position"`` the observer measures the angle only and estimates the
    velocity along with the disturbance (``docs/theory.md``, section 9): ``estimate`` and
    ``update`` then take the angle (a float) and :attr:`velocity` gives :math:`\hat\omega_k`.

    Parameters
    ----------
    model : DiscreteServoModel or control.TransferFunction or control.StateSpace
        Nominal discrete model, ``ServoModel(J_n, b_n).discretize(Ts)``. A sampled python-control
        servo (``control.c2d(sys, Ts)``) is read by :meth:`DiscreteServoModel.from_lti`.
    order : int
        Truncation order ``m >= 0``.
    poles : sequence of complex, optional
        Eigenvalues of the error matrix, strictly inside the unit circle, complex ones in
        conjugate pairs, repeats allowed: ``order + 1`` of them (``order + 3`` for
        ``measurement="position"``).
    bandwidth : float, optional
        Bandwidth ``g > 0`` [rad/s]: all disturbance poles at ``exp(-g Ts)``. Give exactly one
        of ``poles`` and ``bandwidth``.
    measurement : {"state", "position"}, optional
        Angle and velocity measured (default, the paper's observer) or the angle only.
    velocity_bandwidth : float, optional
        Position-only with ``bandwidth``: the two velocity poles at ``exp(-g_v Ts)``; default
        ``bandwidth``.
    gain_direction : sequence of 2 floats, optional
        Measured state only: direction ``d`` of the gains, ``L_i = k_i d / (d^T D_Dn)``;
        default ``(1, 1)`` is eq. (25).

    Attributes
    ----------
    design : ObserverDesign or PositionObserverDesign
        The immutable synthesis result; ``model``, ``order``, ``poles``, ``gains`` and
        ``error_matrix`` are read from it. The state (``.state``, a copy of the
        auxiliary-variable estimate :math:`\hat z_k`, or for a position-only observer the prior
        estimate of :math:`[\theta, \omega, \tau_{k-m}, \dots, \tau_k]`) and the linear
        system (``.system``, what simulation, analysis and export run) are those of
        :class:`Observer`.

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

    __slots__ = ()

    def __init__(
        self,
        model,
        *,
        order,
        poles=None,
        bandwidth=None,
        measurement="state",
        velocity_bandwidth=None,
        gain_direction=None,
    ):
        design = design_observer(
            model,
            order=order,
            poles=poles,
            bandwidth=bandwidth,
            measurement=measurement,
            velocity_bandwidth=velocity_bandwidth,
            gain_direction=gain_direction,
        )
        self._start(design)

    @classmethod
    def from_design(cls, design, *, x0=(0.0, 0.0), tau0: float = 0.0) -> DisturbanceObserver:
        """Runtime observer for an existing design, reset at ``x0, tau0``.

        Parameters
        ----------
        design : ObserverDesign or PositionObserverDesign
            From :func:`hpdob.design_observer`.
        x0 : sequence of 2 floats, optional
            ``[theta (rad), omega (rad/s)]`` of the reset. Default ``(0, 0)``.
        tau0 : float, optional
            Disturbance [N m] of the reset. Default 0.

        Returns
        -------
        DisturbanceObserver

        Raises
        ------
        ParameterTypeError
            If ``design`` is not a design of the order-m families.
        """
        if not isinstance(design, DESIGNS):
            raise ParameterTypeError(
                f"design must be an ObserverDesign, got {type(design).__name__}"
            )
        return cls._of(design, x0, tau0)

    # -- the design, read-only ---------------------------------------------------------

    @property
    def measurement(self) -> str:
        """``"state"`` (angle and velocity measured) or ``"position"`` (angle only)."""
        return self._system.measurement

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
    def velocity_bandwidth(self) -> float | None:
        """Bandwidth [rad/s] of the velocity poles of a position-only observer designed by
        bandwidth, else ``None``."""
        return getattr(self._design, "velocity_bandwidth", None)

    @property
    def gain_direction(self) -> np.ndarray | None:
        """Direction ``d`` of the gain vectors (None for a position-only observer)."""
        return self._design.gain_direction

    @property
    def gains(self) -> np.ndarray:
        r"""Gains: shape ``(order + 1, 2)``, row ``i`` is :math:`L_{i+1}^T`; for a
        position-only observer the current-form gain ``K``, shape ``(order + 3,)``."""
        return self._design.gains

    @property
    def error_matrix(self) -> np.ndarray:
        """Estimation-error matrix: ``M`` (eqs. 12, 22), or :math:`A_a - L c^T` for a
        position-only observer."""
        return self._design.error_matrix

    def to_statespace(self):
        """The observer as a discrete python-control ``StateSpace`` (``dt = Ts``).

        From a zero initial state it reproduces this object after ``reset()`` sample by sample.

        Returns
        -------
        control.StateSpace
            Inputs ``theta, omega, u``, output ``tau_hat``, state the auxiliary variables:
            ``A = M``, ``B = [K_x, K_u]``, ``C = e_{m+1}^T``, ``D = [-L_{m+1}^T, 0]``; for a
            position-only observer inputs ``theta, u``, outputs ``tau_hat, omega_hat`` and
            ``A, B, C, D = F, G, H, E`` of its system.

        Examples
        --------
        >>> from hpdob import DisturbanceObserver, ServoModel
        >>> obs = DisturbanceObserver(ServoModel(2.8e-4).discretize(1e-3), order=0, poles=[0.9])
        >>> obs.to_statespace().A
        array([[0.9]])
        """
        return as_system(self._design).to_statespace()

    def __repr__(self) -> str:
        poles = np.array2string(np.asarray(self.poles), precision=6, separator=", ")
        kind = ", measurement='position'" if self.measurement == "position" else ""
        return (
            f"DisturbanceObserver(order={self.order}{kind}, poles={poles}, "
            f"Ts={self.model.Ts:g}, J_n={self.model.J:g}, b_n={self.model.b:g})"
        )
