"""The closed loop as a value: plant, nominal model, sampling period, controller, observer,
sensor and actuator, validated once."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, fields, replace

from .._validation import ParameterTypeError, ParameterValueError, positive, require_instance
from ..controllers import LOOP_SIGNALS, Controller, LinearController, controller_system
from ..models import Plant, ServoModel, as_servo_model, is_lti
from ..observers import (
    LinearObserver,
    Observer,
    ReactionObserverDesign,
    as_system,
    check_designed_on,
    check_spec,
    design_from_spec,
    initial_state,
    spec_of,
)
from ._devices import Actuator, Encoder

__all__ = ["LOOP_KEYS", "MISSING", "ServoLoop", "accepts_loop", "loop_parts", "resolve_loop"]

#: The parts of a :class:`ServoLoop`, and the one alias rule of the functions that take a loop
#: as their first argument: instead of the loop, its parts may be given as keyword arguments of
#: these names, each meaning what the :class:`ServoLoop` argument of that name means (the
#: ``observer`` a family spec, a design or a :class:`~hpdob.LinearObserver`). ``simulate``
#: and the linear views (``closed_loop``, ``closed_loop_poles``, ``gang_of_four``,
#: ``loop_transfer``, ``loop_margins``, ``noise_gains``) take all seven; a function that sets
#: a part itself takes only the others: ``robust_stability_map`` sets the plant (its grid)
#: and the observer's bandwidth (its ``observer`` is the family spec without it) and reads
#: the actuator's delay as ``delay_samples``; ``tune`` sets the plant (the uncertainty set)
#: and the observer (its candidates); ``compare_observers`` the observer;
#: ``noise_tradeoff`` the plant, observer, sensor and actuator (the observers on the nominal
#: model). A loop and keyword parts together, or a part the function sets, raise a
#: ``TypeError`` that names them.
LOOP_KEYS = ("plant", "nominal", "Ts", "controller", "observer", "sensor", "actuator")
_PLANTS = "a ServoModel, a TwoMassServo or a MujocoServo (an hpdob Plant)"


@dataclass(frozen=True, eq=False, kw_only=True)
class ServoLoop:
    r"""The sampled-data position loop of the paper's section IV, as one validated value.

    Plant (continuous, with friction), a sampled controller of the
    :class:`~hpdob.controllers.Controller` protocol (PD, PID, ADRC, ...) on the nominal model,
    an optional disturbance observer in the inner loop, sensor and actuator. Simulation
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
    controller : Controller or LinearController
        :class:`~hpdob.PD`, :class:`~hpdob.PID`, :class:`~hpdob.FilteredPD`,
        :class:`~hpdob.ADRC`, any other :class:`~hpdob.controllers.Controller` (designed on
        ``nominal`` and ``Ts``) or a :class:`~hpdob.controllers.LinearController` at ``Ts``.
        Its inputs are wired by name: the reference and the measurement
        (:data:`hpdob.controllers.LOOP_SIGNALS`) and the observer's outputs (``tau_hat``, 0
        without an observer; ``omega_hat``; any further output an observer has).
    observer : dict, design, LinearObserver or StateSpace, optional
        A spec of a registered family (``{"type": "eso", "bandwidth": 150.0}``, see
        :func:`hpdob.observers.register_family`), which the loop designs on
        ``nominal.discretize(Ts)`` (and designs again when :meth:`replace` changes
        ``nominal`` or ``Ts``); or a fixed design (:class:`~hpdob.ObserverDesign`, ...),
        :class:`~hpdob.LinearObserver` or labelled python-control ``StateSpace``
        (:meth:`~hpdob.LinearObserver.from_statespace`) designed on ``nominal.discretize(Ts)``
        (one without a nominal model must have the same ``Ts``). Each run starts it from
        ``initial_state(x0, 0)`` unless the run is given an ``observer_state``. The loop
        holds values only: a runtime observer (:class:`~hpdob.DisturbanceObserver`, ...) is
        refused (``TypeError``); give its ``.design`` (or ``.system``) here and its state to
        the run, ``simulate(loop, ..., observer_state=obs.state)``. A reaction-torque observer
        composition whose friction model follows the plant
        (:attr:`~hpdob.observers.ReactionObserverDesign.follows_plant`, a scenario file's
        ``friction = "plant"``) is given this loop's plant's friction
        (:meth:`~hpdob.observers.ReactionObserverDesign.with_plant_friction`; a rigid plant
        only). None: no observer.
    sensor : Encoder, optional
        Default: the ideal state.
    actuator : Actuator, optional
        Default: ideal (no limit, no delay).

    Attributes
    ----------
    system : LinearObserver or None
        The observer as the linear system every consumer runs.
    controller_system : LinearController
        The controller as the linear system every consumer runs.
    design : design, LinearObserver or None
        The observer run: the design of a spec, or the fixed design/system given.
    observer_spec : dict or None
        The spec the loop designs from, or that of a fixed design of a registered family
        (:func:`hpdob.observers.spec_of`); None for any other observer.

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
    controller: Controller | LinearController
    observer: object = None
    sensor: Encoder | None = None
    actuator: Actuator | None = None
    system: LinearObserver | None = field(init=False, repr=False)
    controller_system: LinearController = field(init=False, repr=False)
    design: object = field(init=False, repr=False)
    observer_spec: dict | None = field(init=False, repr=False)

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
        controller = controller_system(self.controller, self.nominal, Ts)
        require_instance(self.sensor, Encoder, "sensor", optional=True)
        actuator = require_instance(self.actuator, Actuator, "actuator", optional=True)
        observer, system, spec = self.observer, None, None
        if isinstance(observer, dict):  # a spec: designed on this loop's nominal model
            spec = check_spec(observer, "observer")
            observer = design_from_spec(self.nominal.discretize(Ts), spec)
            object.__setattr__(self, "observer", spec)
        elif isinstance(observer, Observer):  # a state is the run's, not the loop's
            raise ParameterTypeError(runtime_observer_message(observer))
        elif isinstance(observer, ReactionObserverDesign) and observer.follows_plant:
            # the RTOB's friction model is this loop's plant's (friction = "plant"): read here,
            # so another plant (replace, a sweep's plant.* rows) brings its own friction
            observer = observer.with_plant_friction(self.plant)
            object.__setattr__(self, "observer", observer)
        if observer is not None:
            system = as_system(observer, "observer")
            check_designed_on(system, self.nominal, Ts)
            spec = spec if spec is not None else spec_of(observer)
        _check_wiring(self.controller, controller, system)
        object.__setattr__(self, "Ts", Ts)
        object.__setattr__(self, "actuator", actuator or Actuator())
        object.__setattr__(self, "system", system)
        object.__setattr__(self, "controller_system", controller)
        object.__setattr__(self, "design", observer)
        object.__setattr__(self, "observer_spec", spec)

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
        return replace(self, **changes)

    def initial_observer_state(self, x0) -> tuple | None:
        """The observer's state at the start of a run.

        Parameters
        ----------
        x0 : sequence of 2 floats
            The plant's initial ``[theta (rad), omega (rad/s)]``.

        Returns
        -------
        tuple of float or None
            The state converged on zero disturbance at ``x0`` (:func:`hpdob.initial_state`);
            None without an observer. A run given ``observer_state`` starts from that instead.
        """
        if self.system is None:
            return None
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


