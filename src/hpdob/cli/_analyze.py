"""``hpdob analyze bode|noise|tradeoff|stability``: frequency-domain analyses, figures and data.

Every analysis writes a PNG figure plus the numbers behind it as CSV and JSON into ``--out``.
Defaults are the canonical scenario (:mod:`hpdob.paper._scenario`): true plant J = 3.06e-4 kg m^2,
b = 5e-5 N m s/rad; nominal J_n = 2.8e-4 kg m^2, b_n = 0; Ts = 1 ms; PD(50, 5).
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..simulation._result import json_ready
from ._errors import CLIError
from ._options import (
    add_loop_arguments,
    add_nominal_arguments,
    finite,
    output_path,
    reject_plant_arguments,
)

__all__ = ["register"]

ANALYSES = ("bode", "noise", "tradeoff", "stability")
#: Highest --dpi, and most pixels along either side of a figure: beyond them matplotlib's
#: renderer runs out of memory (std::bad_alloc) instead of failing cleanly.
MAX_DPI = 1200
MAX_PIXELS = 16384


def _grid(text: str) -> list[float]:
    """``LO:HI:N`` (N log-spaced values) or a non-empty comma-separated list of numbers."""
    try:
        if ":" in text:
            lo, hi, n = text.split(":")
            lo, hi, count = float(lo), float(hi), int(n)
            if not (lo > 0 and hi > 0 and count >= 1):
                raise ValueError
            return np.geomspace(lo, hi, count).tolist()
        values = [float(item) for item in text.split(",") if item.strip()]
        if not values:
            raise ValueError
        return values
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected LO:HI:N (N log-spaced positive values) or at least one "
            f"comma-separated number, got {text!r}"
        ) from None


def _dpi(text: str) -> float:
    """A resolution [dots per inch]: a finite number in (0, MAX_DPI]."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and 0 < value <= MAX_DPI):
        raise argparse.ArgumentTypeError(
            f"expected a positive resolution of at most {MAX_DPI} dots per inch, got {text!r}"
        )
    return value


def _orders(text: str) -> list[int]:
    try:
        return [int(item) for item in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated integer orders, got {text!r}"
        ) from None


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
        type=_dpi,
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


def _add_orders(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument(
        "--orders",
        type=_orders,
        default=_orders(default),
        help=f"comma-separated truncation orders, 0 DOb, 1 HPDOb (default {default})",
    )


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "analyze",
        help="frequency response, noise gains, accuracy/noise trade-off, robust stability",
        description="Linear analyses of the observers and the closed loop (see "
        "docs/analysis.md). Writes a PNG figure plus CSV and JSON of the numbers.",
    )
    sub = parser.add_subparsers(dest="analysis", metavar="ANALYSIS", parser_class=type(parser))
    sub.required = True
    bode = sub.add_parser("bode", help="estimation response Q, 1-Q and input sensitivity")
    _add_common(bode)
    _add_orders(bode, "0,1,2,3")
    bode.add_argument("--bandwidth", type=finite, default=100.0, help="[rad/s] (default 100)")
    bode.add_argument(
        "--frequency",
        type=finite,
        default=2.0,
        help="disturbance frequency to report [Hz] (default 2)",
    )
    noise = sub.add_parser("noise", help="noise gains of estimate and command per order")
    _add_common(noise)
    _add_orders(noise, "0,1,2,3")
    noise.add_argument(
        "--bandwidths",
        type=_grid,
        default=_grid("10:2000:25"),
        help="[rad/s], LO:HI:N or a list (default 10:2000:25)",
    )
    tradeoff = sub.add_parser(
        "tradeoff",
        help="estimation error against noise gain",
        description="Estimation error for a sinusoidal disturbance against the estimate's noise "
        "gain; both depend on the observer and its nominal model only.",
    )
    _add_common(tradeoff, loop=False)
    _add_orders(tradeoff, "0,1,2,3")
    tradeoff.add_argument(
        "--bandwidths",
        type=_grid,
        default=_grid("10:3000:61"),
        help="[rad/s], LO:HI:N or a list (default 10:3000:61)",
    )
    tradeoff.add_argument(
        "--frequency", type=finite, default=2.0, help="disturbance frequency [Hz] (default 2)"
    )
    tradeoff.add_argument(
        "--noise",
        choices=("velocity", "position"),
        default="velocity",
        help="measurement carrying the white noise (default: velocity)",
    )
    stab = sub.add_parser("stability", help="robust stability map over model error")
    _add_common(stab)
    _add_orders(stab, "0,1")
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
    for p in (bode, noise, tradeoff, stab):
        p.set_defaults(handler=_run)


