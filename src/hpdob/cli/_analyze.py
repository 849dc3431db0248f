"""``hpdob analyze bode|noise|tradeoff|stability``: frequency-domain analyses, figures and data.

Every analysis writes a PNG figure plus the numbers behind it as CSV and JSON into ``--out``.
Defaults are the canonical scenario (:mod:`hpdob.paper._scenario`): true plant J = 3.06e-4 kg m^2,
b = 5e-5 N m s/rad; nominal J_n = 2.8e-4 kg m^2, b_n = 0; Ts = 1 ms; PD(50, 5).
"""

from __future__ import annotations

import argparse
import contextlib
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ._errors import CLIError
from ._options import (
    add_loop_arguments,
    add_nominal_arguments,
    controller_from_args,
    finite,
    output_path,
    reject_plant_arguments,
)
from ._outputs import MAX_DPI, dpi_argument, save_figure, write_json

__all__ = ["register"]

ANALYSES = ("bode", "noise", "tradeoff", "stability")


# -- argparse types: grids, orders, families and tolerances ------------------------------


#: Most values of one analysis grid (``--bandwidths``, ``--values``): sized up front, before
#: numpy allocates (``10:2000:100000000`` ended in a MemoryError after 12 s).
MAX_GRID_VALUES = 10_000


def _grid(text: str) -> list[float]:
    """``LO:HI:N`` (N log-spaced values) or a non-empty comma-separated list of finite numbers,
    of at most :data:`MAX_GRID_VALUES` values."""
    try:
        if ":" in text:
            lo, hi, n = text.split(":")
            lo, hi, count = float(lo), float(hi), int(n)
            if not (0 < lo < math.inf and 0 < hi < math.inf and count >= 1):
                raise ValueError
        else:
            values = [float(item) for item in text.split(",") if item.strip()]
            if not values or not all(math.isfinite(v) for v in values):
                raise ValueError
            count = len(values)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected LO:HI:N (N log-spaced positive finite values) or finite values as at "
            f"least one comma-separated number, got {text!r}"
        ) from None
    if count > MAX_GRID_VALUES:
        raise argparse.ArgumentTypeError(
            f"a grid has at most {MAX_GRID_VALUES} values, got {count} in {text!r}"
        )
    if ":" in text:
        return np.geomspace(lo, hi, count).tolist()
    return values