def runtime_observer_message(observer) -> str:
    """The one-line refusal of a runtime observer where a loop's observer is expected: its
    type, and the call to use instead (its design, and its state as the run's argument)."""
    part = "design" if getattr(observer, "design", None) is not None else "system"
    return (
        f"observer must be a family spec, a design or a LinearObserver (a loop holds values, "
        f"not state), got a runtime {type(observer).__name__}; pass observer=obs.{part} and "
        "start the run from its state: simulate(loop, ..., observer_state=obs.state)"
    )


def controller_sources(system) -> tuple:
    """The names a controller input may have in a loop with observer ``system`` (or None):
    :data:`~hpdob.controllers.LOOP_SIGNALS`, then the observer's outputs (``tau_hat`` always,
    0 without an observer)."""
    return (*LOOP_SIGNALS, *(system.outputs if system is not None else ("tau_hat",)))


def _check_wiring(spec, controller: LinearController, system) -> None:
    sources = controller_sources(system)
    for name in controller.inputs:
        if name in sources:
            continue
        if name == "omega_hat" and getattr(spec, "velocity", None) == "observer":
            raise ParameterValueError(
                "controller.velocity = 'observer' needs an observer with a velocity estimate "
                "(a position-only observer), got "
                + ("no observer" if system is None else f"one with outputs {system.outputs}")
            )
        raise ParameterValueError(
            f"controller input {name!r} must be a loop signal ({', '.join(LOOP_SIGNALS)}) or "
            "an output of the observer, got "
            + ("no observer" if system is None else f"an observer with outputs {system.outputs}")
        )


