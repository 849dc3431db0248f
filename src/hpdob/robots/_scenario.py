r"""N-joint scenarios in TOML (``[plant] type = "mujoco-arm"`` or ``"two-link-arm"``), run by
``hpdob simulate``; the format is in ``docs/robots.md``."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from .._validation import ParameterTypeError, ParameterValueError, check_keys, positive
from ..simulation import PD, Actuator, Encoder
from ._arm_loop import ArmLoop, JointSines
from ._computed_torque import ComputedTorque
from ._mujoco_arm import MujocoArm
from ._panda import PANDA_READY, panda
from ._two_link import TwoLinkArm

__all__ = ["ARM_PLANTS", "arm_scenario_from_dict", "is_arm_scenario", "load_arm_scenario"]

#: ``[plant] type`` values of an N-joint scenario.
ARM_PLANTS = ("mujoco-arm", "two-link-arm")
TOP_LEVEL = ("label", "Ts", "duration", "substeps", "q0", "tau0", "plant", "nominal",
             "controller", "observer", "sensor", "actuator", "reference", "force",
             "metrics")  # fmt: skip
_MUJOCO_KEYS = ("type", "model", "path", "payload", "inertia_scale", "integrator", "end_effector")
_TWO_LINK_KEYS = ("type", "m", "l", "lc", "I", "J", "b", "gravity")


def is_arm_scenario(data) -> bool:
    """True if the parsed TOML document describes an N-joint arm (its ``[plant] type``)."""
    plant = data.get("plant") if isinstance(data, dict) else None
    return isinstance(plant, dict) and plant.get("type") in ARM_PLANTS


def _table(value, where):
    if not isinstance(value, dict):
        raise ParameterTypeError(f"{where} must be a table, got {type(value).__name__}")
    return value


def _arm(table, where, base: Path | None):
    table = _table(table, where)
    kind = table.get("type")
    if kind not in ARM_PLANTS:
        raise ParameterValueError(
            f"{where}.type must be one of {', '.join(map(repr, ARM_PLANTS))}, got {kind!r}"
        )
    if kind == "two-link-arm":
        check_keys(table, _TWO_LINK_KEYS, where)
        return TwoLinkArm(**{k: v for k, v in table.items() if k != "type"})
    check_keys(table, _MUJOCO_KEYS, where)
    options = {k: table[k] for k in ("payload", "inertia_scale", "integrator") if k in table}
    if ("model" in table) == ("path" in table):
        raise ParameterValueError(
            f'{where} must give one of model = "panda" or path = "<an MJCF file>", got '
            f"{'both' if 'model' in table else 'neither'}"
        )
    if "model" in table:
        if table["model"] != "panda":
            raise ParameterValueError(f'{where}.model must be "panda", got {table["model"]!r}')
        return panda(**options)
    path = Path(table["path"])
    if base is not None and not path.is_absolute():
        path = base / path
    return MujocoArm.from_xml(path, end_effector=table.get("end_effector"), **options)


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


def load_arm_scenario(path) -> tuple[ArmLoop, dict]:
    """Read an N-joint TOML scenario (``docs/robots.md``).

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
    if not is_arm_scenario(data):
        raise ParameterValueError(
            f"{path} is not an N-joint scenario: [plant] type must be one of "
            f"{', '.join(map(repr, ARM_PLANTS))}"
        )
    loop, run = arm_scenario_from_dict(data, path.parent)
    run["label"] = run["label"] or path.stem
    return loop, run
