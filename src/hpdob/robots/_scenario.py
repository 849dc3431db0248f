r"""N-joint scenarios in TOML (``[plant] type = "mujoco-arm"`` or ``"two-link-arm"``, registered
as plant types of :mod:`hpdob.simulation` when this package is imported), read by
:func:`hpdob.simulation.load_scenario` and run by ``hpdob simulate``; the format is in
``docs/robots.md``."""

from __future__ import annotations

import dataclasses
import math
import types
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, check_keys, positive
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
from ._mujoco_arm import MujocoArm
from ._panda import PANDA_READY, panda
from ._two_link import TwoLinkArm

__all__ = ["ArmScenario", "arm_scenario_from_dict", "load_arm_scenario"]

TOP_LEVEL = ("label", "Ts", "duration", "substeps", "q0", "tau0", "plant", "nominal",
             "controller", "observer", "sensor", "actuator", "reference", "force",
             "metrics")  # fmt: skip
_MUJOCO_KEYS = ("model", "path", "payload", "inertia_scale", "integrator", "end_effector")
_TWO_LINK_KEYS = ("m", "l", "lc", "I", "J", "b", "gravity")


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


def _two_link(fields, where, base):
    check_keys(fields, _TWO_LINK_KEYS, where)
    return TwoLinkArm(**fields)


def _mujoco_arm(fields, where, base):
    check_keys(fields, _MUJOCO_KEYS, where)
    options = {k: fields[k] for k in ("payload", "inertia_scale", "integrator") if k in fields}
    if ("model" in fields) == ("path" in fields):
        raise ParameterValueError(
            f'{where} must give one of model = "panda" or path = "<an MJCF file>", got '
            f"{'both' if 'model' in fields else 'neither'}"
        )
    if "model" in fields:
        if fields["model"] != "panda":
            raise ParameterValueError(f'{where}.model must be "panda", got {fields["model"]!r}')
        return panda(**options)
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
    if kind not in types:
        raise ParameterValueError(
            f"{where}.type must be one of {', '.join(map(repr, types))} or "
            f'"computed-torque" (one table for all joints), got {kind!r}'
        )
    cls = types[kind]
    check_keys(table, ("type", *(f.name for f in dataclasses.fields(cls))), where)
    return cls(**{k: v for k, v in table.items() if k != "type"})


def _sensor(table, where):
    check_keys(table, ("counts_per_rev", "velocity", "noise_std", "seed"), where)
    return Encoder(**table)


def _actuator(table, where):
    check_keys(table, ("torque_limit", "delay_samples"), where)
    return Actuator(**table)


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
        q0 = PANDA_READY
    Ts = positive(data["Ts"], "Ts", "a positive finite sampling period [s]")
    controller = data["controller"]
    if isinstance(controller, dict) and controller.get("type") == "computed-torque":
        check_keys(controller, ("type", "kp", "kd", "feedforward"), "controller")
        controller = ComputedTorque(model, controller["kp"], controller["kd"],
                                    feedforward=controller.get("feedforward", True))  # fmt: skip
    else:
        controller = _per_joint_tables(controller, "controller", _joint_controller, n)
    observers = None
    if "observer" in data:
        observers = data["observer"]
        if not isinstance(observers, (dict, list)):
            raise ParameterTypeError(
                f"observer must be a table or a list of tables, got {type(observers).__name__}"
            )
    sensor = _per_joint_tables(data["sensor"], "sensor", _sensor, n) if "sensor" in data else None
    actuator = Actuator()
    if "actuator" in data:
        table = _table(data["actuator"], "actuator") if isinstance(data["actuator"], dict) else None
        if table is not None and isinstance(table.get("torque_limit"), list):
            limits = table["torque_limit"]
            if len(limits) != n:
                raise ParameterValueError(
                    f"actuator.torque_limit must have one entry per joint ({n}), got {len(limits)}"
                )
            actuator = [_actuator({**table, "torque_limit": t}, "actuator") for t in limits]
        else:
            actuator = _per_joint_tables(data["actuator"], "actuator", _actuator, n)
    loop = ArmLoop(plant, Ts, controller, observers=observers, nominal=nominal, q0=q0,
                   sensor=sensor, actuator=actuator)  # fmt: skip
    reference = _table(data["reference"], "reference")
    check_keys(reference, ("type", "amplitude", "frequency"), "reference")
    if reference.get("type", "joint_sines") != "joint_sines":
        raise ParameterValueError(
            f'reference.type must be "joint_sines", got {reference.get("type")!r}'
        )
    run = {
        "duration": positive(data["duration"], "duration", "a positive finite duration [s]"),
        "reference": JointSines(
            loop.q0, reference.get("amplitude", 0.5), reference.get("frequency", 1.0)
        ),
        "tau0": data.get("tau0", "gravity"),
        "label": data.get("label", ""),
    }
    if "substeps" in data:
        run["substeps"] = data["substeps"]
    if "force" in data:
        force = _table(data["force"], "force")
        check_keys(force, ("start", "value"), "force")
        value = np.array(force.get("value", (0.0, 0.0, 0.0)), dtype=float)
        width = 3 if isinstance(plant, MujocoArm) else n
        if value.shape != (width,):
            raise ParameterValueError(
                f"force.value must have {width} entries "
                f"({'a force [N]' if width == 3 else 'joint torques [N m]'}), got {value.tolist()}"
            )
        start = float(force.get("start", 0.0))
        if not math.isfinite(start):
            raise ParameterValueError(f"force.start must be a finite time [s], got {start!r}")
        run["external"] = lambda t: np.where(np.asarray(t)[:, None] >= start, value, 0.0)
    metrics = data.get("metrics", {})
    check_keys(_table(metrics, "metrics"), ("start",), "metrics")
    start = float(metrics.get("start", 0.0))
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
    from ..simulation._scenario import _read_toml

    path = Path(path)
    data = _read_toml(path)
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
