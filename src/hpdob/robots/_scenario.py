r"""N-joint scenarios in TOML (``[plant] type = "mujoco-arm"`` or ``"two-link-arm"``, registered
as plant types of :mod:`hpdob.simulation` when this package is imported), read by
:func:`hpdob.simulation.load_scenario` and run by ``hpdob simulate``; the format is in
``docs/robots.md``."""

from __future__ import annotations

import dataclasses
import re
import types
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    as_real,
    check_keys,
    positive,
)
from ..simulation import (
    PD,
    Actuator,
    Encoder,
    PlantType,
    Scenario,
    get_plant_type,
    plant_types,
    register_plant_type,
)
from ._arm_loop import ArmLoop, JointSines
from ._computed_torque import ComputedTorque
from ._errors import qualified
from ._mujoco_arm import MujocoArm
from ._panda import PANDA_READY, panda
from ._two_link import TwoLinkArm

__all__ = ["ArmScenario", "arm_scenario_from_dict", "load_arm_scenario"]

TOP_LEVEL = ("label", "Ts", "duration", "substeps", "q0", "tau0", "plant", "nominal",
             "controller", "observer", "sensor", "actuator", "reference", "force",
             "metrics")  # fmt: skip
_MUJOCO_KEYS = ("model", "path", "payload", "inertia_scale", "integrator", "end_effector")
_TWO_LINK_KEYS = ("m", "l", "lc", "I", "J", "b", "gravity")
_TWO_LINK_REQUIRED = ("m", "l", "lc", "I")


@dataclass(frozen=True, eq=False)
class ArmScenario(Scenario):
    """An N-joint scenario file read by :func:`hpdob.simulation.load_scenario`.

    Attributes
    ----------
    loop : ArmLoop
        The loop: plant, per-joint observers and controllers, sensors, actuators.
    run : mapping
        :func:`simulate_arm`'s other arguments: ``duration``, ``reference``, ``tau0``,
        ``label`` and, where given, ``external``, ``substeps``.
    metrics_start : float
        Start of the metrics' window [s] (``[metrics] start``).
    """

    metrics_start: float = 0.0

    def simulate(self):
        """Run it: ``simulate_arm(self.loop, **self.run)``.

        Returns
        -------
        ArmResult
        """
        from ._simulate import simulate_arm

        return simulate_arm(self.loop, **self.run)


def _table(value, where):
    if not isinstance(value, dict):
        raise ParameterTypeError(f"{where} must be a table, got {type(value).__name__}")
    return value


def _required(table, keys, where, what):
    """Refuse a table without one of ``keys``, naming the first missing one."""
    for key in keys:
        if key not in table:
            raise ParameterValueError(
                f"missing required key {where}.{key} (required keys of {what}: {', '.join(keys)})"
            )


def _two_link(fields, where, base):
    check_keys(fields, _TWO_LINK_KEYS, where)
    _required(fields, _TWO_LINK_REQUIRED, where, 'type = "two-link-arm"')
    with qualified(where, _TWO_LINK_KEYS):
        return TwoLinkArm(**fields)


def _mujoco_arm(fields, where, base):
    check_keys(fields, _MUJOCO_KEYS, where)
    with qualified(where, _MUJOCO_KEYS, {"path_or_string": "path"}):
        return _mujoco_arm_model(fields, where, base)


def _mujoco_arm_model(fields, where, base):
    options = {k: fields[k] for k in ("payload", "inertia_scale", "integrator") if k in fields}
    if ("model" in fields) == ("path" in fields):
        raise ParameterValueError(
            f'{where} must give one of model = "panda" or path = "<an MJCF file>", got '
            f"{'both' if 'model' in fields else 'neither'}"
        )
    if "model" in fields:
        if fields["model"] != "panda":
            raise ParameterValueError(f'{where}.model must be "panda", got {fields["model"]!r}')
        if fields.get("end_effector", "flange") != "flange":
            raise ParameterValueError(
                f"{where}.end_effector must be the Panda's site 'flange' (or left out), got "
                f"{fields['end_effector']!r}"
            )
        return panda(**options)
    if not isinstance(fields["path"], str):
        raise ParameterTypeError(
            f"{where}.path must be the path of an MJCF file (a string), got "
            f"{type(fields['path']).__name__}"
        )
    path = Path(fields["path"])
    if base is not None and not path.is_absolute():
        path = base / path
    return MujocoArm.from_xml(path, end_effector=fields.get("end_effector"), **options)


