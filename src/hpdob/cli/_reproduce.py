"""``hpdob reproduce``: the main job."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ._options import output_path

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "reproduce",
        help="run the paper's scenario and write Figs. 2-5, traces and metrics",
        description="Simulate the canonical scenario (the paper's section IV): PD, DOb-50, "
        "DOb-100, DOb-200, HPDOb-100 and two virtual experiments (simulations with "
        "encoder, torque limit and delay: the HPDOb on the differenced velocity, and the "
        "recommended position-only observer). Writes fig2-fig5 (PNG and PDF), "
        "traces/<run>.csv and metrics.json, and prints a summary table.",
    )
    parser.add_argument(
        "--out",
        type=output_path,
        default=Path("hpdob-results"),
        metavar="DIR",
        help="output directory (default: %(default)s)",
    )
    parser.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from ..paper import reproduce, summary_table

    start = time.perf_counter()
    results = reproduce(args.out)
    print(summary_table({name: res.metrics() for name, res in results.items()}))
    print(
        f"\nwrote figures fig2-fig5, traces/ and metrics.json to {args.out} "
        f"in {time.perf_counter() - start:.1f} s"
    )
    return 0
