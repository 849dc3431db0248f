"""Scenarios described in TOML: parsed into the keyword arguments of :func:`hpdob.simulate`.

Every error names the key (``plant.J``, ``disturbance[2].type``, ...) and the offending value.
The format is documented in ``docs/simulation.md``; ``examples/*.toml`` are runnable examples.
"""

from __future__ import annotations

import dataclasses
import sys
import types
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from .._signals import Constant, Ramp, SmoothStep, Step
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    check_choice,
    check_keys,
)
from .._waveforms import Chirp, Noise, Sine
from ..controllers import CONTROLLER_TYPES
from ..models import Environment, MujocoServo, ServoModel, TwoMassServo
from ..observers import (
    FRICTION_PARAMETERS,
    check_spec,
    coulomb_velocity_resolution,
    design_from_spec,
    design_reaction_observer,
    get_family,
)
from ._devices import Actuator, Encoder
from ._loop import LOOP_KEYS, ServoLoop
from ._plant_types import PlantType, get_plant_type, register_plant_type
from ._result import CANONICAL_WINDOWS, metric_window
from ._simulate import check_run_arguments, simulate

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "RUN_KEYS",
    "SIGNAL_TYPES",
    "Scenario",
    "load_metric_windows",
    "load_scenario",
    "load_sweep",
    "metric_windows",
    "plant_type_of",
    "scenario_from_dict",
    "scenario_of",
]

SIGNAL_TYPES = {
    "constant": Constant,
    "step": Step,
    "ramp": Ramp,
    "smooth_step": SmoothStep,
    "sine": Sine,
    "chirp": Chirp,
    "noise": Noise,
}
TOP_LEVEL = (
    "label",
    "Ts",
    "duration",
    "substeps",
    "x0",
    "plant",
    "nominal",
    "controller",
    "observer",
    "reaction_observer",
    "sensor",
    "actuator",
    "reference",
    "disturbance",
    "metrics",
)
#: The keys of ``[reaction_observer]`` that are the friction model
#: (:func:`hpdob.observers.reaction_torque_observer`); any other key is the RTOB's own observer.
FRICTION_KEYS = (*FRICTION_PARAMETERS, "friction")
#: Controller types that read ``tau_reac`` (they need a ``[reaction_observer]``).
REACTION_CONTROLLERS = ("force", "impedance", "position-force")
REQUIRED = ("Ts", "duration", "plant", "nominal", "controller", "reference")
SWEEP_KEYS = ("grid", "vary", "n", "seed")


def _prefixed(key: str, err: Exception, names) -> Exception:
    """Re-raise a validation error with its parameter name qualified by ``key``
    (``J must be ...`` from ``[plant]`` becomes ``plant.J must be ...``); a message that does
    not start with one of the table's ``names`` is prefixed as ``key: message``."""
    cls = ParameterTypeError if isinstance(err, TypeError) else ParameterValueError
    text = str(err)
    first = text.split(" ", 1)[0].split("[", 1)[0]
    return cls(f"{key}.{text}" if first in names else f"{key}: {text}")


def _table(data: dict, key: str) -> dict:
    value = data[key]
    if not isinstance(value, dict):
        raise ParameterTypeError(f"{key} must be a table, got {value!r}")
    return value


def _build(cls, fields: dict, key: str, allowed=None, required=None):
    """``cls(**fields)`` with unknown and missing keys and bad values reported as ``key.name``."""
    if allowed is None:  # a dataclass: its public init fields
        params = [f for f in dataclasses.fields(cls) if f.init and not f.name.startswith("_")]
        allowed = [f.name for f in params]
        required = [f.name for f in params if f.default is dataclasses.MISSING]
    check_keys(fields, allowed, key)
    missing = [name for name in required or () if name not in fields]
    if missing:
        raise ParameterValueError(f"missing required key {key}.{missing[0]}")
    try:
        return cls(**fields)
    except (ParameterTypeError, ParameterValueError) as err:
        raise _prefixed(key, err, allowed) from None