def _positive_real(text: str) -> float:
    """A finite number > 0 (e.g. ``--bandwidth`` of ``stability``)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text!r}")
    return value


def _orders(text: str) -> list[int]:
    """Comma-separated distinct integer orders (a repeated one is refused up front: the maps
    were computed before the error)."""
    try:
        values = [int(item) for item in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated integer orders, got {text!r}"
        ) from None
    repeated = sorted({v for v in values if values.count(v) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(
            f"expected distinct orders, got {text!r} (order {repeated[0]} twice)"
        )
    return values


def _measurements(text: str) -> list[str]:
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items or any(item not in ("state", "position") for item in items):
        raise argparse.ArgumentTypeError(
            f"expected comma-separated 'state' and/or 'position', got {text!r}"
        )
    return items


def _pole_tolerance(text: str):
    """``none`` or a number (argparse type of ``--pole-tolerance``; the value is checked by
    the design)."""
    return None if text.strip().lower() == "none" else finite(text)


def _add_common(parser: argparse.ArgumentParser, *, loop: bool = True) -> None:
    """Output options and the model/loop options (``loop=False``: the nominal model only)."""
    parser.add_argument(
        "--out",
        type=output_path,
        default=Path("hpdob-analysis"),
        metavar="DIR",
        help="output directory (default: %(default)s)",
    )
    parser.add_argument(
        "--dpi",
        type=dpi_argument,
        default=150.0,
        help=f"figure resolution [dots per inch], at most {MAX_DPI} (default: %(default)s)",
    )
    title = "loop (defaults: the canonical scenario)" if loop else "nominal model (canonical)"
    group = parser.add_argument_group(title)
    add_nominal_arguments(group)
    if loop:
        add_loop_arguments(group)
    else:
        reject_plant_arguments(parser)


def _add_measurement(parser: argparse.ArgumentParser, *, loop: bool = True) -> None:
    parser.add_argument(
        "--measurement",
        choices=("state", "position"),
        default="state",
        help="--type dob: angle and velocity measured (state) or the angle only "
        "(position; every pole at exp(-g Ts)) (default: %(default)s)",
    )
    _add_family(parser)
    if loop:
        parser.add_argument(
            "--pd-velocity",
            choices=("measured", "observer"),
            default="measured",
            help="velocity of the D term (pd, pid, filtered-pd): the sensor's or the "
            "position-only observer's estimate (default: %(default)s)",
        )


#: Family parameters ``analyze`` sets itself: the bandwidth (its grid or ``--bandwidth``), the
#: order (``--orders``), the paper's family's measurement (``--measurement``).
_SET_BY_ANALYZE = ("bandwidth", "poles", "measurement")


def _family_options() -> dict:
    """``{name: [(family, Parameter), ...]}`` of the registered families' parameters an
    analysis takes as options (not its order, bandwidth or what a design at a bandwidth sets)."""
    from ..observers import families
    from ._design import _observer_options

    set_here = set(_SET_BY_ANALYZE)
    for family in families():
        set_here |= {family.order, *family.set_at_bandwidth} - {None}
    return {k: v for k, v in _observer_options().items() if k not in set_here}


def _add_family(parser: argparse.ArgumentParser) -> None:
    """``--type`` (any registered family, as ``hpdob design --type``) and one option per
    family parameter (:func:`_family_options`): ``--orders`` sweep the family's order key."""
    from ..observers import families
    from ._design import _KIND_TYPES, _option

    group = parser.add_argument_group(
        "observer family", "as 'hpdob design'; --orders are the family's order key and each "
        "bandwidth designs it (a Kalman observer's process noise is chosen for it)",
    )  # fmt: skip
    group.add_argument(
        "--type",
        choices=[f.name for f in families()],
        default="dob",
        help="observer family (default: %(default)s, the paper's)",
    )
    for name, owners in _family_options().items():
        parameter = owners[0][1]
        described = "; ".join(f"{f.name}: {p.help}" for f, p in owners)
        kwargs = {"choices": parameter.choices} if parameter.kind == "choice" else {
            "type": _KIND_TYPES[parameter.kind]}  # fmt: skip
        group.add_argument(_option(name), default=None, help=described, **kwargs)


def _spec(args, order) -> dict:
    """The family spec ``--type`` and its options describe, at ``order`` (the family's order
    key; ``None`` for a family without one), without the bandwidth the analysis sets."""
    from ..observers import get_family
    from ._design import _option

    family = get_family(getattr(args, "type", "dob"), "--type")
    given = {k: getattr(args, k) for k in _family_options() if getattr(args, k, None) is not None}
    foreign = [_option(k) for k in given if k not in family.keys]
    if foreign:
        verb = "applies" if len(foreign) == 1 else "apply"
        raise CLIError(f"{', '.join(foreign)} {verb} to another family, not --type {family.name}")
    measurement = getattr(args, "measurement", "state")
    if "measurement" not in family.keys and measurement != "state":
        raise CLIError(f"--measurement applies to --type dob, not --type {family.name}")
    spec = {"type": family.name, **family.defaults, **given}
    for key in (family.order, "bandwidth", "poles", *family.set_at_bandwidth):
        spec.pop(key, None)
    if "measurement" in family.keys:
        spec["measurement"] = measurement
    if family.order is not None and order is not None:
        spec[family.order] = order
    missing = [k for k in family.required
               if k not in spec and k not in (family.order, *family.set_at_bandwidth)]  # fmt: skip
    if missing:
        raise CLIError(f"--type {family.name} needs {_option(missing[0])} "
                       f"({family.parameter(missing[0]).help})")  # fmt: skip
    return spec