def _arm_types() -> list:
    return [name for name, kind in plant_types().items() if kind.scenario is _scenario]


def _arm(table, where, base: Path | None):
    table = _table(table, where)
    kind = get_plant_type(table.get("type"), f"{where}.type")
    if kind.scenario is not _scenario:
        raise ParameterValueError(
            f"{where}.type must be an N-joint arm, one of {', '.join(map(repr, _arm_types()))}, "
            f"got {kind.name!r}"
        )
    return kind.build({k: v for k, v in table.items() if k != "type"}, where, base)


def _per_joint_tables(value, where, build, n):
    """One table for every joint, or a list of ``n`` tables (``[[observer]]``)."""
    if isinstance(value, list):
        if len(value) != n:
            raise ParameterValueError(
                f"{where} must have one table per joint ({n}), got {len(value)}"
            )
        return [build(_table(v, f"{where}[{i}]"), f"{where}[{i}]") for i, v in enumerate(value)]
    return build(_table(value, where), where)


def _controller_types() -> dict:
    """``[controller] type`` -> class: the controller protocol's table where it exists."""
    try:
        from ..controllers import CONTROLLER_TYPES
    except ImportError:
        return {"pd": PD}
    return dict(CONTROLLER_TYPES)


def _joint_controller(table, where):
    types = _controller_types()
    kind = table.get("type", "pd")
    if not isinstance(kind, str) or kind not in types:
        raise ParameterValueError(
            f"{where}.type must be one of {', '.join(map(repr, types))} or "
            f'"computed-torque" (one table for all joints), got {kind!r}'
        )
    cls = types[kind]
    fields = [f for f in dataclasses.fields(cls) if f.init]
    check_keys(table, ("type", *(f.name for f in fields)), where)
    required = [f.name for f in fields if f.default is dataclasses.MISSING
                and f.default_factory is dataclasses.MISSING]  # fmt: skip
    _required(table, required, where, f"type = {kind!r}")
    with qualified(where, [f.name for f in fields]):
        return cls(**{k: v for k, v in table.items() if k != "type"})


_SENSOR_KEYS = ("counts_per_rev", "velocity", "noise_std", "seed")
_ACTUATOR_KEYS = ("torque_limit", "delay_samples")


def _sensor(table, where):
    check_keys(table, _SENSOR_KEYS, where)
    _required(table, ("counts_per_rev",), where, "an Encoder")
    with qualified(where, _SENSOR_KEYS):
        return Encoder(**table)


def _actuator(table, where):
    check_keys(table, _ACTUATOR_KEYS, where)
    with qualified(where, _ACTUATOR_KEYS):
        return Actuator(**table)


def _joint_values(value, n, where, what, check):
    """A number for every joint or a list of ``n`` numbers, each checked before conversion."""
    if not isinstance(value, list):
        return check(value, where, what)
    if len(value) != n:
        raise ParameterValueError(f"{where} must have one entry per joint ({n}), got {len(value)}")
    return [check(v, f"{where}[{i}]", what) for i, v in enumerate(value)]


def _observer_names(observers):
    """``ArmLoop``'s ``observers[i]`` as the file writes it: ``observer[i]`` for
    ``[[observer]]``, ``observer`` for one ``[observer]`` table for every joint."""
    return lambda message: (
        re.sub(r"^observers\[\d+\]", "observer", message)
        if isinstance(observers, dict)
        else re.sub(r"^observers", "observer", message)
    )