def _controller(table: dict):
    """The ``[controller]`` table: ``type`` (:data:`hpdob.controllers.CONTROLLER_TYPES`,
    default ``"pd"``) and the constructor's arguments."""
    fields = dict(table)
    kind = fields.pop("type", "pd")
    if kind not in CONTROLLER_TYPES:
        raise ParameterValueError(
            f"controller.type must be one of {', '.join(repr(k) for k in CONTROLLER_TYPES)}; "
            f"got {kind!r}"
        )
    return _build(CONTROLLER_TYPES[kind], fields, "controller")


def _signal(spec, key: str):
    if not isinstance(spec, dict):
        raise ParameterTypeError(f"{key} must be a table with a 'type' key, got {spec!r}")
    fields = dict(spec)
    kind = fields.pop("type", None)
    try:
        check_choice(kind, f"{key}.type", SIGNAL_TYPES)
    except ParameterValueError:
        raise ParameterValueError(
            f"{key}.type must be one of {', '.join(repr(k) for k in SIGNAL_TYPES)}; got {kind!r}"
        ) from None
    cls = SIGNAL_TYPES[kind]
    return _build(cls, fields, key)


def _signal_sum(specs, key: str):
    if isinstance(specs, dict):
        specs = [specs]
    if not isinstance(specs, list) or not specs:
        raise ParameterValueError(
            f"{key} must be one table or a non-empty array of tables ([[{key}]]), got {specs!r}"
        )
    total = None
    for i, spec in enumerate(specs):
        signal = _signal(spec, f"{key}[{i}]")
        total = signal if total is None else total + signal
    return total


def _poles(values, key: str):
    if not isinstance(values, list):
        raise ParameterTypeError(
            f"{key} must be an array of numbers or strings like '0.9+0.1j', got {values!r}"
        )
    poles = []
    for i, value in enumerate(values):
        if isinstance(value, str):
            try:
                value = complex(value.replace(" ", ""))
            except ValueError:
                raise ParameterValueError(
                    f"{key}[{i}] must be a number or a complex number "
                    f"like '0.9+0.1j', got {value!r}"
                ) from None
        poles.append(value)
    return poles


def metric_windows(data: dict) -> dict:
    """The ``[metrics]`` table of a parsed scenario: ``{"regulation": (start, stop),
    "tracking": (start, stop)}`` [s], each defaulting to :data:`CANONICAL_WINDOWS`."""
    windows = dict(CANONICAL_WINDOWS)
    if "metrics" in data:
        table = _table(data, "metrics")
        check_keys(table, tuple(CANONICAL_WINDOWS), "metrics")
        for name, bounds in table.items():
            windows[name] = metric_window(bounds, f"metrics.{name}")
    return windows