def _write_json(files, name: str, data: dict) -> None:
    files.write_text(name, json.dumps(json_ready(data), indent=2, allow_nan=False) + "\n")


def _loop(args):
    from ..models._servo import ServoModel
    from ..simulation._controller import PD
    from ..simulation._devices import Actuator

    return {
        "plant": ServoModel(args.J, args.b),
        "nominal": ServoModel(args.J_n, args.b_n),
        "Ts": args.Ts,
        "controller": PD(args.kp, args.kd),
        "actuator": Actuator(delay_samples=args.delay),
    }


def _save(fig, files, name: str, dpi: float) -> None:
    import matplotlib.pyplot as plt

    try:
        width, height = fig.get_size_inches() * dpi
        if max(width, height) > MAX_PIXELS:
            raise CLIError(
                f"--dpi {dpi:g} makes {name} {width:.0f} x {height:.0f} pixels; at most "
                f"{MAX_PIXELS} pixels per side are supported"
            )
        try:
            files.save_figure(name, fig, dpi=dpi)
        except (OverflowError, ValueError) as err:  # e.g. log axes over ~300 decades
            raise CLIError(
                f"cannot draw {name} (the grids may span too many decades): "
                f"{type(err).__name__}: {err}"
            ) from None
    finally:
        plt.close(fig)


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


