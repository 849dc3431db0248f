"""The closed loop as a value: plant, nominal model, sampling period, controller, observer,
sensor and actuator, validated once."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, fields, replace

from .._validation import ParameterTypeError, ParameterValueError, positive, require_instance
from ..models._lti import as_servo_model, is_lti
from ..models._plant import Plant
from ..models._servo import ServoModel
from ..observers._core import initial_state
from ..observers._runtime import Observer
from ..observers._system import LinearObserver, as_system, check_designed_on
from ._controller import PD
from ._devices import Actuator, Encoder

__all__ = ["LOOP_KEYS", "ServoLoop", "accepts_loop", "resolve_loop"]

#: The keyword arguments that make a :class:`ServoLoop` (and that the loop functions accept
#: instead of one).
LOOP_KEYS = ("plant", "nominal", "Ts", "controller", "observer", "sensor", "actuator")
_PLANTS = "a ServoModel, a TwoMassServo or a MujocoServo (an hpdob Plant)"


@dataclass(frozen=True, eq=False, kw_only=True)
class ServoLoop:
    r"""The sampled-data position loop of the paper's section IV, as one validated value.

    Plant (continuous, with friction), sampled PD outer loop on the nominal model, an optional
    disturbance observer in the inner loop, sensor and actuator. Simulation
    (:func:`hpdob.simulate`, :func:`hpdob.sweep`) and every analysis view
    (:func:`hpdob.closed_loop`, :func:`hpdob.closed_loop_poles`, :func:`hpdob.gang_of_four`,
    :func:`hpdob.loop_transfer`, :func:`hpdob.loop_margins`, :func:`hpdob.noise_gains`) take it
    as their first argument; they also accept its keyword arguments instead, as before.

    Parameters
    ----------
    plant : ServoModel, TwoMassServo, MujocoServo or control.TransferFunction
        The true motor (a :class:`hpdob.models.Plant`); a continuous python-control servo
        ``1/(J s^2 + b s)`` (``tf`` or ``ss``) is read by :meth:`ServoModel.from_lti`.
    nominal : ServoModel or control.TransferFunction
        The model the controller (``J_n``) and the observer use (python-control: as ``plant``).
    Ts : float
        Sampling period [s].
    controller : PD
    observer : observer, optional
        A runtime observer (:class:`~hpdob.DisturbanceObserver`, :class:`~hpdob.Observer`), a
        design (:class:`~hpdob.ObserverDesign`), a :class:`~hpdob.LinearObserver` or a labelled
        python-control ``StateSpace`` (:meth:`~hpdob.LinearObserver.from_statespace`), designed
        on ``nominal.discretize(Ts)`` (an observer without a nominal model must have the same
        ``Ts``). A runtime observer's current state is taken now (the loop does not change
        the object); a design or system starts each run from ``initial_state(x0, 0)``.
        None: PD only.
    sensor : Encoder, optional
        Default: the ideal state.
    actuator : Actuator, optional
        Default: ideal (no limit, no delay).

    Attributes
    ----------
    system : LinearObserver or None
        The observer as the linear system every consumer runs.
    observer_state : tuple or None
        The runtime observer's state at construction (None: reset at the run's ``x0``).

    Raises
    ------
    TypeError, ValueError
        Naming the argument, e.g. ``plant must be a ServoModel, ... got str``.

    Examples
    --------
    >>> from hpdob import PD, ServoLoop, ServoModel, closed_loop_poles, design_observer
    >>> nominal = ServoModel(2.8e-4)
    >>> loop = ServoLoop(plant=ServoModel(3.06e-4, 5e-5), nominal=nominal, Ts=1e-3,
    ...                  controller=PD(50, 5),
    ...                  observer=design_observer(nominal.discretize(1e-3), order=1,
    ...                                           bandwidth=100.0))
    >>> bool(abs(closed_loop_poles(loop)).max() < 1)
    True
    >>> loop.replace(observer=None).system is None
    True
    """

    plant: Plant
    nominal: ServoModel
    Ts: float
    controller: PD
    observer: object = None
    sensor: Encoder | None = None
    actuator: Actuator | None = None
    system: LinearObserver | None = field(init=False, repr=False)
    observer_state: tuple | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # python-control systems in: 1/(J s^2 + b s) as a ServoModel, an observer's StateSpace
        # as a LinearObserver (designed on the nominal model)
        object.__setattr__(self, "plant", as_servo_model(self.plant, "plant"))
        object.__setattr__(self, "nominal", as_servo_model(self.nominal, "nominal"))
        if is_lti(self.observer) and isinstance(self.nominal, ServoModel):
            Ts = positive(self.Ts, "Ts", "a positive finite sampling period [s]")
            system = LinearObserver.from_statespace(
                self.observer, model=self.nominal.discretize(Ts), name="observer"
            )
            object.__setattr__(self, "observer", system)
        if not isinstance(self.plant, Plant):
            raise ParameterTypeError(f"plant must be {_PLANTS}, got {type(self.plant).__name__}")
        require_instance(self.nominal, ServoModel, "nominal")
        Ts = positive(self.Ts, "Ts", "a positive finite sampling period [s]")
        require_instance(self.controller, PD, "controller")
        require_instance(self.sensor, Encoder, "sensor", optional=True)
        actuator = require_instance(self.actuator, Actuator, "actuator", optional=True)
        system, state = None, None
        if self.observer is not None:
            system = as_system(self.observer, "observer")
            check_designed_on(system, self.nominal, Ts)
            if isinstance(self.observer, Observer):
                state = tuple(self.observer.state.tolist())
        if self.controller.velocity == "observer" and (system is None or not system.has_velocity):
            raise ParameterValueError(
                "controller.velocity = 'observer' needs an observer with a velocity estimate "
                "(a position-only observer), got "
                + ("no observer" if system is None else f"one with outputs {system.outputs}")
            )
        object.__setattr__(self, "Ts", Ts)
        object.__setattr__(self, "actuator", actuator or Actuator())
        object.__setattr__(self, "system", system)
        object.__setattr__(self, "observer_state", state)

    def replace(self, **changes) -> ServoLoop:
        """A copy with some of the loop's arguments changed (validated like the constructor).

        Parameters
        ----------
        **changes
            New values of any of the constructor's arguments (``plant``, ``nominal``, ``Ts``,
            ``controller``, ``observer``, ``sensor``, ``actuator``).

        Returns
        -------
        ServoLoop

        Raises
        ------
        ParameterTypeError, ParameterValueError
            For an unknown argument, or a value the constructor rejects.
        """
        unknown = sorted(set(changes) - set(LOOP_KEYS))
        if unknown:
            raise ParameterTypeError(
                f"replace() got unknown argument(s) {unknown}; valid: {', '.join(LOOP_KEYS)}"
            )
        new = replace(self, **changes)
        if "observer" not in changes and self.observer_state is not None:
            # the state was taken when this loop was built, not now
            object.__setattr__(new, "observer_state", self.observer_state)
        return new

    def initial_observer_state(self, x0) -> tuple | None:
        """The observer's state at the start of a run.

        Parameters
        ----------
        x0 : sequence of 2 floats
            The plant's initial ``[theta (rad), omega (rad/s)]``.

        Returns
        -------
        tuple of float or None
            The state of the runtime observer the loop was built with, as it was then; for a
            design, the state converged on zero disturbance at ``x0``
            (:func:`hpdob.initial_state`); None without an observer.
        """
        if self.system is None:
            return None
        if self.observer_state is not None:
            return self.observer_state
        return initial_state(self.system, x0, 0.0)

    def keywords(self) -> dict:
        """The loop's arguments as a dict.

        Returns
        -------
        dict
            ``{argument: value}`` of the constructor's arguments, so that
            ``ServoLoop(**loop.keywords())`` builds an equal loop.
        """
        return {f.name: getattr(self, f.name) for f in fields(self) if f.init}


_MISSING = object()


def resolve_loop(loop, legacy: dict, where: str) -> ServoLoop:
    """``loop``, or a :class:`ServoLoop` built from the keyword arguments in ``legacy``."""
    given = {k: v for k, v in legacy.items() if v is not _MISSING}
    if loop is not None:
        if not isinstance(loop, ServoLoop):
            hint = (
                "pass the loop's parts as keyword arguments only"
                if "plant" in given
                else "pass a plant as plant=... with the loop's other keyword arguments"
            )
            raise ParameterTypeError(
                f"{where}() takes a ServoLoop as its first argument, got "
                f"{type(loop).__name__}; {hint} ({', '.join(LOOP_KEYS)}), or build a ServoLoop"
            )
        if given:
            raise ParameterTypeError(
                f"{where}() takes a ServoLoop or the loop's keyword arguments "
                f"({', '.join(LOOP_KEYS)}), not both; got a loop and {', '.join(sorted(given))}"
            )
        return require_instance(loop, ServoLoop, "loop")
    missing = [k for k in ("plant", "nominal", "Ts", "controller") if k not in given]
    if missing:
        raise ParameterTypeError(
            f"{where}() needs a ServoLoop as first argument, or the keyword arguments plant, "
            f"nominal, Ts and controller (missing: {', '.join(missing)})"
        )
    return ServoLoop(**given)


def accepts_loop(function):
    """Let ``function(loop, ...)`` also be called with the loop's keyword arguments instead.

    ``f(plant=..., nominal=..., Ts=..., controller=..., observer=..., sensor=..., actuator=...,
    **rest)`` becomes ``f(ServoLoop(...), **rest)``.
    """

    @functools.wraps(function)
    def wrapper(
        loop=None,
        /,
        *args,
        plant=_MISSING,
        nominal=_MISSING,
        Ts=_MISSING,
        controller=_MISSING,
        observer=_MISSING,
        sensor=_MISSING,
        actuator=_MISSING,
        **kwargs,
    ):
        legacy = {
            "plant": plant,
            "nominal": nominal,
            "Ts": Ts,
            "controller": controller,
            "observer": observer,
            "sensor": sensor,
            "actuator": actuator,
        }
        return function(resolve_loop(loop, legacy, function.__name__), *args, **kwargs)

    return wrapper
