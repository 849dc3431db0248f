"""``hpdob estimate LOG``: run an observer offline over a logged run."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
from pathlib import Path

import numpy as np

from ._design import add_observer_arguments, design_on, observer_spec_of_args
from ._errors import CLIError
from ._logs import add_log_arguments, log_file_from_args
from ._options import finite, output_path
from ._progress import ProgressLine, show_progress

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "estimate",
        help="run an observer offline over a logged run (position, input) and write its estimate",
        description="Design an observer on a nominal model (--J-n/--b-n, or the J and b of an "
        "'hpdob identify' result with --from-identification) at the log's sampling period, run "
        "it over the log (CSV, Parquet or MATLAB .mat) and write estimate.csv, estimate.json "
        "and estimate.png. A linear axis (m, N, kg) works like a rotary one. See "
        "docs/real-data.md.",
    )
    add_log_arguments(parser, emps_help="use the EMPS benchmark's measured run instead of LOG")
    model = parser.add_argument_group("nominal model")
    which = model.add_mutually_exclusive_group()
    which.add_argument("--J-n", type=finite, help="nominal inertia [kg m^2 or kg]")
    which.add_argument(
        "--from-identification",
        type=Path,
        metavar="FILE",
        help="identification.json written by 'hpdob identify': its J and b",
    )
    model.add_argument(
        "--b-n",
        type=finite,
        default=None,
        help="nominal viscous friction [N m s/rad or N s/m] (default: 0)",
    )
    add_observer_arguments(parser)
    parser.add_argument(
        "--out",
        type=output_path,
        default=None,
        metavar="DIR",
        help="output directory (default: hpdob-results/estimate-<log name>)",
    )
    parser.add_argument("--no-plot", action="store_true", help="skip the figure")
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="reading and estimating progress with the time left on stderr (default: when "
        "stderr is a terminal)",
    )
    parser.set_defaults(handler=_run)


def _nominal(args):
    from .._validation import ParameterValueError, as_real
    from ..models import ServoModel

    if args.from_identification is not None:
        try:
            report = json.loads(args.from_identification.read_text(encoding="utf-8"))
            parameters = report["parameters"]
            J, b = parameters["J"], parameters["b"]
        except OSError as err:
            raise CLIError(f"cannot read {args.from_identification}: {err.strerror}") from None
        except (ValueError, KeyError, TypeError):
            raise CLIError(
                f"{args.from_identification} is not an 'hpdob identify' result (expected JSON "
                "with parameters.J and parameters.b)"
            ) from None
        if args.b_n is not None:
            raise CLIError("--b-n and --from-identification both set b_n; give one")
        where = f"of {args.from_identification}"
        J = as_real(J, f"parameters.J {where}", "a finite inertia [kg m^2 or kg]")
        b = as_real(b, f"parameters.b {where}", "a finite viscous friction [N m s/rad or N s/m]")
        try:
            model = ServoModel(J, max(b, 0.0))
        except ParameterValueError as err:
            raise CLIError(f"--from-identification {args.from_identification}: {err}") from None
        return model, f"identified in {args.from_identification}"
    if args.J_n is None:
        raise CLIError("give the nominal model: --J-n (and --b-n), or --from-identification FILE")
    return ServoModel(args.J_n, 0.0 if args.b_n is None else args.b_n), "given"


def _observer_settings(args: argparse.Namespace, design) -> dict:
    """The observer's settings in effect, read from ``design`` (the design, not the command
    line: defaults and derived values such as the Kalman process noise included), as
    JSON-ready values: every parameter of its registered family the design records."""
    from ..observers import get_family

    family = get_family(args.type, "--type")
    settings = {"type": args.type}
    for p in family.parameters:
        if p.kind == "complex_list":
            continue  # poles: reported below from the command line, as given
        value = getattr(design, p.name, None)
        if value is None:
            value = getattr(design.system, p.name, None)
        if value is not None:
            settings[p.name] = np.asarray(value).tolist() if np.ndim(value) else value
    tuned_given = getattr(args, family.tuned, None) is not None
    if family.tuned != "bandwidth" and not tuned_given:  # chosen for a bandwidth
        name = family.tuned.removesuffix("_std")
        settings[f"{name}_for_bandwidth"] = 100.0 if args.bandwidth is None else args.bandwidth
    if args.poles is not None:
        settings.pop("bandwidth", None)
        settings["poles"] = [[float(p.real), float(p.imag)] for p in args.poles]
    return settings


def _run(args: argparse.Namespace) -> int:
    from .._files import check_output

    # Every option and the output location are checked before the log is read: a log may
    # take minutes to read (up to 256 MiB), and a missing --J-n must not wait for it.
    nominal, origin = _nominal(args)
    observer_spec_of_args(args)  # the observer options (their values need the log's Ts)
    out = args.out
    if out is None and args.log is not None:  # the default is named after the log file
        out = Path("hpdob-results") / f"estimate-{Path(args.log).stem}"
    if out is not None:
        check_output(out)
    show = show_progress(args.progress)
    name = "EMPS" if args.log is None else Path(args.log).name
    reading = ProgressLine(f"hpdob estimate: reading {name}", unit="MiB", scale=2**20)
    try:  # a Parquet log is checked here and read block by block below, never held whole
        log = log_file_from_args(args, progress=reading if show else None)
    finally:  # an error or interrupt message starts on its own line
        reading.end()
    if out is None:  # --emps: its name is the shipped file's
        out = Path("hpdob-results") / f"estimate-{Path(log.source).stem}"
        check_output(out)
    design = design_on(args, nominal.discretize(log.Ts))
    # One stage: the CSV is written as the estimate runs, rows counted chunk by chunk.
    writing = ProgressLine("hpdob estimate: estimating, writing estimate.csv", unit="rows")
    written = ["estimate.csv"]
    created = [p for p in (out, *out.parents) if not p.exists()]  # removed again on a refusal
    try:
        if show:
            writing(0, len(log))
        mean, std = _estimate(args, log, design, nominal, origin, out, written,
                              writing if show else None)  # fmt: skip
    except BaseException:
        writing.end()  # the message starts on its own line
        for directory in created:  # innermost first; only what is still empty
            with contextlib.suppress(OSError):
                directory.rmdir()
        raise
    writing.end()
    print(
        f"{log.source}: {len(log)} samples, Ts = {log.Ts:g} s; {design.system.name} on "
        f"J_n = {nominal.J:.6g}, b_n = {nominal.b:.6g} ({origin})"
    )
    print(f"  tau_hat: mean {mean:.6g}, std {std:.6g} (last 90 % of the log)")
    print(f"wrote {', '.join(written)} to {out}")
    return 0


def _estimate(args, log, design, nominal, origin, out, written, progress=None) -> tuple:
    """Run the estimate and write its set of files (``written`` lists them); return the mean
    and standard deviation of the estimate over the last 90 % of the log."""
    from .._files import staged_outputs
    from ..identification import estimate_log

    # Staged and renamed together, estimate.json last (docs/reliability.md): a refused estimate
    # leaves nothing. With --no-plot a previous run's estimate.png is removed: one consistent set.
    with staged_outputs(out, markers=["estimate.json"], replaces=["estimate.png"]) as files:
        # the traces are written as the estimate runs; the statistics skip the first 10 %
        run = estimate_log(design, log, csv=files.path("estimate.csv"), settle=0.1, keep=False,
                           progress=progress)  # fmt: skip
        mean, std = run.mean, run.std
        if not (run.finite and math.isfinite(mean) and math.isfinite(std)):
            raise CLIError(
                f"the estimate of {design.system.name} is not finite on {log.source}: the "
                "observer diverged (or the log's values overflow it); nothing was written"
            )
        report = {
            "log": {"source": log.source, "names": dict(log.names), "samples": len(log),
                    "Ts": log.Ts, "input_gain": log.input_gain},
            "nominal": {"J": nominal.J, "b": nominal.b, "origin": origin},
            "observer": {**_observer_settings(args, design), "name": design.system.name},
            "tau_hat": {"mean": mean, "std": std,
                        "note": "over the last 90 % of the log (after the observer's transient)"},
        }  # fmt: skip
        if not args.no_plot:
            files.plot(
                "estimate.png",
                lambda: run.plot(title=f"{design.system.name} on {log.source}", axis=log.axis),
            )
            written.append("estimate.png")
        files.write_json("estimate.json", report)
        written.append("estimate.json")
    return mean, std
