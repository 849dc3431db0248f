"""A loop and a run written as a scenario file: the TOML that ``hpdob simulate`` reads back.

The inverse of :func:`hpdob.simulation.load_scenario` (``docs/simulation.md``): every value is
written with ``repr`` (a float reads back to the same double), so the file runs the same loop
bit for bit.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np

from .._signals import Sum
from .._validation import ParameterTypeError, ParameterValueError
from ..controllers import CONTROLLER_TYPES
from ..models import MujocoServo, ServoModel, TwoMassServo
from ..observers import ReactionObserverDesign, spec_of
from ._loop import ServoLoop

__all__ = ["scenario_toml"]

#: Signal class -> its ``type`` in a scenario file, and the fields a weight scales.
_SCALED = ("amplitude", "value", "slope", "std", "offset")


def _value(value, key: str) -> str:
    if isinstance(value, complex) and value.imag == 0.0:
        value = value.real
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ParameterValueError(f"{key} must be finite to be written, got {value!r}")
        return repr(value)
    if isinstance(value, complex):
        return json.dumps(str(complex(value)).strip("()"))
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_value(v, key) for v in value) + "]"
    raise ParameterTypeError(f"{key} cannot be written to a scenario file: {value!r}")


def _fields(obj) -> dict:
    """The constructor arguments of a dataclass, those at their default left out."""
    out = {}
    for f in dataclasses.fields(obj):
        if not f.init or f.name.startswith("_"):
            continue
        value = getattr(obj, f.name)
        if value is None or (f.default is not dataclasses.MISSING and value == f.default):
            continue
        out[f.name] = value
    return out


def _table(name: str, fields: dict, *, array: bool = False) -> list[str]:
    lines = [f"[[{name}]]" if array else f"[{name}]"]
    lines += [f"{key} = {_value(value, f'{name}.{key}')}" for key, value in fields.items()]
    return [*lines, ""]


def _signal_tables(signal, name: str) -> list[str]:
    from ._scenario import SIGNAL_TYPES

    kinds = {cls: kind for kind, cls in SIGNAL_TYPES.items()}
    terms = signal.terms if isinstance(signal, Sum) else ((1.0, signal),)
    lines = []
    for weight, term in terms:
        kind = kinds.get(type(term))
        if kind is None:
            raise ParameterTypeError(
                f"{name} must be made of {', '.join(SIGNAL_TYPES)} signals to be written to a "
                f"scenario file, got {type(term).__name__}"
            )
        fields = {f.name: getattr(term, f.name) for f in dataclasses.fields(term) if f.init}
        if weight != 1.0:
            fields = {k: weight * v if k in _SCALED else v for k, v in fields.items()}
        lines += _table(name, {"type": kind, **fields}, array=True)
    return lines


def _mujoco_fields(plant: MujocoServo) -> dict:
    """``[plant] type = "mujoco"`` of a servo built from its parameters (those at the
    constructor's default left out); a wrapped model (``from_xml``) has no file form."""
    import inspect

    if plant.link_length is None:
        raise ParameterTypeError(
            "loop.plant is a MujocoServo wrapped from MJCF (from_xml), which has no scenario-file "
            "form; only a servo built from its parameters (MujocoServo(J, b, ...)) is written"
        )
    fields = {"type": "mujoco"}
    for name, parameter in inspect.signature(MujocoServo.__init__).parameters.items():
        if name in ("self", "environment"):
            continue
        value = getattr(plant, name)
        if value is None or (parameter.default is not inspect.Parameter.empty
                             and value == parameter.default):  # fmt: skip
            continue
        fields[name] = value
    return fields


def _observer_tables(loop: ServoLoop) -> list[str]:
    """``[observer]`` and, for a reaction-torque observer composition, ``[reaction_observer]``:
    its friction model and, if it has one, the RTOB's own design."""
    design = loop.design
    if not isinstance(design, ReactionObserverDesign):
        spec = loop.observer_spec  # the spec given, or that of a design of a registered family
        outputs = getattr(getattr(loop.observer, "system", loop.observer), "outputs", ())
        if spec is None and "tau_reac" in outputs:  # a LinearObserver: its parts are gone
            raise ParameterTypeError(
                "loop.observer is a reaction-torque observer built by reaction_torque_observer"
                "(), whose DOb, RTOB and friction model a scenario file cannot recover: build "
                "it with hpdob.observers.design_reaction_observer() (same arguments) to write "
                "it as [observer] and [reaction_observer]"
            )
        if spec is None:
            raise ParameterTypeError(
                "loop.observer must be of a known family (hpdob.observers.families()) to be "
                f"written to a scenario file, got {type(loop.observer).__name__}"
            )
        return _table("observer", spec)
    tables = {}
    for part, name in (("observer", "dob"), ("reaction_observer", "reaction")):
        observer = getattr(design, name)
        spec = None if observer is None else spec_of(observer)
        if observer is not None and spec is None:
            raise ParameterTypeError(
                f"loop.observer.{name} must be of a known family (hpdob.observers.families()) "
                f"to be written to a scenario file, got {type(observer).__name__}"
            )
        tables[part] = spec or {}
    # the friction model first, then the RTOB's own design (none: the DOb itself); one that
    # follows the plant is written as such (the loop read its numbers from loop.plant)
    friction = design.friction
    if design.follows_plant:
        friction = {"friction": "plant", **{k: v for k, v in friction.items()
                                             if k in ("velocity_filter",
                                                      "coulomb_deadband")}}  # fmt: skip
    reaction = {**friction, **tables["reaction_observer"]}
    return [*_table("observer", tables["observer"]), *_table("reaction_observer", reaction)]


def scenario_toml(loop: ServoLoop, *, reference, duration: float, disturbance=None,
                  substeps: int | None = None, x0=None, label: str = "",
                  comment: str = "") -> str:  # fmt: skip
    """A scenario file that runs ``simulate(loop, reference=..., duration=..., ...)``.

    Parameters
    ----------
    loop : ServoLoop
        A rigid, two-mass or MuJoCo plant (a :class:`~hpdob.MujocoServo` built from its
        parameters), and an observer of a known family (any registered one), a
        reaction-torque observer composition of such observers
        (:func:`hpdob.observers.design_reaction_observer`: ``[observer]`` and
        ``[reaction_observer]``; the ``LinearObserver`` of
        :func:`hpdob.observers.reaction_torque_observer` is refused, its parts are not
        recoverable), or none.
    reference, disturbance : Signal
        Sums of the signal types of scenario files (``docs/simulation.md``); ``disturbance``
        optional.
    duration : float
        Simulated time [s].
    substeps : int, optional
        The run's plant sub-steps per sample (default None: not written, the plant's default).
    x0 : sequence of 2 floats, optional
        The initial ``[theta (rad), omega (rad/s)]`` (default None: not written, at rest at 0).
    label : str, optional
        The run's label (the file names ``hpdob simulate`` writes).
    comment : str, optional
        Lines written as TOML comments at the top.

    Returns
    -------
    str
        The TOML text; :func:`hpdob.simulation.load_scenario` reads it back into the same
        loop and run.

    Raises
    ------
    ParameterTypeError
        For a plant, observer or signal that has no scenario-file form (a MuJoCo model
        wrapped from MJCF, a hand-written observer, a callable).

    Examples
    --------
    >>> from hpdob import PD, ServoLoop, ServoModel, design_observer
    >>> from hpdob.signals import Step
    >>> from hpdob.simulation import scenario_toml
    >>> motor = ServoModel(2.8e-4)
    >>> loop = ServoLoop(plant=motor, nominal=motor, Ts=1e-3, controller=PD(50.0, 5.0),
    ...                  observer=design_observer(motor.discretize(1e-3), order=1,
    ...                                           bandwidth=100.0))
    >>> print(scenario_toml(loop, reference=Step(0.2, 1.0), duration=1.0))  # doctest: +ELLIPSIS
    Ts = 0.001
    duration = 1.0
    <BLANKLINE>
    [plant]
    J = 0.00028
    ...
    [observer]
    type = "dob"
    order = 1
    gain_direction = [1.0, 1.0]
    bandwidth = 100.0
    ...
    """
    if not isinstance(loop, ServoLoop):
        raise ParameterTypeError(f"loop must be a ServoLoop, got {type(loop).__name__}")
    lines = [f"# {line}".rstrip() for line in comment.splitlines()]
    if label:
        lines.append(f"label = {_value(label, 'label')}")
    lines += [f"Ts = {_value(float(loop.Ts), 'Ts')}",
              f"duration = {_value(float(duration), 'duration')}"]  # fmt: skip
    if substeps is not None:
        lines.append(f"substeps = {_value(int(substeps), 'substeps')}")
    if x0 is not None:
        lines.append(f"x0 = {_value([float(v) for v in np.ravel(x0)], 'x0')}")
    lines.append("")
    if isinstance(loop.plant, (TwoMassServo, ServoModel)):
        fields = _fields(loop.plant)
        contact = fields.pop("environment", None)  # the wall: the table [plant.environment]
        kind = {"type": "two-mass"} if isinstance(loop.plant, TwoMassServo) else {}
        lines += _table("plant", {**kind, **fields})
        if contact is not None:
            lines += _table("plant.environment", _fields(contact))
    elif isinstance(loop.plant, MujocoServo):
        lines += _table("plant", _mujoco_fields(loop.plant))
    else:
        raise ParameterTypeError(
            f"loop.plant must be a ServoModel or TwoMassServo to be written to a scenario file, "
            f"got {type(loop.plant).__name__}"
        )
    lines += _table("nominal", _fields(loop.nominal))
    kinds = [name for name, cls in CONTROLLER_TYPES.items() if type(loop.controller) is cls]
    if not kinds:
        raise ParameterTypeError(
            "loop.controller must be one of the scenario files' controller types "
            f"({', '.join(repr(k) for k in CONTROLLER_TYPES)}) to be written to a scenario file, "
            f"got {type(loop.controller).__name__}"
        )
    kind = {} if kinds[0] == "pd" else {"type": kinds[0]}
    lines += _table("controller", {**kind, **_fields(loop.controller)})
    if loop.observer is not None:
        lines += _observer_tables(loop)
    if loop.sensor is not None:
        lines += _table("sensor", _fields(loop.sensor))
    if loop.actuator is not None and _fields(loop.actuator):
        lines += _table("actuator", _fields(loop.actuator))
    lines += _signal_tables(reference, "reference")
    if disturbance is not None:
        lines += _signal_tables(disturbance, "disturbance")
    return "\n".join(lines).rstrip() + "\n"