def scenario_from_dict(data: dict, *, build_observer: bool = True) -> dict:
    """Keyword arguments of :func:`hpdob.simulate` from a parsed TOML document.

    The ``observer`` entry is the design of the ``[observer]`` table (a loop resets it at the
    run's ``x0``); with ``build_observer=False`` it stays the table, a family spec (what
    :func:`hpdob.sweep` takes).
    """
    if not isinstance(data, dict):
        raise ParameterTypeError(f"a scenario must be a table, got {type(data).__name__}")
    check_keys(data, TOP_LEVEL)
    missing = [k for k in REQUIRED if k not in data]
    if missing:
        raise ParameterValueError(
            f"missing required key {missing[0]}; a scenario needs {', '.join(REQUIRED)}"
        )
    metric_windows(data)  # checked here; read with metric_windows() / load_metric_windows()
    # Top-level scalars are checked here, with simulate()'s messages, not at run time.
    Ts, duration, substeps, x0 = check_run_arguments(
        data["Ts"], data["duration"], data.get("substeps"), data.get("x0", (0.0, 0.0))
    )
    kwargs = {"Ts": Ts, "duration": duration}
    if "substeps" in data:
        kwargs["substeps"] = substeps
    if "x0" in data:
        kwargs["x0"] = tuple(x0.tolist())
    if "label" in data:
        if not isinstance(data["label"], str):
            raise ParameterTypeError(
                f"label must be a str, got {data['label']!r} of type {type(data['label']).__name__}"
            )
        kwargs["label"] = data["label"]
    kwargs["plant"] = _plant(_table(data, "plant"))
    kwargs["nominal"] = _build(ServoModel, _table(data, "nominal"), "nominal")
    kwargs["controller"] = _controller(_table(data, "controller"))
    kwargs["reference"] = _signal_sum(data["reference"], "reference")
    if "disturbance" in data:
        kwargs["disturbance"] = _signal_sum(data["disturbance"], "disturbance")
    if "sensor" in data:
        sensor = dict(_table(data, "sensor"))
        kind = sensor.pop("type", "encoder")
        if kind == "encoder":
            kwargs["sensor"] = _build(Encoder, sensor, "sensor")
        elif kind != "ideal" or sensor:
            raise ParameterValueError(
                f"sensor.type must be 'encoder' or 'ideal' (the latter "
                f"without other keys), got {kind!r}"
            )
    if "actuator" in data:
        kwargs["actuator"] = _build(Actuator, _table(data, "actuator"), "actuator")
    if "observer" in data:
        spec = _with_poles(_table(data, "observer"), "observer")
        model = kwargs["nominal"].discretize(kwargs["Ts"])
        design = _observer(model, spec)  # validated now, with the file's key names
        kwargs["observer"] = spec if not build_observer else design
        if "reaction_observer" in data:
            # a ReactionObserverDesign: it keeps its parts, so a sweep designs it again
            table = _table(data, "reaction_observer")
            kwargs["observer"] = _reaction_observer(model, design, table, kwargs["plant"],
                                                    kwargs.get("sensor"))  # fmt: skip
    elif "reaction_observer" in data:
        raise ParameterValueError(
            "reaction_observer needs an [observer] table: the DOb it is composed with"
        )
    kind = data["controller"].get("type", "pd")
    if kind in REACTION_CONTROLLERS and "reaction_observer" not in data:
        raise ParameterValueError(
            f"controller.type = {kind!r} reads the reaction-torque estimate tau_reac: the "
            "scenario needs an [observer] and a [reaction_observer] table"
        )
    return kwargs


def _with_poles(table: dict, key: str) -> dict:
    """A copy of an observer table with its complex lists (poles) read: TOML has no complex
    numbers, so they are written as strings like ``'0.9+0.1j'``."""
    spec = dict(table)
    family = get_family(spec.get("type", "dob"), f"{key}.type")
    for p in family.parameters:
        if p.kind == "complex_list" and p.name in spec:
            spec[p.name] = _poles(spec[p.name], f"{key}.{p.name}")
    return spec


def _observer(model, spec: dict, key: str = "observer"):
    """The design ``spec`` (an ``[observer]`` table) describes, errors named ``observer.*``."""
    family = get_family(spec.get("type", "dob"), f"{key}.type")
    check_keys(spec, (*family.keys, "type"), key)
    missing = [name for name in family.required if name not in spec]
    if missing:
        raise ParameterValueError(f"missing required key {key}.{missing[0]}")
    check_spec(spec, key)
    try:
        return design_from_spec(model, spec)
    except (ParameterTypeError, ParameterValueError) as err:
        raise _prefixed(key, err, ("type", *family.keys)) from None


