"""Command-line options shared by the subcommands, defined once so that a flag means one thing.

``--J-n/--b-n`` are the nominal model (controller and observer) in every subcommand, defaulting
to the paper's nominal model; ``--J/--b`` are the true plant, and exist only where a plant does
(a subcommand without a plant rejects them with a pointer to ``--J-n/--b-n``).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..paper._scenario import CONTROLLER, NOMINAL, PLANT, TS

__all__ = [
    "add_loop_arguments",
    "add_nominal_arguments",
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
    group.add_argument(
        "--kp", type=finite, default=CONTROLLER.kp, help="PD gain kp [1/s^2] (%(default)s)"
    )
    group.add_argument(
        "--kd", type=finite, default=CONTROLLER.kd, help="PD gain kd [1/s] (%(default)s)"
    )
    group.add_argument(
        "--delay", type=int, default=0, help="actuator delay [samples] (%(default)s)"
    )
