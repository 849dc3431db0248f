"""``hpdob tune``: recommend the observer for a motor, a sensor and an uncertainty."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import ClassVar

from ._errors import CLIError
from ._options import (
    add_controller_arguments,
    add_nominal_arguments,
    controller_from_args,
    finite,
    output_path,
    reject_plant_arguments,
)
from ._progress import ProgressLine, show_progress
from ._ranges import check_uncertainty_ranges

__all__ = ["register"]


def _pair(text: str) -> tuple[float, float]:
    try:
        values = [float(item) for item in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 2:
        raise argparse.ArgumentTypeError(f"expected LOW,HIGH, got {text!r}")
    return values[0], values[1]


def _frequency(text: str):
    return _pair(text) if "," in text else finite(text)


def families_of(text: str) -> list[str]:
    """The tuner's variants (:func:`hpdob.tuning.candidate_families`) ``--families`` names.

    Each item is a registered family's type (``hpdob design --type``: ``dob``, ``eso``,
    ``kalman``, any family registered since), which stands for all its variants (``dob``: the
    observers measuring the state and their position-only versions), or one variant by its
    name (``state``, ``position``, ``eso``, ``kalman``: the names ``tune(families=...)`` takes,
    kept on the command line). Anything else is refused with both spellings listed.
    """
    from ..tuning import candidate_families

    variants = candidate_families()
    of_type: dict = {}
    for name, (family, _, _) in variants.items():
        of_type.setdefault(family.name, []).append(name)
    chosen = []
    for item in (part.strip() for part in text.split(",")):
        if item in of_type:
            chosen += of_type[item]
        elif item in variants:
            chosen.append(item)
        else:
            raise CLIError(
                f"--families takes family types {', '.join(of_type)} or their variants "
                f"{', '.join(variants)}, got {item!r}"
            )
    return list(dict.fromkeys(chosen))


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "tune",
        help="recommend the observer for a motor, sensor and uncertainty, verified by simulation",
        description="Search every observer family, order and bandwidth: accuracy, sensor noise "
        "and robust stability over the inertia/friction uncertainty (with one extra sample of "
        "delay) analytically, then the robust candidates in simulation; the best is verified "
        "at every corner of the uncertainty set. Prints the recommendation and why, writes "
        "tune.json, tune.csv, tune.png and scenario.toml (the verified loop and run, for "
        "'hpdob simulate'), and can export the observer as C. See docs/tuning.md.",
    )
    add_nominal_arguments(parser.add_argument_group("nominal model"))
    reject_plant_arguments(parser)
    loop = parser.add_argument_group("loop")
    add_controller_arguments(loop)
    loop.add_argument("--counts-per-rev", type=int, default=None, help="encoder counts per rev")
    loop.add_argument("--noise-std", type=finite, default=0.0, help="angle noise std [rad] (0)")
    loop.add_argument("--delay", type=int, default=0, help="actuator delay [samples] (0)")
    loop.add_argument("--torque-limit", type=finite, default=None, help="torque limit [N m]")
    loop.add_argument("--coulomb", type=finite, default=None,
                      help="simulated Coulomb friction [N m] (0.01 J_n/2.8e-4)")  # fmt: skip
    search = parser.add_argument_group("search")
    search.add_argument("--J-range", type=_pair, default=(1.0, 1.0), metavar="LOW,HIGH",
                        help="true/nominal inertia ratios, e.g. 0.8,1.25 (1,1)")  # fmt: skip
    search.add_argument("--b-range", type=_pair, default=None, metavar="LOW,HIGH",
                        help="absolute true viscous frictions [N m s/rad] (b_n)")  # fmt: skip
    search.add_argument("--frequency", type=_frequency, default=None, metavar="F|LOW,HIGH",
                        help="disturbance frequency [Hz] or band (default: 0.1,10)")  # fmt: skip
    search.add_argument("--families", default=None, metavar="LIST",
                        help="comma-separated observer family types, as 'hpdob design --type' "
                        "(e.g. dob,eso,kalman: each with its tuner variants), or variants by "
                        "name (state, position: the dob's) (default: all)")  # fmt: skip
    search.add_argument("--objective", choices=("estimation", "position"),
                        default="estimation", help="rank by (default: %(default)s)")  # fmt: skip
    search.add_argument("--noise-limit", type=finite, default=None,
                        help="largest sensor noise in the estimate [N m RMS]")  # fmt: skip
    out = parser.add_argument_group("output")
    out.add_argument("--out", type=output_path, default=Path("hpdob-tune"), metavar="DIR",
                     help="output directory (default: %(default)s)")  # fmt: skip
    out.add_argument("--export-c", type=output_path, default=None, metavar="DIR",
                     help="also export the recommended observer as C99 into DIR")  # fmt: skip
    out.add_argument("--prefix", default="dob", help="C prefix with --export-c (dob)")
    out.add_argument("--dtype", default="double", help="C scalar type with --export-c")
    out.add_argument("--no-plot", action="store_true", help="skip the figure")
    out.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                     help="progress on stderr (default: when stderr is a terminal)")  # fmt: skip
    parser.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from .._files import staged_outputs
    from ..models import ServoModel
    from ..simulation import Actuator, Encoder, scenario_toml
    from ..tuning import tune

    if args.export_c is not None:  # checked before the search, not after it
        from .._validation import check_choice
        from ..export import DTYPES, check_directory, check_prefix

        check_prefix(args.prefix)
        check_choice(args.dtype, "dtype", DTYPES)
        check_directory(args.export_c)
    elif (args.prefix, args.dtype) != ("dob", "double"):
        raise CLIError("--prefix and --dtype apply to --export-c only")
    if args.counts_per_rev is not None and args.counts_per_rev < 1:
        raise CLIError(f"--counts-per-rev must be a positive integer, got {args.counts_per_rev}")
    sensor = None
    if args.counts_per_rev is not None or args.noise_std != 0:  # Encoder checks the values
        sensor = Encoder(args.counts_per_rev or 2**31, noise_std=args.noise_std)
    check_uncertainty_ranges(args.J_range, args.b_range, J_n=args.J_n, b_n=args.b_n)
    families = None if args.families is None else families_of(args.families)
    progress = _Progress(sys.stderr) if show_progress(args.progress) else None
    try:
        result = tune(
            nominal=ServoModel(args.J_n, args.b_n),
            Ts=args.Ts,
            controller=controller_from_args(args, velocity="observer"),
            sensor=sensor,
            actuator=Actuator(torque_limit=args.torque_limit, delay_samples=args.delay),
            J_range=args.J_range,
            b_range=args.b_range,
            disturbance_frequency=args.frequency,
            families=families,
            objective=args.objective,
            noise_limit=args.noise_limit,
            coulomb=args.coulomb,
            progress=progress,
        )
    finally:  # an error or interrupt message starts on its own line
        if progress is not None:
            progress.end()
    loop = result.loop()
    scenario = scenario_toml(
        loop, label="tuned", **result.scenario,
        comment="The loop and run 'hpdob tune' verified its recommendation in (the centre of the "
        f"uncertainty set):\n{result.recommendation['name']}, {result.recommendation['parameter']}"
        f" = {result.recommendation['value']:.6g}. Run: hpdob simulate scenario.toml",
    )  # fmt: skip
    written = ["tune.csv", "scenario.toml"]
    # Staged and renamed together, tune.json last (docs/reliability.md); the C files (their own
    # atomic pair, in their own directory) are written before the commit, so a failed export
    # leaves the previous tune.* untouched.
    with staged_outputs(args.out, markers=["tune.json"], replaces=["tune.png"]) as files:
        result.table.to_csv(files.path("tune.csv"), index=False)
        files.write_text("scenario.toml", scenario)
        if not args.no_plot:
            files.plot("tune.png", lambda: result.plot())
            written.append("tune.png")
        if args.export_c is not None:
            from ..export import export_c

            paths = export_c(result.design, args.export_c, prefix=args.prefix, dtype=args.dtype)
            written += [str(p) for p in paths]
        files.write_json("tune.json", result.to_dict())
        written.append("tune.json")
    print(result.report())
    print(f"wrote {', '.join(written)} (in {args.out})")
    return 0


class _Progress:
    """``tune``'s progress on one line of a terminal: the stage, its share done and (from the
    stage's elapsed time) an estimate of its time left; a line per stage."""

    NAMES: ClassVar[dict] = {
        "analysis": "analysing candidates",
        "simulation": "simulating the robust ones",
        "verification": "verifying at the corners",
    }

    def __init__(self, stream, clock=None):
        self.stream, self.clock = stream, clock
        self.stage, self.line = None, None

    def __call__(self, stage: str, done: int, total: int) -> None:
        if stage != self.stage:  # a new stage: its own clock and line
            self.end()
            kwargs = {} if self.clock is None else {"clock": self.clock}
            self.line = ProgressLine(f"tune: {self.NAMES[stage]}", self.stream, **kwargs)
            self.stage = stage
        self.line(done, total)

    def end(self) -> None:
        """End the current stage's line if it is left open."""
        if self.line is not None:
            self.line.end()
