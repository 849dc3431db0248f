"""``hpdob compare``: the paper's observers, their position-only versions, ESO and Kalman, each
tuned to the same noise gain, on the paper's scenario."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._options import finite, output_path

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


def _run(args: argparse.Namespace) -> int:

    from .._files import staged_outputs
    from ..analysis import compare_observers
    from ..analysis._comparison import DEFAULT_NOISE_GAIN

    sensors = ("ideal", "encoder") if args.sensor == "both" else (args.sensor,)
    gain = DEFAULT_NOISE_GAIN if args.noise_gain is None else args.noise_gain
    comparison = compare_observers(sensors=sensors, noise_gain=gain)
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