def _is_paper_family(args) -> bool:
    return getattr(args, "type", "dob") == "dob"


def _label(args, order) -> str:
    from ..observers import spec_label

    return spec_label(_spec(args, order))


def _design(args, model, order: int, bandwidth: float):
    """The ``--type`` family's design of ``order`` at ``bandwidth`` [rad/s] on ``model``."""
    from ..observers import design_at_bandwidth, design_observer

    if _is_paper_family(args) and not _family_given(args):  # the paper's, as it always was
        return design_observer(
            model, order=order, bandwidth=bandwidth,
            measurement=getattr(args, "measurement", "state"),
        )  # fmt: skip
    return design_at_bandwidth(model, _spec(args, order), bandwidth)


def _family_given(args) -> bool:
    return any(getattr(args, k, None) is not None for k in _family_options())


def _add_orders(parser: argparse.ArgumentParser, default: str, *, follows: bool = False) -> None:
    """``--orders``; ``follows``: its default (None until :func:`_family_grid`) follows
    ``--type``, as its help says."""
    follow = "; for another --type the family's orders that it can design" if follows else ""
    parser.add_argument(
        "--orders",
        type=_orders,
        default=None if follows else _orders(default),
        help=f"comma-separated truncation orders, 0 DOb, 1 HPDOb (default {default}{follow})",
    )


def _print_notes(notes) -> None:
    import sys

    for note in notes:
        print(note, file=sys.stderr)


#: The defaults of ``analyze noise`` and ``analyze tradeoff``'s grids (the paper's family's).
GRID_DEFAULTS = {"noise": ("0,1,2,3", "10:2000:25"), "tradeoff": ("0,1,2,3", "10:3000:61")}