def arm_scenario_from_dict(data: dict, base: Path | None = None) -> tuple[ArmLoop, dict]:
    """The :class:`ArmLoop` and the :func:`simulate_arm` keyword arguments of a parsed document.

    Parameters
    ----------
    data : dict
        The parsed TOML document.
    base : pathlib.Path, optional
        Directory relative ``[plant] path`` entries are resolved against.

    Returns
    -------
    (ArmLoop, dict)

    Raises
    ------
    ParameterTypeError, ParameterValueError
        Naming the key (``observer[2].order``, ``actuator.torque_limit``, ...).
    """
    check_keys(data, TOP_LEVEL)
    for key in ("Ts", "duration", "plant", "controller", "reference"):
        if key not in data:
            raise ParameterValueError(f"missing required key {key} of an N-joint scenario")
    plant = _arm(data["plant"], "plant", base)
    nominal = _arm(data["nominal"], "nominal", base) if "nominal" in data else None
    n = plant.n_joints
    model = nominal or plant
    q0 = data.get("q0", "ready" if isinstance(plant, MujocoArm) and n == 7 else None)
    if q0 == "ready":
        if n != 7:
            raise ParameterValueError(
                f'q0 = "ready" is the Panda\'s ready pose (7 joints), not for this {n}-joint arm'
            )
        q0 = PANDA_READY
    elif q0 is not None:
        q0 = _joint_values(q0, n, "q0", 'a finite joint angle [rad] (or "ready")', as_real)
    Ts = positive(data["Ts"], "Ts", "a positive finite sampling period [s]")
    label = data.get("label", "")
    if not isinstance(label, str):
        raise ParameterTypeError(f"label must be a string, got {type(label).__name__}")
    tau0 = data.get("tau0", "gravity")
    if tau0 != "gravity":
        if not isinstance(tau0, list):
            raise ParameterValueError(
                f'tau0 must be "gravity" or a list of one torque [N m] per joint, got {tau0!r}'
            )
        tau0 = _joint_values(tau0, n, "tau0", "a finite torque [N m]", as_real)
    controller = data["controller"]
    if isinstance(controller, dict) and controller.get("type") == "computed-torque":
        check_keys(controller, ("type", "kp", "kd", "feedforward"), "controller")
        _required(controller, ("kp", "kd"), "controller", 'type = "computed-torque"')
        with qualified("controller", ("kp", "kd", "feedforward")):
            feedforward = controller.get("feedforward", True)
            controller = ComputedTorque(model, controller["kp"], controller["kd"],
                                        feedforward=feedforward)  # fmt: skip
    else:
        controller = _per_joint_tables(controller, "controller", _joint_controller, n)
    observers = None
    if "observer" in data:
        observers = data["observer"]
        if not isinstance(observers, (dict, list)):
            raise ParameterTypeError(
                f"observer must be a table or a list of tables, got {type(observers).__name__}"
            )
        if isinstance(observers, list):
            if len(observers) != n:
                raise ParameterValueError(
                    f"observer must have one table per joint ({n}), got {len(observers)}"
                )
            for i, table in enumerate(observers):
                _table(table, f"observer[{i}]")
    sensor = _per_joint_tables(data["sensor"], "sensor", _sensor, n) if "sensor" in data else None
    actuator = Actuator()
    if "actuator" in data:
        table = _table(data["actuator"], "actuator") if isinstance(data["actuator"], dict) else None
        if table is not None and isinstance(table.get("torque_limit"), list):
            check_keys(table, _ACTUATOR_KEYS, "actuator")
            limits = table["torque_limit"]
            if len(limits) != n:
                raise ParameterValueError(
                    f"actuator.torque_limit must have one entry per joint ({n}), got {len(limits)}"
                )
            actuator = []
            for i, limit in enumerate(limits):
                with qualified("actuator", _ACTUATOR_KEYS, {"torque_limit": f"torque_limit[{i}]"}):
                    actuator.append(Actuator(**{**table, "torque_limit": limit}))
        else:
            actuator = _per_joint_tables(data["actuator"], "actuator", _actuator, n)
    rename = _observer_names(observers)
    try:
        loop = ArmLoop(plant, Ts, controller, observers=observers, nominal=nominal, q0=q0,
                       sensor=sensor, actuator=actuator)  # fmt: skip
    except (ParameterTypeError, ParameterValueError) as err:
        raise type(err)(rename(str(err))) from None
    reference = _table(data["reference"], "reference")
    check_keys(reference, ("type", "amplitude", "frequency"), "reference")
    if reference.get("type", "joint_sines") != "joint_sines":
        raise ParameterValueError(
            f'reference.type must be "joint_sines", got {reference.get("type")!r}'
        )
    amplitude = _joint_values(reference.get("amplitude", 0.5), n, "reference.amplitude",
                              "a finite swing [rad]", as_real)  # fmt: skip
    frequency = _joint_values(reference.get("frequency", 1.0), n, "reference.frequency",
                              "a positive finite frequency [Hz]", positive)  # fmt: skip
    run = {
        "duration": positive(data["duration"], "duration", "a positive finite duration [s]"),
        "reference": JointSines(loop.q0, amplitude, frequency),
        "tau0": tau0,
        "label": label,
    }
    if "substeps" in data:
        run["substeps"] = as_int(data["substeps"], "substeps", "a positive integer",
                                 minimum=1, maximum=10_000)  # fmt: skip
    if "force" in data:
        force = _table(data["force"], "force")
        check_keys(force, ("start", "value"), "force")
        width = 3 if isinstance(plant, MujocoArm) else n
        what = "a force [N]" if width == 3 else "joint torques [N m]"
        value = force.get("value", [0.0] * width)
        if not isinstance(value, list) or len(value) != width:
            raise ParameterValueError(
                f"force.value must have {width} entries ({what}), got {value!r}"
            )
        value = np.array([as_real(v, f"force.value[{i}]", "a finite number")
                          for i, v in enumerate(value)])  # fmt: skip
        start = as_real(force.get("start", 0.0), "force.start", "a finite time [s]")
        run["external"] = lambda t: np.where(np.asarray(t)[:, None] >= start, value, 0.0)
    metrics = data.get("metrics", {})
    check_keys(_table(metrics, "metrics"), ("start",), "metrics")
    start = as_real(metrics.get("start", 0.0), "metrics.start", "a time [s] in [0, duration)")
    if not 0.0 <= start < run["duration"]:
        raise ParameterValueError(
            f"metrics.start must be in [0, duration = {run['duration']!r}) s, got {start!r}"
        )
    run["metrics_start"] = start
    return loop, run