def _reaction_observer(model, dob, table: dict, plant, sensor=None):
    """The ``[reaction_observer]`` table: the DOb composed with an RTOB
    (:func:`hpdob.observers.design_reaction_observer`). Its :data:`FRICTION_KEYS` are the
    friction model (``friction = "plant"``: the ``[plant]``'s ``b``, ``coulomb``,
    ``coulomb_velocity``, which the design follows: ``follows_plant=True``;
    ``coulomb_deadband = "encoder"``: the ``[sensor]``'s velocity resolution through the
    term's velocity path, :func:`hpdob.observers.coulomb_velocity_resolution`); any other keys
    are the RTOB's own observer (a family spec, like ``[observer]``; none: the DOb itself).
    Errors are named ``reaction_observer.*``."""
    fields = dict(table)
    options = {key: fields.pop(key) for key in FRICTION_KEYS if key in fields}
    deadband = options.get("coulomb_deadband")
    if isinstance(deadband, str) and deadband != "encoder":
        raise ParameterValueError(
            "reaction_observer.coulomb_deadband must be a non-negative dead band [rad/s] or "
            f"'encoder', got {deadband!r}"
        )
    from_encoder = deadband == "encoder"
    if from_encoder:
        if not isinstance(sensor, Encoder) or sensor.velocity != "backward-difference":
            raise ParameterValueError(
                "reaction_observer.coulomb_deadband = 'encoder' needs a [sensor] encoder with "
                f"backward-difference velocity, got {sensor!r}"
            )
        options["coulomb_deadband"] = 0.0
    if "friction" in options:
        if options["friction"] != "plant":
            raise ParameterValueError(
                "reaction_observer.friction must be 'plant' (the [plant] table's b, coulomb and "
                f"coulomb_velocity), got {options['friction']!r}"
            )
        if not isinstance(plant, ServoModel):
            raise ParameterValueError(
                "reaction_observer.friction = 'plant' needs a rigid [plant] (a ServoModel), got "
                f"{type(plant).__name__}"
            )
        given = [key for key in ("viscous", "coulomb", "coulomb_velocity") if key in options]
        if given:  # else coulomb_velocity would be silently replaced by the plant's
            raise ParameterValueError(
                f"reaction_observer.{given[0]} = {options[given[0]]!r} cannot be given with "
                "friction = 'plant' (the [plant] table's b, coulomb and coulomb_velocity): "
                "change them in [plant], or leave friction out and give the numbers"
            )
        # the design remembers that its friction model is the plant's: a loop with another
        # plant (a sweep's plant.* rows) reads that plant's
        options["friction"], options["follows_plant"] = plant, True
    reaction = None
    if fields:
        fields = _with_poles(fields, "reaction_observer")
        reaction = _observer(model, fields, "reaction_observer")
    try:
        design = design_reaction_observer(dob, reaction, **options)
        if from_encoder:  # the resolution of the term's own velocity path, then the term again
            if not design.coulomb:
                raise ParameterValueError(
                    "coulomb_deadband = 'encoder' is the Coulomb term's dead band, but coulomb "
                    "is 0; leave it out"
                )
            options["coulomb_deadband"] = coulomb_velocity_resolution(
                design.system, counts_per_rev=sensor.counts_per_rev
            )
            design = design_reaction_observer(dob, reaction, **options)
        return design
    except (ParameterTypeError, ParameterValueError) as err:
        raise _prefixed("reaction_observer", err, FRICTION_KEYS) from None


def _with_environment(fields: dict, key: str) -> dict:
    """``[plant.environment]`` as an :class:`~hpdob.Environment`, errors named
    ``plant.environment.*``."""
    if "environment" in fields:
        contact = fields["environment"]
        if not isinstance(contact, dict):
            raise ParameterTypeError(
                f"{key}.environment must be a table (stiffness, damping, position), got {contact!r}"
            )
        fields = {**fields, "environment": _build(Environment, contact, f"{key}.environment")}
    return fields


#: The keys of ``[plant] type = "mujoco"`` (a :class:`~hpdob.MujocoServo` built from them).
MUJOCO_SERVO_KEYS = ("J", "b", "coulomb", "link_mass", "link_length", "timestep", "integrator",
                     "wall")  # fmt: skip


def _rigid(fields: dict, key: str, base) -> ServoModel:
    return _build(ServoModel, _with_environment(fields, key), key)


def _two_mass(fields: dict, key: str, base) -> TwoMassServo:
    return _build(TwoMassServo, _with_environment(fields, key), key)


def _mujoco_servo(fields: dict, key: str, base) -> MujocoServo:
    if "environment" in fields:  # MuJoCo's own contact instead: a wall the link presses
        raise ParameterValueError(
            f"{key}.environment: a MuJoCo plant cannot carry an Environment; give it a wall "
            f"the link presses ({key}.wall [rad] with {key}.link_length)"
        )
    return _build(MujocoServo, fields, key, allowed=MUJOCO_SERVO_KEYS, required=("J",))


