"""The logs being identified: arrays or :class:`Log` objects, their loops, their filter
settings and regressions, and the refusals of a log that cannot take part."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    require_instance,
)
from ._checks import check_lengths, check_time, sample_vector
from ._log import Log
from ._loop import FeedbackLoop
from ._regression import (
    MIN_ROWS,
    Regression,
    Settings,
    adaptive_bandwidth,
    build_regression,
    minimum_samples,
    resolve_settings,
)

__all__ = ["Run", "as_runs", "check_run", "prepare", "resolve", "scaled"]


@dataclass
class Run:
    """One log being identified."""

    t: np.ndarray
    theta: np.ndarray
    u: np.ndarray
    loop: FeedbackLoop | None
    Ts: float
    name: str
    settings: Settings | None = None
    regression: Regression | None = None


def as_runs(t, theta, u, loop, time_tolerance):
    """The logs to identify, from arrays or from :class:`Log` objects."""
    if theta is None and u is None:
        logs = [t] if isinstance(t, Log) else t
        if not isinstance(logs, Sequence) or isinstance(logs, str) or not logs:
            raise ParameterTypeError(
                "identify takes (t, theta, u) arrays, a Log, or a non-empty list of Logs; got "
                f"{type(t).__name__} without theta and u"
            )
        for i, log in enumerate(logs):
            require_instance(log, Log, f"logs[{i}]")
        sources = [log.source or f"log {i}" for i, log in enumerate(logs)]
        if len(set(sources)) < len(sources):
            sources = [f"log {i} ({s})" for i, s in enumerate(sources)]
        runs = [
            Run(log.t, log.theta, log.u, None, log.Ts, name)
            for log, name in zip(logs, sources, strict=True)
        ]
    else:
        if theta is None or u is None:
            raise ParameterTypeError(
                "give t, theta and u (arrays), or one Log or a list of Logs alone"
            )
        t = sample_vector(t, "t", "times [s]")
        theta = sample_vector(theta, "theta", "positions [rad or m]")
        u = sample_vector(u, "u", "torques or forces [N m or N]")
        check_lengths({"t": t, "theta": theta, "u": u})
        runs = [Run(t, theta, u, None, check_time(t, "t", time_tolerance), "the log")]
    if loop is None or isinstance(loop, FeedbackLoop):
        loops = [loop] + [None] * (len(runs) - 1)
        if loop is not None and len(runs) > 1:
            raise ParameterTypeError(
                f"loop must be a list of {len(runs)} FeedbackLoops or None, one per log, got "
                "one FeedbackLoop for several logs"
            )
    elif isinstance(loop, Sequence) and len(loop) == len(runs):
        loops = [require_instance(x, FeedbackLoop, f"loop[{i}]", optional=True)
                 for i, x in enumerate(loop)]  # fmt: skip
    else:
        raise ParameterTypeError(
            f"loop must be a FeedbackLoop, None, or a list of {len(runs)} (one per log), "
            f"got {type(loop).__name__}"
        )
    for i, (run, lp) in enumerate(zip(runs, loops, strict=True)):
        if lp is not None and len(lp) != run.theta.size:
            which = f"loop[{i}]" if len(runs) > 1 else "loop"
            raise ParameterValueError(
                f"{which} must have one reference sample per logged sample: the log has "
                f"{run.theta.size}, {which}.reference has {len(lp)}"
            )
        run.loop = lp
    return runs


def resolve(run: Run, adaptive, bandwidth, cutoff, order, decimation, border, min_speed, zoh):
    """The settings of ``run``: the adaptive defaults (filters from the log, rests dropped
    when ``min_speed`` is None) or the benchmark's rules, overridden by what is given."""
    if adaptive and bandwidth is None and cutoff is None and decimation is None:
        bandwidth = adaptive_bandwidth(run.theta, run.Ts)
    return resolve_settings(
        run.Ts, bandwidth=bandwidth, cutoff=cutoff, order=order, decimation=decimation,
        border=border, min_speed=0.0 if min_speed is None else min_speed,
        zoh=adaptive if zoh is None else zoh, rests=adaptive and min_speed is None,
    )  # fmt: skip


def scaled(settings: Settings, factor: float, border_given: bool) -> Settings | None:
    """The settings with the filters' bandwidth scaled by ``factor`` (None if impossible)."""
    try:
        return resolve_settings(
            settings.Ts, bandwidth=settings.bandwidth * factor, cutoff=settings.cutoff * factor,
            order=settings.order, decimation=max(1, round(settings.decimation / factor)),
            border=settings.border if border_given else None, min_speed=settings.min_speed,
            zoh=settings.zoh, rests=settings.rests,
        )  # fmt: skip
    except ParameterValueError:
        return None


def prepare(run: Run, settings: Settings, where: str) -> None:
    needed = minimum_samples(settings)
    if run.theta.size < needed:
        raise ParameterValueError(
            f"the log{where} is too short to identify: {run.theta.size} samples, but decimation "
            f"= {settings.decimation} and border = {settings.border} need at least {needed} "
            f"for {MIN_ROWS} regression rows"
        )
    run.settings = settings
    run.regression = build_regression(run.theta, run.u, settings)
    check_run(run, where)


def check_run(run: Run, where: str) -> None:
    """Refuse a log that cannot take part, saying why."""
    theta, u, settings = run.theta, run.u, run.settings
    if np.ptp(theta) == 0.0:
        raise ParameterValueError(
            f"theta{where} does not move (every sample is {float(theta[0])!r}): a log at rest "
            "cannot identify J, b, coulomb and offset; log a run that moves"
        )
    if np.ptp(u) == 0.0:
        raise ParameterValueError(
            f"u{where} is constant (every sample is {float(u[0])!r}): the input must vary to "
            "identify J, b, coulomb and offset"
        )
    rows = run.regression.X.shape[0]
    rests = run.regression.rest_rows
    if rows < MIN_ROWS and rests:
        raise ParameterValueError(
            f"the log{where} rests most of the time: {rests} of {rows + rests} regression rows "
            f"are at rest (filtered speed below {run.regression.rest_speed:.3g}, 2 % of its "
            f"largest, for more than {settings.decimation} samples) and are dropped, leaving "
            f"{rows}, fewer than {MIN_ROWS}. Give more rows per move with "
            f"filter_bandwidth={2 * settings.bandwidth:.3g} (twice the {settings.bandwidth:.3g} Hz "
            f"read from the log: half the decimation, now {settings.decimation}), or keep "
            "the rest rows with min_speed=0 (the friction at rest is then read as offset), or "
            "log longer moves"
        )
    if rows < MIN_ROWS:
        raise ParameterValueError(
            f"min_speed = {settings.min_speed:g} leaves {rows} regression rows{where}, fewer "
            f"than {MIN_ROWS}: theta is slower than min_speed almost everywhere; lower min_speed"
        )