_MISSING = object()
#: The "not given" marker of the loop's keyword arguments (see :func:`loop_parts`).
MISSING = _MISSING


def resolve_loop(loop, legacy: dict, where: str, *, plant_optional: bool = False) -> ServoLoop:
    """``loop``, or a :class:`ServoLoop` built from the keyword arguments in ``legacy`` (the
    one alias table of the loop functions: :data:`LOOP_KEYS`). With ``plant_optional`` (a
    function that sets the true plant itself: the robust maps, the tuner) a missing plant is
    the nominal model."""
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
    if plant_optional and "plant" not in given and "nominal" in given:
        given["plant"] = given["nominal"]
    missing = [k for k in ("plant", "nominal", "Ts", "controller") if k not in given]
    if missing:
        raise ParameterTypeError(
            f"{where}() needs a ServoLoop as first argument, or the keyword arguments plant, "
            f"nominal, Ts and controller (missing: {', '.join(missing)})"
        )
    return ServoLoop(**given)


def loop_parts(loop, legacy: dict, where: str) -> dict:
    """The loop's parts (:data:`LOOP_KEYS`) from ``loop`` or from the keyword arguments in
    ``legacy`` (``_MISSING`` where not given), for functions that set some parts themselves
    and so cannot always build a :class:`ServoLoop` from the keywords (a robust map of a
    ``PD(velocity="observer")`` whose observer is the map's). ``observer`` is the loop's
    spec (:attr:`ServoLoop.observer_spec`) when the parts come from a loop."""
    given = {k: v for k, v in legacy.items() if v is not _MISSING}
    if loop is None:
        return given
    if not isinstance(loop, ServoLoop):
        raise ParameterTypeError(
            f"{where}() takes a ServoLoop as its first argument, got {type(loop).__name__}; "
            f"pass the loop's parts as keyword arguments ({', '.join(sorted(legacy))}) or "
            "build a ServoLoop"
        )
    if given:
        raise ParameterTypeError(
            f"{where}() takes a ServoLoop or the loop's keyword arguments "
            f"({', '.join(sorted(legacy))}), not both; got a loop and {', '.join(sorted(given))}"
        )
    return {**loop.keywords(), "observer": loop.observer_spec}


def accepts_loop(function=None, *, plant_optional: bool = False):
    """Let ``function(loop, ...)`` also be called with the loop's keyword arguments instead.

    ``f(plant=..., nominal=..., Ts=..., controller=..., observer=..., sensor=..., actuator=...,
    **rest)`` becomes ``f(ServoLoop(...), **rest)``: the one alias of every function taking a
    loop. ``@accepts_loop(plant_optional=True)`` for functions that set the plant themselves.
    """
    if function is None:
        return functools.partial(accepts_loop, plant_optional=plant_optional)

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
        resolved = resolve_loop(loop, legacy, function.__name__, plant_optional=plant_optional)
        return function(resolved, *args, **kwargs)

    return wrapper