def _family_grid(args, model, designs: dict | None = None) -> list[str]:
    """Fill in ``args.orders`` and ``args.bandwidths`` where they were not given.

    The paper's family (``--type dob``) takes the defaults as they are. Another family takes
    the default orders it has (one row for a family without an order key) and, of a default
    axis, the values it can design: the bandwidths it designs at some default order, then the
    orders it designs at every such bandwidth (an ESO of extended order 2 cannot be realised in
    double precision at 10 rad/s; a Kalman design refuses bandwidths beyond pi/(2 Ts)). An
    axis the user gave is kept whole, so a point it cannot design stops the analysis, named.
    Returns the notes of what was left out, for stderr; ``designs`` (a dict) receives the
    designs made on the way, by ``(order, bandwidth)``, for the analysis to reuse.
    """
    from .._validation import ParameterTypeError, ParameterValueError
    from ..observers import get_family

    orders_text, bandwidths_text = GRID_DEFAULTS[args.analysis]
    given_orders, given_bandwidths = args.orders is not None, args.bandwidths is not None
    if args.orders is None:
        args.orders = _orders(orders_text)
    if args.bandwidths is None:
        args.bandwidths = _grid(bandwidths_text)
    if _is_paper_family(args) or (given_orders and given_bandwidths):
        return []
    family = get_family(args.type, "--type")
    if family.order is None and not given_orders:
        args.orders = args.orders[:1]  # one row: a family without an order key
    first_error, works = None, {}
    for m in args.orders:
        for g in args.bandwidths:
            try:
                design = _design(args, model, m, g)
                works[m, g] = True
                if designs is not None:
                    designs[m, g] = design
            except (ParameterValueError, ParameterTypeError) as err:
                first_error = first_error or err
                works[m, g] = False
    notes = []
    if not given_bandwidths:
        kept = [g for g in args.bandwidths if any(works[m, g] for m in args.orders)]
        if len(kept) < len(args.bandwidths):
            left = [g for g in args.bandwidths if g not in kept]
            notes.append(f"{len(left)} default bandwidths ({left[0]:.4g}-{left[-1]:.4g} rad/s)")
        args.bandwidths = kept or args.bandwidths
    if not given_orders:
        kept = [m for m in args.orders if all(works[m, g] for g in args.bandwidths)]
        left = [m for m in args.orders if m not in kept]
        if left:
            notes.append(f"order{'s' if len(left) > 1 else ''} {', '.join(map(str, left))}")
        args.orders = kept or args.orders
    if not all(works[m, g] for m in args.orders for g in args.bandwidths):
        raise first_error  # nothing of the default grid left: say why, as for a given grid
    if not notes:
        return []
    return [
        f"hpdob analyze {args.analysis}: --type {family.name} cannot design "
        f"{' and '.join(notes)} of the default grid, left out (first: {first_error}); give "
        "--orders and --bandwidths to choose the grid"
    ]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "analyze",
        help="frequency response, noise gains, accuracy/noise trade-off, robust stability",
        description="Linear analyses of the observers and the closed loop (see "
        "docs/analysis.md). Writes a PNG figure plus CSV and JSON of the numbers.",
    )
    sub = parser.add_subparsers(dest="analysis", metavar="ANALYSIS", parser_class=type(parser))
    sub.required = True
    bode = sub.add_parser(
        "bode",
        help="estimation response Q, 1-Q and input sensitivity",
        description="Frequency response of each order's disturbance estimation, Q = "
        "tau_hat/tau_dn in closed form, its error 1-Q, and the input sensitivity S of the loop "
        "(docs/analysis.md, sections 2 and 3). Writes bode.png, bode.csv and bode.json (peaks, "
        "-3 dB frequency, error at --frequency, loop margins).",
    )
    _add_common(bode)
    _add_orders(bode, "0,1,2,3")
    _add_measurement(bode)
    bode.add_argument("--bandwidth", type=finite, default=100.0, help="[rad/s] (default 100)")
    bode.add_argument(
        "--frequency",
        type=finite,
        default=2.0,
        help="disturbance frequency to report [Hz] (default 2)",
    )
    noise = sub.add_parser(
        "noise",
        help="noise gains of estimate and command per order",
        description="Exact noise gains of the closed loop (discrete Lyapunov equation): RMS of "
        "the estimate and of the command per unit white position or velocity noise, for each "
        "order over the bandwidths (docs/analysis.md, section 4). Writes noise.png, noise.csv "
        "and noise.json.",
    )
    _add_common(noise)
    _add_orders(noise, GRID_DEFAULTS["noise"][0], follows=True)
    _add_measurement(noise)
    noise.add_argument(
        "--bandwidths",
        type=_grid,
        default=None,
        help=f"[rad/s], LO:HI:N or a list (default {GRID_DEFAULTS['noise'][1]}; for another "
        "--type the values the family can design)",
    )
    tradeoff = sub.add_parser(
        "tradeoff",
        help="estimation error against noise gain",
        description="Estimation error for a sinusoidal disturbance against the estimate's noise "
        "gain; both depend on the observer and its nominal model only.",
    )
    _add_common(tradeoff, loop=False)
    _add_family(tradeoff)
    _add_orders(tradeoff, GRID_DEFAULTS["tradeoff"][0], follows=True)
    tradeoff.add_argument(
        "--bandwidths",
        type=_grid,
        default=None,
        help=f"[rad/s], LO:HI:N or a list (default {GRID_DEFAULTS['tradeoff'][1]}; for another "
        "--type the values the family can design)",
    )
    tradeoff.add_argument(
        "--frequency", type=finite, default=2.0, help="disturbance frequency [Hz] (default 2)"
    )
    tradeoff.add_argument(
        "--noise",
        choices=("velocity", "position", "encoder"),
        default=None,
        help="measurement carrying the white noise; encoder: angle noise, differenced into "
        "the velocity (default: velocity, encoder when position-only observers are included)",
    )
    tradeoff.add_argument(
        "--measurements",
        type=_measurements,
        default=["state"],
        help="the paper's observer versions (--type dob), e.g. state,position (default: state)",
    )
    tradeoff.add_argument(
        "--pole-tolerance",
        type=_pole_tolerance,
        default=0.05,
        metavar="TOL|none",
        help="largest realised-pole error, in units of a pole's distance to the unit circle, "
        "of a design in double precision (high orders at low bandwidths exceed it); 'none' "
        "accepts every design (default: %(default)s)",
    )
    stab = sub.add_parser(
        "stability",
        help="robust stability map over model error",
        description="Closed-loop stability over a grid of true-plant inertias (J/J_n) or "
        "viscous frictions and observer bandwidths, one map per order, with the stability "
        "boundary refined (docs/analysis.md, section 6). Writes "
        "stability_<parameter>_m<order>[_delay<d>].png and .csv per order and "
        "stability.json.",
    )
    _add_common(stab)
    _add_orders(stab, "0,1")
    _add_measurement(stab)
    stab.add_argument(
        "--parameter",
        choices=("J_ratio", "b"),
        default="J_ratio",
        help="varied true-plant parameter (default J_ratio = J/J_n)",
    )
    stab.add_argument(
        "--values",
        type=_grid,
        default=None,
        help="its grid (default 0.1:10:61 for J_ratio, 1e-4:10:61 for b)",
    )
    stab.add_argument(
        "--bandwidths",
        type=_grid,
        default=_grid("10:2000:61"),
        help="[rad/s], LO:HI:N or a list (default 10:2000:61)",
    )
    stab.add_argument(
        "--bandwidth",
        type=_positive_real,
        default=None,
        metavar="G",
        help="observer bandwidth [rad/s] of your design: a star marks it at the loop's true "
        "plant (--J/--J-n or --b) on each map (default: no mark)",
    )
    for p, what in ((bode, "orders"), (noise, "grid points"), (tradeoff, "grid points"),
                    (stab, "grid points")):  # fmt: skip
        p.add_argument(
            "--progress",
            action=argparse.BooleanOptionalAction,
            default=None,
            help=f"{what} done and time left on stderr (default: when stderr is a terminal)",
        )
        p.set_defaults(handler=_run)


