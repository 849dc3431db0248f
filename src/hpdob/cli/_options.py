"""Command-line options shared by the subcommands, defined once so that a flag means one thing.

``--J-n/--b-n`` are the nominal model (controller and observer) in every subcommand, defaulting
to the paper's nominal model; ``--J/--b`` are the true plant, and exist only where a plant does
(a subcommand without a plant rejects them with a pointer to ``--J-n/--b-n``).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..paper import CONTROLLER, NOMINAL, PLANT, TS

__all__ = [
    "add_controller_arguments",
    "add_loop_arguments",
    "add_nominal_arguments",
    "add_scenario_overrides",
    "apply_scenario_overrides",
    "controller_from_args",
    "controller_type",
    "finite",
    "output_path",
    "reject_plant_arguments",
]


def finite(text: str) -> float:
    """A finite number (argparse type): ``expected a number, got 'abc'``."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def output_path(text: str) -> Path:
    """A non-empty path (argparse type of every ``--out``): ``--out ''`` would silently mean
    the current directory."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a non-empty path, got {text!r}")
    return Path(text)


def add_nominal_arguments(group) -> None:
    """``--J-n``, ``--b-n`` (the paper's nominal model by default) and ``--Ts``."""
    group.add_argument(
        "--J-n",
        type=finite,
        default=NOMINAL.J,
        help="nominal inertia J_n [kg m^2] of controller and observer (default: %(default)s)",
    )
    group.add_argument(
        "--b-n",
        type=finite,
        default=NOMINAL.b,
        help="nominal viscous friction b_n [N m s/rad] (default: %(default)s)",
    )
    group.add_argument(
        "--Ts", type=finite, default=TS, help="sampling period [s] (default: %(default)s)"
    )


class _NoPlant(argparse.Action):
    def __call__(self, parser, namespace, values, option_string=None):
        parser.error(
            f"{option_string} sets the true plant, and this command has none; the nominal "
            f"model is --J-n/--b-n"
        )


def reject_plant_arguments(parser: argparse.ArgumentParser) -> None:
    """Hidden ``--J``/``--b`` that fail with a pointer to ``--J-n``/``--b-n``."""
    for flag in ("--J", "--b"):
        parser.add_argument(flag, action=_NoPlant, help=argparse.SUPPRESS)


def add_loop_arguments(group) -> None:
    """The true plant (``--J``, ``--b``), the PD gains and the actuator delay."""
    group.add_argument(
        "--J", type=finite, default=PLANT.J, help="true inertia [kg m^2] (%(default)s)"
    )
    group.add_argument(
        "--b", type=finite, default=PLANT.b, help="true viscous friction [N m s/rad] (%(default)s)"
    )
    add_controller_arguments(group)
    group.add_argument(
        "--delay", type=int, default=0, help="actuator delay [samples] (%(default)s)"
    )


#: The options of one controller type each: ``option: (--controller type, help)``.
CONTROLLER_OPTIONS = {
    "--ki": ("pid", "PID integral gain ki [1/s^3] (needed by --controller pid)"),
    "--tracking-time": ("pid",
                        "PID anti-windup tracking time [s] (default: sqrt(kd/ki))"),
    "--time-constant": ("filtered-pd",
                        "derivative filter time constant T_f [s] (needed by --controller "
                        "filtered-pd)"),
    "--adrc-bandwidth": ("adrc",
                         "ADRC closed-loop bandwidth w_c [rad/s] (needed by --controller adrc)"),
    "--adrc-observer-bandwidth": ("adrc",
                                  "bandwidth of ADRC's own ESO [rad/s] (default: 5 w_c)"),
}  # fmt: skip


#: The ``--controller`` types a command line builds: the servo loop's. The force controllers
#: (force, impedance, position-force) read a reaction-torque estimate and push on a wall, which
#: only a scenario file describes (``hpdob simulate``, docs/force-control.md).
SERVO_CONTROLLERS = ("pd", "pid", "filtered-pd", "adrc")


def controller_type(text: str) -> str:
    """argparse type of ``--controller``: a :data:`SERVO_CONTROLLERS` name; a force controller
    is refused with a pointer to ``hpdob simulate``, not run as a PD."""
    from ..controllers import CONTROLLER_TYPES

    if text in SERVO_CONTROLLERS:
        return text
    accepted = ", ".join(SERVO_CONTROLLERS)
    if text in CONTROLLER_TYPES:
        raise argparse.ArgumentTypeError(
            f"{text!r} needs a wall and a reaction-torque observer, which this command does not "
            f"build; it runs {accepted}. Run {text!r} with 'hpdob simulate SCENARIO.toml' "
            f'([controller] type = "{text}" and a [reaction_observer], docs/force-control.md)'
        )
    raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from {accepted})")


