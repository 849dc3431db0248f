"""``hpdob sweep spec.toml --out results.parquet|csv``: batch and Monte Carlo studies."""

from __future__ import annotations

import argparse
import sys
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
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="a progress bar with the time left on stderr (default: when stderr is a terminal)",
    )
    parser.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from ..simulation._scenario import load_sweep
    from ..simulation._sweep import SweepIncomplete, sweep

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
    try:
        rows = sweep(
            base,
            **{**options, "progress": args.progress},
            scheduler=args.scheduler or args.workers,
        )
    except SweepIncomplete as failure:  # keep the finished rows; say what is missing
        if len(failure.rows):
            _write(failure.rows, args.out)
        print(
            f"hpdob sweep: error: {failure}; wrote the {len(failure.rows)} finished rows to "
            f"{args.out}; missing: scenarios {_ranges(failure.missing)}; rerun the sweep to "
            f"complete it (every row depends only on the spec and its seed)",
            file=sys.stderr,
        )
        return 1
    elapsed = time.perf_counter() - start
    _write(rows, args.out)
    stable = int(rows["stable"].sum())
    print(
        f"{len(rows)} scenarios ({stable} stable, {len(rows) - stable} diverged or invalid) "
        f"in {elapsed:.1f} s; wrote {args.out}"
    )
    return 0


def _write(rows, out: Path) -> None:
    from .._files import atomic_path

    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as temporary:  # a reader never sees a truncated table
        if out.suffix == ".parquet":
            rows.to_parquet(temporary, index=False)
        else:
            rows.to_csv(temporary, index=False)


def _ranges(numbers) -> str:
    """``[0, 1, 2, 5, 7, 8]`` as ``0-2, 5, 7-8`` (at most 10 ranges shown)."""
    spans = []
    for n in sorted(numbers):
        if spans and n == spans[-1][1] + 1:
            spans[-1][1] = n
        else:
            spans.append([n, n])
    text = [f"{a}-{b}" if b > a else f"{a}" for a, b in spans[:10]]
    return ", ".join(text) + (f" and {len(spans) - 10} more ranges" if len(spans) > 10 else "")
