"""``hpdob identify LOG``: identify J, b, Coulomb friction and offset from a logged run."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._design import _integer, _number_list
from ._errors import CLIError
from ._logs import add_log_arguments, log_from_args
from ._options import finite as _real
from ._options import output_path

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "identify",
        help="identify inertia, friction and offset of an axis from a logged run",
        description="Identify u = J qdd + b qd + coulomb sign(qd) + offset from a log (CSV, "
        "Parquet or MATLAB .mat) by the EMPS benchmark's IDIM-LS or by IDIM-IV; writes "
        "identification.json, identification.csv and identification.png into the output "
        "directory and prints a summary. A linear axis (m, N, kg) works like a rotary one "
        "(rad, N m, kg m^2): --axis sets the units of the report. See docs/real-data.md.",
    )
    add_log_arguments(
        parser,
        emps_help="use the EMPS benchmark's measured run shipped with hpdob (and its "
        "controller for --method idim-iv) instead of LOG",
        reference=True,
    )
    method = parser.add_argument_group("method")
    method.add_argument(
        "--method",
        choices=("idim-ls", "idim-iv"),
        default="idim-ls",
        help="inverse-model least squares, or instrumental variables from the simulated loop "
        "(needs --reference, --kp, --kd) (default: %(default)s)",
    )
    method.add_argument("--kp", type=_real, help="loop position gain [N m/rad or N/m]")
    method.add_argument("--kd", type=_real, help="loop velocity gain [N m s/rad or N s/m]")
    method.add_argument(
        "--velocity-filter",
        type=_number_list(float),
        default=None,
        metavar="C0,C1,...",
        help="the loop's velocity estimate sum c_i y_(k-i) / Ts (default: 1,-1)",
    )
    method.add_argument("--limit", type=_real, help="the loop's output limit [N m or N]")
    filters = parser.add_argument_group("filters (defaults: the EMPS rules, see identify())")
    filters.add_argument("--bandwidth", type=_real, help="closed-loop bandwidth [Hz]")
    filters.add_argument("--cutoff", type=_real, help="Butterworth cut-off [Hz]")
    filters.add_argument("--order", type=_integer, default=4, help="Butterworth order (4)")
    filters.add_argument("--decimation", type=_integer, help="decimation factor")
    filters.add_argument("--border", type=_integer, help="samples dropped at each end")
    filters.add_argument(
        "--min-speed", type=_real, default=0.0, help="drop rows slower than this [rad/s or m/s]"
    )
    parser.add_argument(
        "--out",
        type=output_path,
        default=None,
        metavar="DIR",
        help="output directory (default: hpdob-results/identify-<log name>)",
    )
    parser.add_argument("--no-plot", action="store_true", help="skip the figure")
    parser.set_defaults(handler=_run)


def _load(args):
    from ..identification import emps_loop
    from ..identification._loop import FeedbackLoop

    log = log_from_args(args)
    if args.emps:
        return log, emps_loop(log) if args.method == "idim-iv" else None
    loop = None
    if args.method == "idim-iv":
        missing = [f"--{k}" for k in ("reference", "kp", "kd") if getattr(args, k) is None]
        if missing:
            raise CLIError(
                f"--method idim-iv needs the loop that produced the log: give {', '.join(missing)}"
            )
        loop = FeedbackLoop(
            log.reference,
            kp=args.kp,
            kd=args.kd,
            velocity_filter=tuple(args.velocity_filter or (1.0, -1.0)),
            limit=args.limit,
        )
    return log, loop


def _run(args: argparse.Namespace) -> int:
    import warnings

    from .._files import check_output, staged_outputs
    from ..identification import EMPS_PUBLISHED, IdentificationWarning

    log, loop = _load(args)
    check_output(args.out or Path("hpdob-results") / f"identify-{Path(log.source).stem}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IdentificationWarning)
        result = log.identify(
            method=args.method, loop=loop, bandwidth=args.bandwidth, cutoff=args.cutoff,
            order=args.order, decimation=args.decimation, border=args.border,
            min_speed=args.min_speed, axis=args.axis or log.axis,
        )  # fmt: skip
    out = args.out or Path("hpdob-results") / f"identify-{Path(log.source).stem}"
    report = result.to_dict()
    report["log"] = {
        "source": log.source,
        "names": dict(log.names),
        "input_gain": log.input_gain,
        "samples": len(log),
        "Ts": log.Ts,
    }
    if args.emps:
        report["published"] = dict(EMPS_PUBLISHED)
    written = ["identification.json", "identification.csv"]
    # Staged and renamed together, identification.json last (docs/reliability.md).
    with staged_outputs(
        out, markers=["identification.json"], replaces=["identification.png"]
    ) as files:  # with --no-plot a previous identification.png goes: one consistent set
        result.to_csv(files.path("identification.csv"))
        if not args.no_plot:
            files.plot(
                "identification.png",
                lambda: result.plot(title=f"{result.method.upper()} on {log.source}"),
            )
            written.append("identification.png")
        files.write_json("identification.json", report)
    print(f"{log.source}: {len(log)} samples, Ts = {log.Ts:g} s")
    print(result.summary())
    if args.emps:
        p = EMPS_PUBLISHED
        print(
            f"  published IDIM-LS (EMPS description, section 3.4): M {p['J']} kg, "
            f"Fv {p['b']} N s/m, Fc {p['coulomb']} N, offset {p['offset']} N"
        )
    print(f"wrote {', '.join(written)} to {out}")
    caught = [w for w in caught if issubclass(w.category, IdentificationWarning)]
    for warning in caught:
        print(f"warning: {warning.message}")
    return 1 if caught else 0