def _bode(args, files) -> list[str]:
    from .._table import columns_to_csv
    from ..analysis._estimation import estimation_response
    from ..analysis._figures import bode_figure
    from ..analysis._sensitivity import gang_of_four, loop_margins
    from ..observers._synthesis import design_observer

    loop = _loop(args)
    model = loop["nominal"].discretize(loop["Ts"])
    designs = [design_observer(model, order=m, bandwidth=args.bandwidth) for m in args.orders]
    f = np.geomspace(0.1, 0.5 / loop["Ts"], 400)
    sens = [
        gang_of_four(**loop, observer=d).S.frequency_response(2 * np.pi * f).frdata[0, 0]
        for d in designs
    ]
    _save(
        bode_figure(designs, f, sensitivities=sens, mark_frequency=args.frequency),
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
    summary = {"bandwidth_rad_s": args.bandwidth, "frequency_Hz": args.frequency, "orders": {}}
    for d, s in zip(designs, sens, strict=True):
        q = estimation_response(d, f)
        columns["frequency_Hz"] += f.tolist()
        columns["order"] += [d.order] * f.size
        columns["Q_abs"] += np.abs(q).tolist()
        columns["Q_phase_deg"] += np.degrees(np.unwrap(np.angle(q))).tolist()
        columns["error_abs"] += np.abs(1 - q).tolist()
        columns["S_abs"] += np.abs(s).tolist()
        below = np.nonzero(np.abs(q) < 10 ** (-3 / 20))[0]
        margins = loop_margins(**loop, observer=d)
        summary["orders"][str(d.order)] = {
            "Q_peak_dB": float(20 * np.log10(np.abs(q).max())),
            "Q_peak_Hz": float(f[np.argmax(np.abs(q))]),
            "Q_minus3dB_Hz": float(f[below[0]]) if below.size else None,
            "error_gain_at_frequency": float(
                abs(estimation_response(d, args.frequency, error=True)[0])
            ),
            "S_peak_dB": float(20 * np.log10(np.abs(s).max())),
            "loop_margins": {
                **asdict(margins),
                "inertia_factor_range": list(margins.inertia_factor_range),
            },
        }
    columns_to_csv(columns, files.path("bode.csv"))
    _write_json(files, "bode.json", summary)
    return ["bode.png", "bode.csv", "bode.json"]


def _noise(args, files) -> list[str]:
    from .._table import columns_to_csv
    from ..analysis._figures import noise_figure
    from ..analysis._noise import noise_gains
    from ..observers._synthesis import design_observer

    loop = _loop(args)
    model = loop["nominal"].discretize(loop["Ts"])
    gains = [
        [
            noise_gains(**loop, observer=design_observer(model, order=m, bandwidth=g))
            for g in args.bandwidths
        ]
        for m in args.orders
    ]
    _save(noise_figure(args.bandwidths, args.orders, gains), files, "noise.png", args.dpi)
    rows = [
        {"order": m, "bandwidth_rad_s": g, **gain.to_dict()}
        for m, row in zip(args.orders, gains, strict=True)
        for g, gain in zip(args.bandwidths, row, strict=True)
    ]
    columns_to_csv({k: [r[k] for r in rows] for k in rows[0]}, files.path("noise.csv"))
    _write_json(files, "noise.json", {"loop": _describe(args), "gains": rows})
    return ["noise.png", "noise.csv", "noise.json"]


def _describe(args) -> dict:
    return {
        "J_n": args.J_n,
        "b_n": args.b_n,
        "J": args.J,
        "b": args.b,
        "Ts": args.Ts,
        "kp": args.kp,
        "kd": args.kd,
        "delay_samples": args.delay,
    }


def _tradeoff(args, files) -> list[str]:
    from ..analysis._tradeoff import noise_tradeoff
    from ..models._servo import ServoModel

    result = noise_tradeoff(
        nominal=ServoModel(args.J_n, args.b_n),
        Ts=args.Ts,
        frequency=args.frequency,
        bandwidths=args.bandwidths,
        orders=args.orders,
        noise=args.noise,
    )
    _save(result.plot(), files, "tradeoff.png", args.dpi)
    result.to_csv(files.path("tradeoff.csv"))
    reference = result.orders[0]
    summary = {
        "frequency_Hz": result.frequency,
        "noise": result.noise,
        "reference_order": reference,
        "improvement_at_equal_noise": {
            str(m): dict(
                zip(
                    [f"{g:.6g}" for g in result.bandwidths],
                    result.improvement(m, reference=reference).tolist(),
                    strict=True,
                )
            )
            for m in result.orders[1:]
        },
    }
    _write_json(files, "tradeoff.json", summary)
    return ["tradeoff.png", "tradeoff.csv", "tradeoff.json"]


def _stability(args, files) -> list[str]:
    from ..analysis._robust import robust_stability_map
    from ..models._servo import ServoModel

    loop = _loop(args)
    J_ratio = args.J / args.J_n
    values = args.values
    if values is None:
        values = _grid("0.1:10:61") if args.parameter == "J_ratio" else _grid("1e-4:10:61")
    # Map axes must increase; on the command line a grid is a set of values (10:1:5 or 3,1,2).
    values, bandwidths = sorted(set(values)), sorted(set(args.bandwidths))
    grid = (
        {"J_ratio": values, "b": args.b}
        if args.parameter == "J_ratio"
        else {"J_ratio": J_ratio, "b": values}
    )
    written, summary = [], {"loop": _describe(args), "maps": []}
    for m in args.orders:
        smap = robust_stability_map(
            **grid,
            bandwidth=bandwidths,
            order=m,
            nominal=ServoModel(args.J_n, args.b_n),
            Ts=args.Ts,
            controller=loop["controller"],
            delay_samples=args.delay,
        )
        stem = f"stability_{args.parameter}_m{m}" + (f"_delay{args.delay}" if args.delay else "")
        # Mark the loop's own plant at the canonical bandwidth if it lies on the map.
        point = (100.0, J_ratio if args.parameter == "J_ratio" else args.b)
        inside = (
            smap.bandwidths.min() <= point[0] <= smap.bandwidths.max()
            and smap.values.min() <= point[1] <= smap.values.max()
        )
        _save(smap.plot(mark=point if inside else None), files, f"{stem}.png", args.dpi)
        smap.to_csv(files.path(f"{stem}.csv"))
        written += [f"{stem}.png", f"{stem}.csv"]
        summary["maps"].append(
            {
                "order": m,
                "parameter": args.parameter,
                "delay_samples": args.delay,
                "stable_fraction": float(smap.stable.mean()),
                "boundary": smap.boundary(),
            }
        )
    _write_json(files, "stability.json", summary)
    return [*written, "stability.json"]