def _scenario(data: dict, path: Path) -> ArmScenario:
    """The :class:`ArmScenario` of the parsed file ``path`` (the arms' ``PlantType.scenario``)."""
    loop, run = arm_scenario_from_dict(data, path.parent)
    start = run.pop("metrics_start")
    run["label"] = run["label"] or path.stem
    return ArmScenario(loop, types.MappingProxyType(run), metrics_start=start)


def load_arm_scenario(path) -> tuple[ArmLoop, dict]:
    """Read an N-joint TOML scenario (``docs/robots.md``).

    :func:`hpdob.simulation.load_scenario` reads the same file into an :class:`ArmScenario`.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.toml`` file.

    Returns
    -------
    (ArmLoop, dict)
        The loop and :func:`simulate_arm`'s keyword arguments (plus ``metrics_start`` [s], the
        start of the metrics' window).

    Raises
    ------
    ParameterTypeError, ParameterValueError
        A key or value is wrong (named), or the file cannot be read.
    """
    from ..simulation import read_toml

    path = Path(path)
    data = read_toml(path)
    plant = data.get("plant")
    kind = get_plant_type(plant.get("type", "rigid")) if isinstance(plant, dict) else None
    if kind is None or kind.scenario is not _scenario:
        raise ParameterValueError(
            f"{path} is not an N-joint scenario: [plant] type must be one of "
            f"{', '.join(map(repr, _arm_types()))}"
        )
    loop, run = arm_scenario_from_dict(data, path.parent)
    run["label"] = run["label"] or path.stem
    return loop, run


for _name, _build, _what in (
    ("two-link-arm", _two_link, "the built-in two-link planar arm, TwoLinkArm"),
    ("mujoco-arm", _mujoco_arm, "an MJCF arm of hinges and motors or the Panda, MujocoArm"),
):
    register_plant_type(PlantType(_name, _build, scenario=_scenario, description=_what),
                        replace=True)  # fmt: skip
