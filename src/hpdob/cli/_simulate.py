"""``hpdob simulate scenario.toml``: run a scenario described in TOML."""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "simulate",
        help="run a closed-loop scenario described in a TOML file",
        description="Simulate the scenario in a TOML file (plant, nominal, Ts, duration, "
        "controller, observer, reference, disturbance, sensor, actuator; see "
        "docs/simulation.md and the .toml files in examples/). Writes <label>.csv, "
        "metrics.json and <label>.png into the output directory.",
    )
    parser.add_argument("scenario", type=Path, help="scenario file (.toml)")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="output directory (default: hpdob-results/<scenario name>)",
    )
    parser.add_argument("--no-plot", action="store_true", help="skip the figure")
    parser.add_argument(
        "--measurement",
        choices=("state", "position"),
        default=None,
        help="override the [observer] table's measurement: angle and velocity (state) or the "
        "angle only (position); the other family's gain_direction/velocity_bandwidth is dropped",
    )
    parser.add_argument(
        "--pd-velocity",
        choices=("measured", "observer"),
        default=None,
        help="override the [controller] table's velocity: the sensor's, or the position-only "
        "observer's estimate",
    )
    parser.set_defaults(handler=_run)


def _scenario(args):
    """The scenario's simulate() arguments and metric windows, with the command's overrides."""
    from ..simulation._scenario import _read_toml, metric_windows, scenario_from_dict
    from ._errors import CLIError

    data = _read_toml(args.scenario)
    if args.measurement is not None:
        table = data.get("observer")
        if not isinstance(table, dict):
            raise CLIError(
                f"--measurement needs an [observer] table in {args.scenario}, which has none"
            )
        other = "gain_direction" if args.measurement == "position" else "velocity_bandwidth"
        data["observer"] = {
            **{k: v for k, v in table.items() if k != other},
            "measurement": args.measurement,
        }
    if args.pd_velocity is not None and isinstance(data.get("controller"), dict):
        data["controller"] = {**data["controller"], "velocity": args.pd_velocity}
    kwargs = scenario_from_dict(data)
    kwargs.setdefault("label", args.scenario.stem)
    return kwargs, metric_windows(data)


def _run(args: argparse.Namespace) -> int:
    import warnings

    from ..simulation._result import metrics_json
    from ..simulation._simulate import SimulationDivergedWarning, simulate

    kwargs, windows = _scenario(args)
    out = args.out or Path("hpdob-results") / args.scenario.stem
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimulationDivergedWarning)  # reported below instead
        result = simulate(**kwargs)
    out.mkdir(parents=True, exist_ok=True)
    stem = result.label or args.scenario.stem
    result.to_csv(out / f"{stem}.csv")
    metrics = result.metrics(**windows)
    (out / "metrics.json").write_text(metrics_json({stem: metrics}))
    if not args.no_plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig = result.plot()
        fig.savefig(out / f"{stem}.png", dpi=150)
        plt.close(fig)
    for name, value in metrics.items():
        print(f"{name:<32}{value:.6e}")
    print(f"wrote {stem}.csv, metrics.json{'' if args.no_plot else f', {stem}.png'} to {out}")
    if result.diverged:
        print(f"warning: {result.message}")
        return 1
    return 0
