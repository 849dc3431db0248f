"""``hpdob sweep spec.toml --out results.parquet|csv``: batch and Monte Carlo studies."""

from __future__ import annotations

import argparse
import contextlib
import os
import shlex
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
    parser.add_argument(
        "--resume",
        action="store_true",
        help="complete an incomplete sweep: read the rows an interrupted or failed run kept in "
        "<out>.partial.csv (or .parquet), run only the missing scenarios and write --out, "
        "equal to a run from scratch",
    )
    parser.set_defaults(handler=_run)


def partial_path(out: Path) -> Path:
    """Where the finished rows of an incomplete sweep go: ``r.csv`` -> ``r.partial.csv``
    (never ``--out`` itself: a file there is always a complete result)."""
    return out.with_name(f"{out.stem}.partial{out.suffix}")


def _run(args: argparse.Namespace) -> int:
    from .. import robots  # noqa: F401  # registers the arm plant types (registration from above)
    from .._interrupts import Interrupted, acknowledge
    from ..simulation import SweepIncomplete, SweepInterrupted, load_sweep, sweep

    if args.scheduler is not None and not args.scheduler.strip():  # '' used to run locally
        raise CLIError(
            f"--scheduler must be a dask address like tcp://host:8786, got {args.scheduler!r}"
        )
    if args.out.suffix not in FORMATS:
        raise CLIError(f"--out must end in {' or '.join(FORMATS)}, got {str(args.out)!r}")
    if args.out.is_dir():
        raise CLIError(f"--out must be a file, got the directory {str(args.out)!r}")
    partial = partial_path(args.out)
    base, options = load_sweep(args.spec)
    resume = _read_partial(partial) if args.resume else None
    start = time.perf_counter()
    try:
        with _quiet_dask(args.scheduler is not None):
            rows = sweep(
                base,
                **{**options, "progress": args.progress, "resume": resume},
                scheduler=args.scheduler or args.workers,
            )
    except SweepIncomplete as failure:  # keep the finished rows; say what is missing
        _write(failure.rows, partial)
        print(f"hpdob sweep: error: {failure}; {_kept(args, failure, partial)}", file=sys.stderr)
        return 1
    except SweepInterrupted as interrupt:  # the same, then exit as interrupted (130, 143, 129)
        acknowledge()  # handled here: the partial file may be committed
        if len(interrupt.rows):
            _write(interrupt.rows, partial)  # a second signal here: atomic, nothing half-written
            detail = _kept(args, interrupt, partial)
        else:
            detail = f"no scenario had finished; {args.out} was not written"
        raise Interrupted(interrupt.signum, detail) from None
    elapsed = time.perf_counter() - start
    _write(rows, args.out)
    partial.unlink(missing_ok=True)  # complete now (or stale: this run did every scenario)
    stable = int(rows["stable"].sum())
    resumed = "" if resume is None else f", {len(resume)} of them from {partial}"
    print(
        f"{len(rows)} scenarios ({stable} stable, {len(rows) - stable} diverged or invalid"
        f"{resumed}) in {elapsed:.1f} s; wrote {args.out}"
    )
    return 0


def _kept(args: argparse.Namespace, stopped, partial: Path) -> str:
    """Where the finished rows of an incomplete sweep went, what is missing, and the command
    that completes it."""
    again = ["hpdob", "sweep", str(args.spec), "--out", str(args.out), "--resume"]
    if args.scheduler is not None:
        again += ["--scheduler", args.scheduler]
    return (
        f"wrote the {len(stopped.rows)} finished rows to {partial} ({args.out} was not "
        f"written); missing: scenarios {_ranges(stopped.missing)}; to run only those and write "
        f"{args.out}: {shlex.join(again)}"
    )


def _read_partial(partial: Path):
    """The rows of ``partial`` as written by :func:`_write`, read back exactly (pandas 3 parses
    floats to the nearest double; the resumed file is compared byte for byte with a run from
    scratch in the tests), an empty cell as NaN only where a number belongs (``error`` is
    text)."""
    import pandas as pd

    if not partial.is_file():
        raise CLIError(
            f"--resume: there is no partial result {partial} to resume (one is written when a "
            "sweep is interrupted or its dask cluster fails part-way; without it, run the "
            "sweep without --resume)"
        )
    try:
        if partial.suffix == ".parquet":
            return pd.read_parquet(partial)
        header = pd.read_csv(partial, nrows=0).columns
        # pandas 3 reads floats exactly by default (and deprecates the option); pandas 2 not
        exact = {"float_precision": "round_trip"} if pd.__version__.startswith("2.") else {}
        return pd.read_csv(
            partial,
            **exact,
            keep_default_na=False,
            na_values={name: [""] for name in header if name != "error"},
        )
    except (OSError, ValueError) as err:  # pandas' parser errors are ValueErrors
        message = " ".join(str(err).split())
        raise CLIError(f"--resume: cannot read the partial result {partial}: {message}") from None


@contextlib.contextmanager
def _quiet_dask(active: bool):
    """Route dask's loggers to nothing while a sweep runs on a cluster: a lost scheduler makes
    ``distributed.client`` log a 20-line traceback beside hpdob's one-line message, which says
    all there is to say. ``HPDOB_TRACEBACK=1`` keeps them (as it keeps hpdob's traceback)."""
    if not active or os.environ.get("HPDOB_TRACEBACK"):
        yield
        return
    import logging

    with contextlib.suppress(ImportError):  # configures its loggers on import: do that first
        import distributed  # noqa: F401
    families = ("distributed", "tornado", "bokeh", "asyncio")
    names = {n for n in logging.Logger.manager.loggerDict if n.split(".")[0] in families}
    saved = []
    for name in sorted(names | set(families)):  # distributed.client has its own handler
        logger = logging.getLogger(name)
        saved.append((logger, logger.handlers[:], logger.propagate))
        logger.handlers = [logging.NullHandler()]
        logger.propagate = False
    try:
        yield
    finally:
        for logger, handlers, propagate in saved:
            logger.handlers, logger.propagate = handlers, propagate


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