def add_controller_arguments(group) -> None:
    """``--controller`` (a scenario file's ``[controller] type``, of :data:`SERVO_CONTROLLERS`),
    ``--kp``, ``--kd`` and the options of each type (:data:`CONTROLLER_OPTIONS`); see
    :func:`controller_from_args`."""
    group.add_argument(
        "--controller",
        type=controller_type,
        default="pd",
        metavar="{" + ",".join(SERVO_CONTROLLERS) + "}",
        help="the outer loop, as a scenario file's [controller] type (default: %(default)s; "
        "the force controllers: 'hpdob simulate' with a scenario file)",
    )
    group.add_argument(
        "--kp",
        type=finite,
        default=None,
        help=f"gain kp [1/s^2] of pd, pid, filtered-pd ({CONTROLLER.kp:g})",
    )
    group.add_argument(
        "--kd",
        type=finite,
        default=None,
        help=f"gain kd [1/s] of pd, pid, filtered-pd ({CONTROLLER.kd:g})",
    )
    for option, (_, text) in CONTROLLER_OPTIONS.items():
        group.add_argument(option, type=finite, default=None, help=text)  # fmt: skip


def controller_from_args(args, *, velocity: str = "measured", feedforward: bool = True):
    """The controller of ``--controller`` and its options, the paper's PD gains by default.

    ``velocity`` (``"measured"`` or ``"observer"``) and ``feedforward`` apply to the types
    that have them (pd, pid, filtered-pd). An option of another type, or a type's option left
    out, is refused with the option named (``CLIError``); values are checked by the
    controller's constructor.
    """
    from ..controllers import ADRC, PD, PID, FilteredPD
    from ._errors import CLIError

    kind = args.controller
    if kind not in SERVO_CONTROLLERS:  # never a PD in its place (argparse refused it already)
        raise CLIError(f"--controller must be one of {', '.join(SERVO_CONTROLLERS)}, got {kind!r}")
    for option, (owner, _) in CONTROLLER_OPTIONS.items():
        if getattr(args, name_of(option)) is not None and owner != kind:
            raise CLIError(f"{option} applies to --controller {owner} only, not {kind}")
    if kind == "adrc":
        for option in ("--kp", "--kd"):
            if getattr(args, name_of(option)) is not None:
                raise CLIError(f"{option} applies to --controller pd, pid, filtered-pd, not adrc")
    needed = {"pid": "--ki", "filtered-pd": "--time-constant", "adrc": "--adrc-bandwidth"}
    if kind in needed and getattr(args, name_of(needed[kind])) is None:
        raise CLIError(f"--controller {kind} needs {needed[kind]} "
                       f"({CONTROLLER_OPTIONS[needed[kind]][1].split(' (')[0]})")  # fmt: skip
    if kind == "adrc":
        return ADRC(args.adrc_bandwidth, observer_bandwidth=args.adrc_observer_bandwidth)
    kp = CONTROLLER.kp if args.kp is None else args.kp
    kd = CONTROLLER.kd if args.kd is None else args.kd
    common = {"feedforward": feedforward, "velocity": velocity}
    if kind == "pid":
        return PID(kp, args.ki, kd, tracking_time=args.tracking_time, **common)
    if kind == "filtered-pd":
        return FilteredPD(kp, kd, time_constant=args.time_constant, **common)
    return PD(kp, kd, **common)


def name_of(option: str) -> str:
    """The argparse destination of ``option`` (``--tracking-time`` -> ``tracking_time``)."""
    return option.lstrip("-").replace("-", "_")


def add_scenario_overrides(parser) -> None:
    """``--measurement`` and ``--pd-velocity``: a scenario file's observer measurement and PD
    velocity, overridden (:func:`apply_scenario_overrides`). Both change the run's loop, so
    ``hpdob simulate`` and ``hpdob build-loop`` take them alike."""
    parser.add_argument(
        "--measurement",
        choices=("state", "position"),
        default=None,
        help="override the [observer] table's measurement: angle and velocity (state) or the "
        "angle only (position); the other family's gain_direction/velocity_bandwidth is dropped",
    )
    parser.add_argument(
        "--pd-velocity",
        choices=("measured", "observer"),
        default=None,
        help="override the [controller] table's velocity: the sensor's, or the position-only "
        "observer's estimate",
    )


def apply_scenario_overrides(args, data: dict) -> dict:
    """``data`` (a scenario file's tables, as ``read_toml`` gives them) with the overrides of
    :func:`add_scenario_overrides` applied; a CLIError for ``--measurement`` without an
    ``[observer]`` table. ``data`` itself is not changed."""
    from ._errors import CLIError

    data = dict(data)
    if args.measurement is not None:
        table = data.get("observer")
        if not isinstance(table, dict):
            raise CLIError(
                f"--measurement needs an [observer] table in {args.scenario}, which has none"
            )
        other = "gain_direction" if args.measurement == "position" else "velocity_bandwidth"
        data["observer"] = {
            **{k: v for k, v in table.items() if k != other},
            "measurement": args.measurement,
        }
    if args.pd_velocity is not None and isinstance(data.get("controller"), dict):
        data["controller"] = {**data["controller"], "velocity": args.pd_velocity}
    return data
