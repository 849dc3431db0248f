"""``hpdob compare``: the paper's observers, their position-only versions, ESO and Kalman, each
tuned to the same noise gain, on the paper's scenario."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._options import (
    add_controller_arguments,
    add_nominal_arguments,
    controller_from_args,
    finite,
    output_path,
)

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "compare",
        help="compare DOb, HPDOb, order 2, their position-only versions, ESO and Kalman",
        description="Tune every observer to the same noise gain in its estimate (RMS of tau_hat "
        "per unit white angle noise, velocity by backward difference where one is taken), run "
        "the paper's scenario with the ideal sensor and/or the virtual experiment's encoder, "
        "and write comparison.csv, comparison.json, comparison.md and comparison.png. See "
        "docs/comparison.md.",
    )
    add_nominal_arguments(parser.add_argument_group("nominal model"))
    loop = parser.add_argument_group(
        "loop",
        "the true plant and the controller; defaults: the paper's (its PD), the plant scaled "
        "with J_n",
    )
    loop.add_argument(
        "--J",
        type=finite,
        default=None,
        help="true inertia [kg m^2] (default: J_n 3.06/2.8, the paper's ratio)",
    )
    loop.add_argument(
        "--b",
        type=finite,
        default=None,
        help="true viscous friction [N m s/rad] (default: 5e-5 J_n/2.8e-4)",
    )
    loop.add_argument(
        "--coulomb",
        type=finite,
        default=None,
        help="true Coulomb friction [N m] (default: 0.01 J_n/2.8e-4)",
    )
    add_controller_arguments(loop)
    parser.add_argument(
        "--sensor",
        choices=("ideal", "encoder", "both"),
        default="both",
        help="which sensor case(s) to run (default: %(default)s)",
    )
    parser.add_argument(
        "--noise-gain",
        type=finite,
        default=None,
        help="target noise gain of every estimate [N m/rad] (default: 10)",
    )
    parser.add_argument(
        "--out",
        type=output_path,
        default=Path("hpdob-comparison"),
        metavar="DIR",
        help="output directory (default: %(default)s)",
    )
    parser.add_argument("--no-plot", action="store_true", help="skip the figure")
    parser.set_defaults(handler=_run)


def _loop(args: argparse.Namespace):
    """The loop of the comparison: the paper's, at the given J_n (plant scaled with it)."""
    from ..models import ServoModel
    from ..paper import CONTROLLER, NOMINAL, PLANT
    from ..simulation import ServoLoop

    scale = args.J_n / NOMINAL.J
    plant = PLANT.replace(
        J=PLANT.J * scale if args.J is None else args.J,
        b=PLANT.b * scale if args.b is None else args.b,
        coulomb=PLANT.coulomb * scale if args.coulomb is None else args.coulomb,
    )
    controller = controller_from_args(args, feedforward=CONTROLLER.feedforward)
    return ServoLoop(plant=plant, nominal=ServoModel(args.J_n, args.b_n), Ts=args.Ts,
                     controller=controller)  # fmt: skip


def _run(args: argparse.Namespace) -> int:

    from .._files import staged_outputs
    from ..analysis import DEFAULT_NOISE_GAIN, compare_observers

    sensors = ("ideal", "encoder") if args.sensor == "both" else (args.sensor,)
    gain = DEFAULT_NOISE_GAIN if args.noise_gain is None else args.noise_gain
    comparison = compare_observers(_loop(args), sensors=sensors, noise_gain=gain)
    written = ["comparison.csv", "comparison.md"]
    # Staged and renamed together, comparison.json last (docs/reliability.md).
    with staged_outputs(
        args.out, markers=["comparison.json"], replaces=["comparison.png"]
    ) as files:  # with --no-plot a previous comparison.png goes: one consistent set
        comparison.to_csv(files.path("comparison.csv"))
        files.write_text("comparison.md", comparison.to_markdown())
        if not args.no_plot:
            files.plot("comparison.png", lambda: comparison.plot())
            written.append("comparison.png")
        files.write_json("comparison.json", comparison.to_dict())
        written.append("comparison.json")
    print(comparison.to_markdown())
    print(f"wrote {', '.join(written)} to {args.out}")
    return 0