def _loop(args):
    from ..models import ServoModel
    from ..simulation import Actuator

    velocity = getattr(args, "pd_velocity", "measured")
    return {
        "plant": ServoModel(args.J, args.b),
        "nominal": ServoModel(args.J_n, args.b_n),
        "Ts": args.Ts,
        "controller": controller_from_args(args, velocity=velocity),
        "actuator": Actuator(delay_samples=args.delay),
    }


#: The summary JSON of each analysis: renamed last, so it marks a complete set of outputs.
MARKERS = {
    "bode": "bode.json",
    "noise": "noise.json",
    "tradeoff": "tradeoff.json",
    "stability": "stability.json",
}


def _run(args: argparse.Namespace) -> int:
    import matplotlib

    from .._files import staged_outputs

    matplotlib.use("Agg")
    # Every output is staged and renamed only when all are complete (the JSON last): a bad
    # value found late (e.g. an order that cannot be designed) leaves the previous outputs.
    with staged_outputs(args.out, markers=[MARKERS[args.analysis]]) as files:
        written = {
            "bode": _bode,
            "noise": _noise,
            "tradeoff": _tradeoff,
            "stability": _stability,
        }[args.analysis](args, files)
    print(f"wrote {', '.join(written)} to {args.out}")
    return 0


@contextlib.contextmanager
def _progress_line(label: str, args):
    """``progress(done, total)`` for ``--progress`` (a :class:`ProgressLine`; a no-op without
    it), its line ended on leaving, so an error or interrupt message starts on its own line."""
    from ._progress import ProgressLine, show_progress

    line = ProgressLine(label) if show_progress(args.progress) else None
    try:
        yield line if line is not None else (lambda done, total: None)
    finally:
        if line is not None:
            line.end()


def _below_nyquist(Ts: float) -> float:
    """The largest frequency [Hz] at or below 1/(2 Ts) whose ``2 pi f Ts`` does not round above
    pi: python-control warns "evaluation above Nyquist frequency" for one ulp more."""
    top = 0.5 / Ts
    while 2.0 * np.pi * top * Ts > np.pi:
        top = float(np.nextafter(top, 0.0))
    return top


