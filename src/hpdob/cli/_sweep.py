"""``hpdob sweep spec.toml --out results.parquet|csv``: batch and Monte Carlo studies."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ._errors import CLIError
from ._options import output_path

__all__ = ["register"]

FORMATS = (".parquet", ".csv")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "sweep",
        help="run a grid / Monte Carlo sweep described in a TOML file",
        description="Run the scenarios of a sweep spec (a scenario as for `hpdob simulate` plus "
        "a [sweep] table with grid, vary, n, seed; see docs/sweep.md and "
        "examples/sweep_bandwidth.toml) and write one row per scenario.",
    )
    parser.add_argument("spec", type=Path, help="sweep spec (.toml)")
    parser.add_argument(
        "--out",
        type=output_path,
        required=True,
        metavar="FILE",
        help="results file: .parquet or .csv",
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--scheduler",
        metavar="ADDR",
        default=None,
        help="dask scheduler address, e.g. tcp://127.0.0.1:8786 "
        "(default: local threads on all cores)",
    )
    where.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="number of local worker threads (default: all cores)",
    )
    parser.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from .._files import atomic_path
    from ..simulation._scenario import load_sweep
    from ..simulation._sweep import sweep

    if args.scheduler is not None and not args.scheduler.strip():  # '' used to run locally
        raise CLIError(
            f"--scheduler must be a dask address like tcp://host:8786, got {args.scheduler!r}"
        )
    if args.out.suffix not in FORMATS:
        raise CLIError(f"--out must end in {' or '.join(FORMATS)}, got {str(args.out)!r}")
    if args.out.is_dir():
        raise CLIError(f"--out must be a file, got the directory {str(args.out)!r}")
    base, options = load_sweep(args.spec)
    start = time.perf_counter()
    rows = sweep(base, **options, scheduler=args.scheduler or args.workers)
    elapsed = time.perf_counter() - start
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(args.out) as temporary:  # a reader never sees a truncated table
        if args.out.suffix == ".parquet":
            rows.to_parquet(temporary, index=False)
        else:
            rows.to_csv(temporary, index=False)
    stable = int(rows["stable"].sum())
    print(
        f"{len(rows)} scenarios ({stable} stable, {len(rows) - stable} diverged or invalid) "
        f"in {elapsed:.1f} s; wrote {args.out}"
    )
    return 0
