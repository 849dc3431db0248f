"""``hpdob simulate scenario.toml``: run a scenario described in TOML."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ._options import add_scenario_overrides, apply_scenario_overrides, output_path
from ._progress import ProgressLine, show_progress

__all__ = ["register"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "simulate",
        help="run a closed-loop scenario described in a TOML file",
        description="Simulate the scenario in a TOML file (plant, nominal, Ts, duration, "
        "controller, observer, reference, disturbance, sensor, actuator; see "
        "docs/simulation.md and the .toml files in examples/), or an N-joint arm "
        '([plant] type = "mujoco-arm" or "two-link-arm", per-joint [[observer]] tables; see '
        "docs/robots.md). Writes <label>.csv, metrics.json and <label>.png into the output "
        "directory.",
    )
    parser.add_argument("scenario", type=Path, help="scenario file (.toml)")
    parser.add_argument(
        "--out",
        type=output_path,
        default=None,
        metavar="DIR",
        help="output directory (default: hpdob-results/<scenario name>)",
    )
    parser.add_argument("--no-plot", action="store_true", help="skip the figure")
    add_scenario_overrides(parser)
    parser.add_argument(
        "--force-window",
        type=float,
        nargs=2,
        default=None,
        metavar=("START", "STOP"),
        help="the window [s] of the steady-state force metrics (force_rms_*_steady) of a run "
        "against a wall with a reaction-torque observer: the samples with START <= t < STOP "
        "(STOP may be inf); default: from 0.5 s after the first contact to the end. Refused "
        "on a scenario without such metrics and for a window that holds no sample of the run",
    )
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="samples done and time left on stderr, then the writing stage (default: when "
        "stderr is a terminal)",
    )
    parser.set_defaults(handler=_run)


def _scenario(args):
    """The scenario's simulate() arguments and metric windows, with the command's overrides."""
    from .. import robots  # noqa: F401  # registers the arm plant types (registration from above)
    from ..simulation import metric_windows, read_toml, scenario_from_dict

    data = apply_scenario_overrides(args, read_toml(args.scenario))
    kwargs = scenario_from_dict(data)
    kwargs.setdefault("label", args.scenario.stem)
    return kwargs, metric_windows(data)


def _run_own_loop(args: argparse.Namespace, data: dict, kind) -> int:
    """A scenario whose plant type has a loop of its own (``PlantType.scenario``: the N-joint
    arms, ``[plant] type = "mujoco-arm"``; docs/robots.md), with per-joint metrics."""
    import warnings

    from .._files import check_file_stem, json_text, staged_outputs
    from ..simulation import SimulationDivergedWarning
    from ._errors import CLIError

    if args.measurement is not None or args.pd_velocity is not None:
        raise CLIError("--measurement and --pd-velocity apply to single-axis scenarios only")
    scenario = kind.scenario(data, args.scenario)
    start = scenario.metrics_start
    out = args.out or Path("hpdob-results") / args.scenario.stem
    stem = check_file_stem(scenario.run["label"], "label")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimulationDivergedWarning)  # reported below instead
        result = scenario.simulate()
    metrics = result.metrics(start=start)
    with staged_outputs(out, markers=["metrics.json"]) as files:
        result.to_csv(files.path(f"{stem}.csv"))
        if not args.no_plot:
            files.plot(f"{stem}.png", lambda: result.plot())
        per_joint = {
            joint: {name: values[j] for name, values in metrics.items()}
            for j, joint in enumerate(result.joint_names)
        }
        files.write_text("metrics.json", json_text({stem: per_joint}))
    print(f"{'joint':<10}" + "".join(f"{name:>24}" for name in metrics))
    for joint, values in per_joint.items():
        print(f"{joint:<10}" + "".join(f"{v:>24.6e}" for v in values.values()))
    print(f"wrote {stem}.csv, metrics.json{'' if args.no_plot else f', {stem}.png'} to {out}")
    if result.diverged:
        print("warning: the run diverged")
        return 1
    return 0


def _previous_files(out: Path) -> list[str]:
    """The files of the run whose metrics.json is in ``out`` (its keys are the labels)."""
    import json

    from .._files import check_file_stem
    from .._validation import ParameterTypeError, ParameterValueError

    try:
        labels = list(json.loads((out / "metrics.json").read_text(encoding="utf-8")))
    except (OSError, ValueError, TypeError):
        return []
    names = []
    for label in labels:
        try:  # a label that is not a plain file name never names a file to delete
            check_file_stem(label)
        except (ParameterTypeError, ParameterValueError):
            continue
        names += [f"{label}.csv", f"{label}.png"]
    return names


def _run(args: argparse.Namespace) -> int:
    import warnings

    from .._files import check_file_stem, check_output, staged_outputs
    from ..simulation import (
        SimulationDivergedWarning,
        force_reference,
        force_run_metrics,
        metrics_json,
        plant_type_of,
        position_metrics_apply,
        read_toml,
        simulate,
    )

    data = read_toml(args.scenario)
    kind = plant_type_of(data)  # the registry: a type with a loop of its own runs that loop
    if kind is not None and kind.scenario is not None:
        return _run_own_loop(args, data, kind)
    kwargs, windows = _scenario(args)
    window = "steady" if args.force_window is None else _force_window(args.force_window)
    if args.force_window is not None:
        _check_force_window(window, kwargs, args.scenario)
    out = args.out or Path("hpdob-results") / args.scenario.stem
    # The label names the output files: never a path (e.g. "../escaped") nor a hidden name.
    stem = check_file_stem(kwargs.get("label") or args.scenario.stem, "label")
    check_output(out)  # before the run, not after it
    show = show_progress(args.progress)
    _check_size(kwargs, showing=show)
    line = ProgressLine("hpdob simulate:", unit="samples")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SimulationDivergedWarning)  # reported below instead
        try:  # the kernel runs in chunks when progress is shown: the same bits (simulate())
            result = simulate(**kwargs, progress=line if show else None)
        finally:  # an error or interrupt message starts on its own line
            line.end()
    metrics = result.metrics(**windows)
    controller = kwargs["controller"]
    if not position_metrics_apply(controller):  # r is tau_ref [N m]: theta - r means nothing
        for name in ("regulation", "tracking"):
            metrics.pop(f"rms_position_error_{name}", None)
    # against a wall: the impact, tau_reac vs tau_contact, tau_contact vs tau_ref
    # (docs/force-control.md); the same function gives a sweep's rows
    metrics.update(force_run_metrics(result, controller, window=window))
    force_kind, tau_ref = force_reference(result, controller)
    # Staged: renamed together when all are written, metrics.json last (docs/reliability.md).
    # The previous run's <label>.csv/.png (another label, or a figure this --no-plot run does
    # not draw) are removed at the commit: the directory holds one consistent set.
    replaces = [*_previous_files(out), f"{stem}.png"]
    # rows written, chunk by chunk (32768 rows each: the column-wise writer's chunks)
    writing = ProgressLine(f"hpdob simulate: writing {stem}.csv", unit="rows")
    try:
        if show:
            writing(0, len(result))
        with staged_outputs(out, markers=["metrics.json"], replaces=replaces) as files:
            result.to_csv(files.path(f"{stem}.csv"), progress=writing if show else None)
            if not args.no_plot:
                files.plot(f"{stem}.png", lambda: result.plot_force(tau_ref=tau_ref)
                           if force_kind else result.plot())  # fmt: skip
            files.write_text("metrics.json", metrics_json({stem: metrics}))
    finally:
        writing.end()
    for name, value in metrics.items():
        print(f"{name:<32}{value:.6e}")
    print(f"wrote {stem}.csv, metrics.json{'' if args.no_plot else f', {stem}.png'} to {out}")
    if result.diverged:
        print(f"warning: {result.message}")
        return 1
    return 0


def _force_window(bounds) -> tuple[float, float]:
    """``--force-window START STOP`` checked before the run (START < STOP, not NaN)."""
    from .._validation import ParameterValueError
    from ..simulation import metric_window
    from ._errors import CLIError

    try:
        return metric_window(bounds, "--force-window")
    except ParameterValueError as err:
        raise CLIError(str(err)) from None


def _check_force_window(window, kwargs, path) -> None:
    """Refuse ``--force-window`` where it would be ignored (no steady force metrics: no wall,
    no reaction-torque observer or no force controller) or would hold no sample (NaN)."""
    from types import SimpleNamespace

    import numpy as np

    from ..simulation import force_run_columns, sample_count
    from ._errors import CLIError

    parts = SimpleNamespace(plant=kwargs["plant"], observer=kwargs.get("observer"),
                            controller=kwargs["controller"])  # fmt: skip
    if "force_steady_start" not in force_run_columns(parts):
        raise CLIError(
            f"--force-window: {path} reports no steady force metrics to window (they need a "
            "wall, [plant.environment], a [reaction_observer] and a force, impedance or "
            "switching controller); drop --force-window"
        )
    try:
        n = sample_count(kwargs["Ts"], kwargs["duration"])
    except (TypeError, ValueError):
        return  # simulate() reports it with its own message
    t = np.arange(n) * kwargs["Ts"]  # the sampling instants of the run, as simulate's
    start, stop = window
    if not np.any((t >= start) & (t < stop)):
        raise CLIError(
            f"--force-window [{start:g}, {stop:g}] s holds no sample of the run (t = 0 to "
            f"{t[-1] if n else 0.0:g} s): the window must overlap the run"
        )


#: Plant steps above which ``hpdob simulate`` says on stderr how big the run is before it.
NOTICE_PLANT_STEPS = 10**7

#: Samples per run of ``hpdob simulate`` (the library's simulate() has no such limit, only
#: its 1e8 plant steps): every sample is a row of <label>.csv, about 175 bytes, so this bounds
#: the command to about a minute and 350 MB (docs/reliability.md: 2e6 samples took 28 s).
MAX_SAMPLES = 2_000_000


def _check_size(kwargs, *, showing: bool = False) -> None:
    """Refuse a run beyond :data:`MAX_SAMPLES`, and state the size of a long one before it
    when its progress is not shown (``showing``)."""
    from ..simulation import MAX_PLANT_STEPS, sample_count
    from ._errors import CLIError

    try:
        n = sample_count(kwargs["Ts"], kwargs["duration"])
        substeps = kwargs["plant"].substeps(kwargs["Ts"], kwargs.get("substeps"))
    except (TypeError, ValueError):
        return  # simulate() reports it with its own message
    if n > MAX_SAMPLES:
        raise CLIError(
            f"a run of {n} samples (duration {kwargs['duration']:.12g} s at Ts = "
            f"{kwargs['Ts']:.12g} s) is beyond hpdob simulate's limit of {MAX_SAMPLES} samples "
            "per run (each sample is a row of the CSV it writes: the limit keeps a run to "
            "about a minute); shorten duration, raise Ts, or call hpdob.simulate() from Python "
            f"(no CSV; its limit is {MAX_PLANT_STEPS:.0e} plant steps)"
        )
    steps = n * substeps
    if not showing and NOTICE_PLANT_STEPS < steps <= MAX_PLANT_STEPS:
        print(
            f"hpdob simulate: a long run of {n} samples x {substeps} substeps = {steps:.3g} "
            f"plant steps (the limits per run are {MAX_SAMPLES} samples and "
            f"{MAX_PLANT_STEPS:.0e} plant steps); --progress shows how far it is",
            file=sys.stderr,
            flush=True,
        )