def _bode(args, files) -> list[str]:
    from .._table import columns_to_csv
    from ..analysis import bode_figure, estimation_response, gang_of_four, loop_margins

    loop = _loop(args)
    nyquist = 0.5 / loop["Ts"]
    if not 0 <= args.frequency < nyquist:  # above it the response is an alias's (as tune says)
        raise CLIError(
            f"--frequency must be at least 0 and below the Nyquist frequency 1/(2 Ts) = "
            f"{nyquist:.6g} Hz, got {args.frequency!r}"
        )
    model = loop["nominal"].discretize(loop["Ts"])
    designs = [_design(args, model, m, args.bandwidth) for m in args.orders]
    f = np.geomspace(0.1, _below_nyquist(loop["Ts"]), 400)
    sens, margins = [], []  # per order: |S| on the grid, then the margins (the costly part)
    with _progress_line("analyze bode:", args) as line:
        line(0, 2 * len(designs))
        for d in designs:
            S = gang_of_four(**loop, observer=d).S
            sens.append(S.frequency_response(2 * np.pi * f).frdata[0, 0])
            line(2 * len(sens) - 1, 2 * len(designs))
            margins.append(loop_margins(**loop, observer=d))
            line(2 * len(sens), 2 * len(designs))
    labels = None  # the paper's family: its order names, as always
    if not _is_paper_family(args):
        labels = [f"{_label(args, m)}, g = {args.bandwidth:g} rad/s" for m in args.orders]
    save_figure(
        bode_figure(designs, f, sensitivities=sens, mark_frequency=args.frequency, labels=labels),
        files,
        "bode.png",
        args.dpi,
    )
    columns = {
        "frequency_Hz": [],
        "order": [],
        "Q_abs": [],
        "Q_phase_deg": [],
        "error_abs": [],
        "S_abs": [],
    }
    summary = {
        "bandwidth_rad_s": args.bandwidth,
        "frequency_Hz": args.frequency,
        "measurement": args.measurement,
        "observer": _spec(args, None),
        "orders": {},
    }
    for m, d, s, margin in zip(args.orders, designs, sens, margins, strict=True):
        q = estimation_response(d, f)
        columns["frequency_Hz"] += f.tolist()
        columns["order"] += [m] * f.size
        columns["Q_abs"] += np.abs(q).tolist()
        columns["Q_phase_deg"] += np.degrees(np.unwrap(np.angle(q))).tolist()
        columns["error_abs"] += np.abs(1 - q).tolist()
        columns["S_abs"] += np.abs(s).tolist()
        below = np.nonzero(np.abs(q) < 10 ** (-3 / 20))[0]
        summary["orders"][str(m)] = {
            "Q_peak_dB": float(20 * np.log10(np.abs(q).max())),
            "Q_peak_Hz": float(f[np.argmax(np.abs(q))]),
            "Q_minus3dB_Hz": float(f[below[0]]) if below.size else None,
            "error_gain_at_frequency": float(
                abs(estimation_response(d, args.frequency, error=True)[0])
            ),
            "S_peak_dB": float(20 * np.log10(np.abs(s).max())),
            "loop_margins": {
                **asdict(margin),
                "inertia_factor_range": list(margin.inertia_factor_range),
            },
        }
    columns_to_csv(columns, files.path("bode.csv"))
    write_json(files, "bode.json", summary)
    return ["bode.png", "bode.csv", "bode.json"]