# the single-axis plant types; packages above register theirs (hpdob.robots: the arms)
for _name, _builder, _what in (
    ("rigid", _rigid, "a rigid axis, ServoModel (the default)"),
    ("two-mass", _two_mass, "motor and load on a spring, TwoMassServo"),
    ("mujoco", _mujoco_servo, "a servo simulated by MuJoCo, MujocoServo"),
):
    register_plant_type(PlantType(_name, _builder, description=_what), replace=True)


def plant_type_of(data) -> PlantType | None:
    """The registered type of a parsed document's ``[plant]`` table (default ``"rigid"``); None
    without a ``[plant]`` table (the reader reports it)."""
    plant = data.get("plant") if isinstance(data, dict) else None
    if not isinstance(plant, dict):
        return None
    return get_plant_type(plant.get("type", "rigid"), "plant.type")


def _plant(table: dict):
    fields = dict(table)
    kind = get_plant_type(fields.pop("type", "rigid"), "plant.type")
    if kind.scenario is not None:
        raise ParameterValueError(
            f"plant.type {kind.name!r} ({kind.description}) is run by its own loop, not "
            "simulate(): read the file with load_scenario"
        )
    return kind.build(fields, "plant", None)


#: Largest scenario or sweep file [bytes]: a scenario is a few hundred bytes, a sweep's explicit
#: grid a few kilobytes; a 60 MB TOML file took minutes to parse.
MAX_SCENARIO_BYTES = 1 << 20