def _noise(args, files) -> list[str]:
    from .._table import columns_to_csv
    from ..analysis import noise_figure, noise_gains

    loop = _loop(args)
    model = loop["nominal"].discretize(loop["Ts"])
    designs: dict = {}  # those _family_grid made (another family's default grid)
    _print_notes(_family_grid(args, model, designs))
    total = len(args.orders) * len(args.bandwidths)
    with _progress_line("analyze noise:", args) as line:
        line(0, total)
        gains = []
        for m in args.orders:
            gains.append([])
            for g in args.bandwidths:
                design = designs[m, g] if (m, g) in designs else _design(args, model, m, g)
                gains[-1].append(noise_gains(**loop, observer=design))
                line(len(gains[-1]) + (len(gains) - 1) * len(args.bandwidths), total)
    labels = None if _is_paper_family(args) else [_label(args, m) for m in args.orders]
    figure = noise_figure(args.bandwidths, args.orders, gains, labels=labels)
    save_figure(figure, files, "noise.png", args.dpi)
    rows = [
        {"order": m, "bandwidth_rad_s": g, **gain.to_dict()}
        for m, row in zip(args.orders, gains, strict=True)
        for g, gain in zip(args.bandwidths, row, strict=True)
    ]
    columns_to_csv({k: [r[k] for r in rows] for k in rows[0]}, files.path("noise.csv"))
    write_json(files, "noise.json", {"loop": _describe(args), "gains": rows})
    return ["noise.png", "noise.csv", "noise.json"]


def _describe(args) -> dict:
    from ..controllers import controller_settings

    controller = controller_from_args(args, velocity=args.pd_velocity)
    return {
        "J_n": args.J_n,
        "b_n": args.b_n,
        "J": args.J,
        "b": args.b,
        "Ts": args.Ts,
        "controller": {**controller_settings(controller), "type": args.controller},
        "kp": getattr(controller, "kp", None),
        "kd": getattr(controller, "kd", None),
        "delay_samples": args.delay,
        "measurement": args.measurement,
        "observer": _spec(args, None),
        "pd_velocity": args.pd_velocity,
    }


def _tradeoff(args, files) -> list[str]:
    from ..analysis import noise_tradeoff
    from ..models import ServoModel

    nominal = ServoModel(args.J_n, args.b_n)
    _print_notes(_family_grid(args, nominal.discretize(args.Ts)))
    spec = None  # the paper's family, its versions by --measurements (as it always was)
    if not _is_paper_family(args) or _family_given(args):
        if args.measurements != ["state"] and not _is_paper_family(args):
            raise CLIError(f"--measurements applies to --type dob, not --type {args.type}")
        if len(args.measurements) != 1:
            raise CLIError("--measurements takes one version with --type dob's options")
        args.measurement = args.measurements[0]
        spec = _spec(args, None)
    noise = args.noise
    if noise is None and spec is not None:  # the angle noise if the family measures no velocity
        from ..observers import design_at_bandwidth, get_family

        key = get_family(spec["type"], "--type").order
        first = design_at_bandwidth(nominal.discretize(args.Ts),
                                    {**spec, **({} if key is None else {key: args.orders[0]})},
                                    args.bandwidths[0], "--type")  # fmt: skip
        noise = "encoder" if first.system.measurement == "position" else "velocity"
    if noise is None:
        noise = "encoder" if "position" in args.measurements else "velocity"
    family = {} if spec is None else {"family": spec}
    with _progress_line("analyze tradeoff:", args) as line:
        result = noise_tradeoff(
            nominal=nominal,
            Ts=args.Ts,
            frequency=args.frequency,
            bandwidths=args.bandwidths,
            orders=args.orders,
            noise=noise,
            measurements=args.measurements if spec is None else ["state"],
            pole_tolerance=args.pole_tolerance,
            progress=line,
            **family,
        )
    save_figure(result.plot(), files, "tradeoff.png", args.dpi)
    result.to_csv(files.path("tradeoff.csv"))
    reference = result.orders[0]
    first = result.measurements[0]

    def key(m, kind):  # the order alone for one family (as before), else "position:1"
        return str(m) if len(args.measurements) == 1 else f"{kind}:{m}"

    summary = {
        "frequency_Hz": result.frequency,
        "noise": result.noise,
        "reference_order": reference,
        "reference_measurement": first,
        "improvement_at_equal_noise": {
            key(m, kind): dict(
                zip(
                    [f"{g:.6g}" for g in result.bandwidths],
                    result.improvement(
                        m, reference=reference, measurement=kind, reference_measurement=first
                    ).tolist(),
                    strict=True,
                )
            )
            for m, kind in zip(result.orders, result.measurements, strict=True)
            if (m, kind) != (reference, first)
        },
    }
    if spec is not None:
        summary["observer"] = spec
    write_json(files, "tradeoff.json", summary)
    return ["tradeoff.png", "tradeoff.csv", "tradeoff.json"]


def _stability(args, files) -> list[str]:
    from ._progress import ProgressLine, show_progress

    loop = _loop(args)
    J_ratio = args.J / args.J_n
    values = args.values
    if values is None:
        values = _grid("0.1:10:61" if args.parameter == "J_ratio" else "1e-4:10:61")
    # Map axes must increase; on the command line a grid is a set of values (10:1:5 or 3,1,2).
    values, bandwidths = sorted(set(values)), sorted(set(args.bandwidths))
    grid = (
        {"J_ratio": values, "b": args.b}
        if args.parameter == "J_ratio"
        else {"J_ratio": J_ratio, "b": values}
    )
    written, summary = [], {"loop": _describe(args), "maps": []}
    # One line for all the maps: done/total and the time left count every requested order.
    line = ProgressLine("analyze stability:") if show_progress(args.progress) else None
    try:
        for k, m in enumerate(args.orders):
            progress = _overall(line, k, len(args.orders), m)
            written += _stability_map(
                args, files, grid, bandwidths, loop, J_ratio, summary, order=m, progress=progress
            )
    finally:  # an error or interrupt message starts on its own line
        if line is not None:
            line.end()
    write_json(files, "stability.json", summary)
    return [*written, "stability.json"]


def _overall(line, k: int, maps: int, order: int):
    """``progress(done, total)`` of map ``k`` of ``maps`` (all of one size) as the share of the
    whole command on ``line``."""
    if line is None:
        return None

    def progress(done: int, total: int) -> None:
        line(k * total + done, maps * total, detail=f"order {order},")

    return progress


def _stability_map(args, files, grid, bandwidths, loop, J_ratio, summary, *, order, progress):
    """Compute, draw and stage the map of one order; returns the names written."""
    from ..analysis import robust_stability_map
    from ..models import ServoModel

    m = order
    family = (  # the paper's family as it always was; any other by its spec
        {"order": m, "measurement": args.measurement}
        if _is_paper_family(args) and not _family_given(args)
        else {"observer": _spec(args, m)}
    )
    smap = robust_stability_map(
        **grid,
        **family,
        bandwidth=bandwidths,
        nominal=ServoModel(args.J_n, args.b_n),
        Ts=args.Ts,
        controller=loop["controller"],
        delay_samples=args.delay,
        progress=progress,
    )
    stem = f"stability_{args.parameter}_m{m}" + (f"_delay{args.delay}" if args.delay else "")
    if args.measurement == "position":
        stem += "_position"
    if not _is_paper_family(args):  # another family's maps beside the paper's, not over them
        stem = f"stability_{args.type}_{args.parameter}_m{m}" + stem.split(f"_m{m}", 1)[1]
    # Mark the user's design (--bandwidth) at the loop's own plant if it lies on the map.
    point = None
    if args.bandwidth is not None:
        point = (args.bandwidth, J_ratio if args.parameter == "J_ratio" else args.b)
        inside = (
            smap.bandwidths.min() <= point[0] <= smap.bandwidths.max()
            and smap.values.min() <= point[1] <= smap.values.max()
        )
        point = point if inside else None
    save_figure(smap.plot(mark=point), files, f"{stem}.png", args.dpi)
    smap.to_csv(files.path(f"{stem}.csv"))
    summary["maps"].append(
        {
            "order": m,
            "observer": _spec(args, m),
            "parameter": args.parameter,
            "delay_samples": args.delay,
            "stable_fraction": float(smap.stable.mean()),
            "boundary": smap.boundary(),
        }
    )
    return [f"{stem}.png", f"{stem}.csv"]