def read_toml(path: Path) -> dict:
    try:
        with open(path, "rb") as handle:  # at most one byte more than allowed: FIFOs too
            data = handle.read(MAX_SCENARIO_BYTES + 1)
    except OSError as err:
        raise ParameterValueError(
            f"cannot read scenario file {str(path)!r}: {err.strerror}"
        ) from None
    if len(data) > MAX_SCENARIO_BYTES:
        size = path.stat().st_size if path.is_file() else None
        asked = f"{size} bytes" if size else f"more than {MAX_SCENARIO_BYTES} bytes"
        raise ParameterValueError(
            f"scenario file {str(path)!r} has {asked}; at most {MAX_SCENARIO_BYTES} bytes "
            f"(1 MiB) are read"
        )
    try:
        text = data.decode("utf-8-sig")  # TOML is UTF-8 (a byte-order mark is tolerated)
    except UnicodeDecodeError as err:
        utf16 = data[:2] in (b"\xff\xfe", b"\xfe\xff")
        raise ParameterValueError(
            f"{path} is not UTF-8 text ({'it looks like UTF-16; ' if utf16 else ''}byte "
            f"{err.start} is {data[err.start : err.start + 1]!r}): TOML files must be saved as "
            f"UTF-8"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ParameterValueError(f"{path} is not valid TOML: {err}") from None
    except RecursionError:
        raise ParameterValueError(
            f"{path} nests tables or arrays too deeply to be a scenario"
        ) from None


def load_sweep(path) -> tuple[dict, dict]:
    """Read a sweep spec: a scenario plus a ``[sweep]`` table (``grid``, ``vary``, ``n``,
    ``seed``). Returns ``(base, options)`` for ``hpdob.sweep(base, **options)``."""
    data = dict(read_toml(Path(path)))
    options = data.pop("sweep", None)
    if not isinstance(options, dict):
        raise ParameterValueError(
            f"a sweep spec needs a [sweep] table with {', '.join(SWEEP_KEYS)}; got {options!r}"
        )
    check_keys(options, SWEEP_KEYS, "sweep")
    base = scenario_from_dict(data, build_observer=False)
    base.pop("label", None)
    return base, {**options, "metric_windows": metric_windows(data)}


#: The run settings of a scenario: :func:`hpdob.simulate`'s arguments besides the loop.
RUN_KEYS = ("duration", "reference", "disturbance", "substeps", "x0", "label")


@dataclass(frozen=True, eq=False)
class Scenario:
    """A scenario file read by :func:`load_scenario`: the loop and the run settings.

    Attributes
    ----------
    loop : ServoLoop
        Plant, nominal model, ``Ts``, controller, observer (its spec: the loop designs it on
        the nominal model), sensor and actuator.
    run : mapping
        :func:`hpdob.simulate`'s other arguments the file gives: ``duration``,
        ``reference`` and, where given, ``disturbance``, ``substeps``, ``x0``; ``label``.
    """

    loop: ServoLoop
    run: Mapping

    def simulate(self):
        """Run it: ``simulate(self.loop, **self.run)``.

        Returns
        -------
        SimulationResult
        """
        return simulate(self.loop, **self.run)

    def __getitem__(self, key):
        raise TypeError(_MOVED)

    def __iter__(self):
        raise TypeError(_MOVED)

    def keys(self):
        """Refused: a Scenario is not simulate()'s keyword arguments (see the message).

        Returns
        -------
        None
            Never: it always raises.

        Raises
        ------
        TypeError
            Always, with the call that replaces ``simulate(**load_scenario(path))``.
        """
        raise TypeError(_MOVED)


_MOVED = (
    "load_scenario returns a Scenario (a ServoLoop and the run settings; docs/changelog.md), "
    "not simulate()'s keyword arguments: call simulate(scenario.loop, **scenario.run) or "
    "scenario.simulate(), and read scenario.loop.plant, scenario.run['label'], ..."
)


def scenario_of(kwargs: dict) -> Scenario:
    """The :class:`Scenario` of simulate()'s keyword arguments (``observer`` a spec)."""
    loop = ServoLoop(**{k: v for k, v in kwargs.items() if k in LOOP_KEYS})
    run = types.MappingProxyType({k: v for k, v in kwargs.items() if k in RUN_KEYS})
    return Scenario(loop, run)


def load_scenario(path) -> Scenario:
    """Read a TOML scenario file: a :class:`~hpdob.ServoLoop` and the run settings.

    The format (``[plant]`` of a registered type, :func:`plant_types`: ``"rigid"``,
    ``"two-mass"``, ``"mujoco"``; ``[nominal]``, ``[controller]``, ``[observer]`` of any
    family, ``[sensor]``, ``[actuator]``, ``reference`` and ``disturbance`` signal lists,
    ``Ts``, ``duration``) is documented in ``docs/simulation.md``; ``examples/*.toml`` are
    runnable examples; ``hpdob simulate FILE`` runs one from the command line. A plant type
    with a loop of its own gives that loop's scenario: ``"two-link-arm"`` and
    ``"mujoco-arm"`` an :class:`hpdob.robots.ArmScenario` (an :class:`~hpdob.robots.ArmLoop`,
    ``docs/robots.md``).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.toml`` file (UTF-8).

    Returns
    -------
    Scenario
        ``.loop``: a :class:`~hpdob.ServoLoop` (plant, nominal, ``Ts``, controller and, when
        the file gives them, the observer's spec, which the loop designs on the nominal
        model, sensor, actuator); ``.run``: ``duration``, ``reference`` and, when given,
        ``disturbance``, ``substeps``, ``x0``, and ``label`` (default: the file's stem). Run
        it with ``simulate(scenario.loop, **scenario.run)`` or ``scenario.simulate()``
        (which runs an arm's loop with :func:`hpdob.robots.simulate_arm`).

    Raises
    ------
    ValueError
        If the file cannot be read, is not UTF-8 TOML, or a key or value is wrong; the message
        names the key (``plant.J``, ``disturbance[2].type``, ...) and the value.
    TypeError
        If a value has the wrong type (named the same way).

    Examples
    --------
    >>> from hpdob.simulation import load_scenario, simulate
    >>> scenario = load_scenario("examples/canonical_hpdob.toml")  # doctest: +SKIP
    >>> result = simulate(scenario.loop, **scenario.run)                   # doctest: +SKIP
    """
    path = Path(path)
    data = read_toml(path)
    kind = plant_type_of(data)
    if kind is not None and kind.scenario is not None:  # a loop of its own (an N-joint arm)
        return kind.scenario(data, path)
    kwargs = scenario_from_dict(data, build_observer=False)
    kwargs.setdefault("label", path.stem)
    return scenario_of(kwargs)


def load_metric_windows(path) -> dict:
    """The metric windows of a TOML scenario file (its ``[metrics]`` table, see
    :func:`metric_windows`), as keyword arguments of :meth:`SimulationResult.metrics`."""
    return metric_windows(read_toml(Path(path)))
