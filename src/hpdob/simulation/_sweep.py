"""Batch sweeps and Monte Carlo studies over many closed-loop scenarios.

A sweep expands ``grid``/``vary`` into scenarios (:mod:`hpdob.simulation._sweep_spec`), runs them in
chunks (local threads by default; a dask.distributed cluster on request) and returns one row
of parameters and metrics per scenario. Traces are never kept, so memory grows with the
number of scenarios only.
"""

from __future__ import annotations

import math
import os
import sys
from concurrent.futures import ThreadPoolExecutor, as_completed

import numpy as np

from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    check_keys,
    require_instance,
)
from ..models._servo import ServoModel
from ..observers._runtime import DisturbanceObserver
from ..observers._synthesis import ObserverDesign, design_observer
from ._controller import PD
from ._devices import Actuator, Encoder
from ._result import CANONICAL_WINDOWS, metric_window
from ._simulate import (
    PLANT_TYPES,
    _observer_arrays,
    _sample_count,
    check_run_arguments,
    resolve_substeps,
    run_prepared,
    sample_signals,
)
from ._sweep_spec import expand_scenarios

__all__ = ["sweep"]

SIMULATE_KEYS = (
    "plant",
    "nominal",
    "Ts",
    "duration",
    "controller",
    "observer",
    "reference",
    "disturbance",
    "substeps",
    "sensor",
    "actuator",
    "x0",
)
OBSERVER_KEYS = ("order", "poles", "bandwidth", "gain_direction")
METRIC_COLUMNS = (
    "rms_estimation_error",
    "rms_position_error_regulation",
    "rms_position_error_tracking",
    "max_abs_position_error",
)


def _observer_spec(observer) -> dict | None:
    """A dict of DisturbanceObserver keyword arguments (built per scenario)."""
    if observer is None:
        return None
    if isinstance(observer, DisturbanceObserver):
        observer = observer.design
    if isinstance(observer, ObserverDesign):
        spec = {"order": observer.order, "gain_direction": tuple(observer.gain_direction)}
        if observer.bandwidth is not None:
            spec["bandwidth"] = observer.bandwidth
        else:
            spec["poles"] = tuple(observer.poles)
        return spec
    if not isinstance(observer, dict):
        raise ParameterTypeError(
            "base['observer'] must be a dict of DisturbanceObserver "
            f"arguments ({', '.join(OBSERVER_KEYS)}), a DisturbanceObserver "
            f"or None, got {type(observer).__name__}"
        )
    check_keys(observer, OBSERVER_KEYS, "observer")
    if "order" not in observer:
        raise ParameterValueError(
            f"base['observer'] must have the required key 'order' (keys: "
            f"{', '.join(OBSERVER_KEYS)}), got {observer!r}"
        )
    return dict(observer)


def _resolve_base(base, *, varies_Ts: bool = False) -> dict:
    if not isinstance(base, dict):
        raise ParameterTypeError(
            f"base must be a dict of simulate() arguments, got {type(base).__name__}"
        )
    check_keys(base, SIMULATE_KEYS, "base")
    missing = [
        k
        for k in ("plant", "nominal", "Ts", "duration", "controller", "reference")
        if k not in base
    ]
    if missing:
        raise ParameterValueError(f"base is missing the required key {missing[0]!r}")
    resolved = dict(base)
    resolved["observer"] = _observer_spec(base.get("observer"))
    # Shared arguments are checked here, once, so that a typo fails the call instead of
    # every scenario (per-scenario values are checked again in run_scenario).
    # substeps None: per scenario, the default or a MujocoServo's own
    Ts, duration, substeps, x0 = check_run_arguments(
        base["Ts"], base["duration"], base.get("substeps"), base.get("x0", (0.0, 0.0))
    )
    if not varies_Ts:  # else checked per scenario, against that scenario's Ts
        _sample_count(Ts, duration)
    require_instance(base.get("sensor"), Encoder, "sensor", optional=True)
    require_instance(base.get("actuator"), Actuator, "actuator", optional=True)
    resolved.update(Ts=Ts, duration=duration, substeps=substeps, x0=tuple(x0.tolist()))
    return resolved


def _metric_windows(windows) -> dict:
    resolved = dict(CANONICAL_WINDOWS)
    if windows is None:
        return resolved
    if not isinstance(windows, dict):
        raise ParameterTypeError(
            "metric_windows must be a dict like {'regulation': (1.2, 4.0), 'tracking': "
            f"(4.0, inf)}} or None, got {type(windows).__name__}"
        )
    check_keys(windows, tuple(CANONICAL_WINDOWS), "metric_windows")
    for name, bounds in windows.items():
        resolved[name] = metric_window(bounds, f"metric_windows['{name}']")
    return resolved


def _scenario_parts(base: dict, params: dict):
    """Validated simulate() pieces of one scenario (raises Parameter*Error on bad values)."""

    def sub(prefix):
        return {k[len(prefix) :]: v for k, v in params.items() if k.startswith(prefix)}

    plant = require_instance(base["plant"], PLANT_TYPES, "plant").replace(**sub("plant."))
    nominal = require_instance(base["nominal"], ServoModel, "nominal").replace(**sub("nominal."))
    ctrl = require_instance(base["controller"], PD, "controller")
    gains = {"kp": ctrl.kp, "kd": ctrl.kd, **sub("controller.")}
    controller = PD(gains["kp"], gains["kd"], feedforward=ctrl.feedforward)
    Ts = params.get("Ts", base["Ts"])
    spec = base["observer"]
    design = None
    if spec is not None:
        spec = {**spec, **sub("observer.")}
        if "observer.bandwidth" in params:
            spec.pop("poles", None)
        design = design_observer(nominal.discretize(Ts), **spec)
    elif sub("observer."):
        raise ParameterValueError("observer.* parameters need base['observer']")
    return plant, nominal, controller, Ts, design


def run_scenario(base: dict, params: dict, cache: dict | None = None) -> dict:
    """Simulate one scenario and return its row (metrics, ``stable``, ``error``).

    ``base`` comes from :func:`_resolve_base`. ``cache`` maps ``(Ts, n, substeps)`` to the
    sampled reference and disturbance, shared by scenarios with the same time grid.
    """
    row = dict(params)
    try:
        plant, nominal, controller, Ts, design = _scenario_parts(base, params)
        S = resolve_substeps(plant, Ts, base["substeps"])
        n = _sample_count(Ts, base["duration"])
        x0 = np.array(base["x0"])  # checked once in _resolve_base, like sensor and actuator
        key = (Ts, n, S)
        signals = None if cache is None else cache.get(key)
        if signals is None:
            signals = sample_signals(
                base["reference"], base.get("disturbance"), Ts=Ts, n=n, substeps=S
            )
            if cache is not None:
                cache[key] = signals
        design, z0 = _observer_arrays(design, nominal, Ts, x0)  # starts at x0, tau0 = 0
        result = run_prepared(
            plant=plant,
            nominal=nominal,
            controller=controller,
            design=design,
            z0=z0,
            sensor=base.get("sensor"),
            actuator=base.get("actuator") or Actuator(),
            x0=x0,
            signals=signals.scaled(float(params.get("disturbance_scale", 1.0))),
        )
    except (ParameterValueError, ParameterTypeError) as err:
        row.update(dict.fromkeys(METRIC_COLUMNS, math.nan), stable=False, error=str(err))
        return row
    row.update(result.metrics(**base["metric_windows"]))
    row["max_abs_position_error"] = result.max_abs_position_error()
    row["stable"] = not result.diverged
    row["error"] = result.message if result.diverged else ""
    return row


def run_chunk(base: dict, chunk: list) -> list:
    """Rows of ``chunk``, a list of ``(index, params)``; runs anywhere (local or a worker)."""
    cache: dict = {}
    return [{"scenario": index, **run_scenario(base, params, cache)} for index, params in chunk]


def _chunks(scenarios: list, workers: int) -> list:
    """Split ``[(index, params)]`` into chunks: ~8 per worker, 1-64 scenarios each."""
    indexed = list(enumerate(scenarios))
    size = max(1, min(64, math.ceil(len(indexed) / (8 * max(workers, 1)))))
    return [indexed[i : i + size] for i in range(0, len(indexed), size)]


def _progress_callback(progress, total: int):
    """Return ``(update(n), close())`` for the requested progress display."""
    if callable(progress):
        done = [0]

        def update(n):
            done[0] += n
            progress(done[0], total)

        return update, lambda: None
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        return (lambda n: None), (lambda: None)
    from tqdm.auto import tqdm

    bar = tqdm(total=total, unit="scenario", desc="hpdob sweep", file=sys.stderr)
    return bar.update, bar.close


def _run_local(base, chunks, workers, update) -> list:
    rows = []
    with ThreadPoolExecutor(max_workers=workers) as pool:  # the kernel releases the GIL
        futures = [pool.submit(run_chunk, base, chunk) for chunk in chunks]
        for future in as_completed(futures):
            chunk_rows = future.result()
            rows.extend(chunk_rows)
            update(len(chunk_rows))
    return rows


def _run_dask(base, scenarios, scheduler, update) -> list:
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "a scheduler address or Client needs dask.distributed: pip install 'hpdob[dask]'"
        ) from err
    own = isinstance(scheduler, str)
    client = Client(scheduler) if own else scheduler
    try:
        chunks = _chunks(scenarios, len(client.scheduler_info().get("workers", {})))
        # Each task carries the (small) base itself rather than a scattered copy: tasks then
        # have no data dependencies, so a task whose worker dies is simply run again elsewhere
        # (scattered data lost with a worker cancels its dependants: "lost dependencies").
        # pure=False: never reuse results across sweeps; retries also covers transient failures.
        futures = [client.submit(run_chunk, base, chunk, pure=False, retries=3) for chunk in chunks]
        rows = []
        for future in dask_completed(futures):
            chunk_rows = future.result()
            rows.extend(chunk_rows)
            update(len(chunk_rows))
        return rows
    finally:
        if own:
            client.close()


def _workers_and_mode(scheduler):
    if scheduler is None or scheduler == "threads":
        return os.cpu_count() or 1, "local"
    if isinstance(scheduler, bool):
        raise ParameterTypeError(
            f"scheduler must be None, a number of local workers, "
            f"'tcp://host:port' or a dask Client, got {scheduler!r}"
        )
    if isinstance(scheduler, int):
        return as_int(
            scheduler, "scheduler", "a positive number of local workers", minimum=1
        ), "local"
    if isinstance(scheduler, str):
        if "://" not in scheduler:
            raise ParameterValueError(
                f"scheduler must be 'threads', a number of local workers "
                f"or a dask address like 'tcp://127.0.0.1:8786', got "
                f"{scheduler!r}"
            )
        return None, "dask"  # the workers are counted once connected
    if type(scheduler).__name__ == "Client":
        return None, "dask"
    raise ParameterTypeError(
        f"scheduler must be None, a number of local workers, "
        f"'tcp://host:port' or a dask Client, got {type(scheduler).__name__}"
    )


def sweep(
    base: dict,
    *,
    grid=None,
    vary=None,
    n=None,
    seed=0,
    metric_windows=None,
    scheduler=None,
    progress=None,
):
    """Run many closed-loop scenarios and return one row of parameters and metrics each.

    Parameters
    ----------
    base : dict
        Keyword arguments of :func:`hpdob.simulate` shared by all scenarios. ``observer`` may
        be a dict of :class:`DisturbanceObserver` arguments (``order``, ``bandwidth`` or
        ``poles``, ``gain_direction``), built per scenario on ``nominal.discretize(Ts)`` and
        started at ``x0`` with ``tau0 = 0`` (an observer object is turned into such a dict).
    grid : dict, optional
        Dotted path -> list of values; the scenarios are their Cartesian product. Paths:
        ``plant.J``, ``plant.b``, ``plant.coulomb``, ``plant.coulomb_velocity`` (a
        :class:`ServoModel` plant), ``plant.link_mass``, ``plant.link_length`` (a
        :class:`MujocoServo` plant), ``nominal.J``,
        ``nominal.b``, ``observer.order``, ``observer.bandwidth``, ``controller.kp``,
        ``controller.kd``, ``Ts``, ``disturbance_scale`` (multiplies the disturbance).
    vary : dict, optional
        Path -> ``("uniform", low, high)``, ``("normal", mean, std)`` or
        ``("loguniform", low, high)``; ``n`` draws per grid point.
    n : int, optional
        Number of random draws (required with ``vary``).
    seed : int, optional
        Seed of all draws (``numpy.random.default_rng``). Same seed, same rows, bit for bit,
        locally or on a cluster.
    metric_windows : dict, optional
        ``{"regulation": (start, stop), "tracking": (start, stop)}`` [s]: the windows of the
        position metrics (:meth:`SimulationResult.metrics`); missing entries keep the
        canonical windows (1.2-4 s and 4 s-inf).
    scheduler : None, int, str or dask.distributed.Client, optional
        None or ``"threads"``: all local cores (threads; the compiled kernel releases the GIL).
        An int: that many local threads. ``"tcp://host:port"`` or a ``Client``: run chunks of
        scenarios on that dask cluster (``pip install 'hpdob[dask]'``); a worker that dies
        mid-sweep has its chunks rerun elsewhere.
    progress : None, bool or callable, optional
        None: a progress bar on a terminal (stderr), silent otherwise. True/False force it on
        or off; a callable is called as ``progress(done, total)``.

    Returns
    -------
    pandas.DataFrame
        One row per scenario, in scenario order: ``scenario``, the varied parameters, the
        three metrics of :meth:`SimulationResult.metrics`, ``max_abs_position_error`` [rad],
        ``stable`` (False if the run diverged or its parameters were invalid) and ``error``
        (the divergence or validation message; empty when all went well).

    Raises
    ------
    ValueError, TypeError
        For a bad ``base``, an unknown path (the valid ones are listed), a bad distribution,
        or a bad scheduler. Bad *values* in a scenario (e.g. a negative inertia drawn from a
        normal distribution) do not raise: that row gets ``stable=False`` and the message.

    Examples
    --------
    >>> from hpdob import sweep
    >>> from hpdob import paper
    >>> base = {**paper.scenario(), "duration": 2.0, "observer": {"order": 1,
    ...         "bandwidth": 100.0}}
    >>> rows = sweep(base, grid={"observer.order": [0, 1]}, progress=False)
    >>> rows[["observer.order", "stable"]].to_dict("records")
    [{'observer.order': 0, 'stable': True}, {'observer.order': 1, 'stable': True}]
    """
    try:
        import pandas as pd
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "hpdob.sweep returns a pandas DataFrame: pip install 'hpdob[sweep]'"
        ) from err
    varies_Ts = "Ts" in (grid or {}) or "Ts" in (vary or {})
    resolved = _resolve_base(base, varies_Ts=varies_Ts)
    resolved["metric_windows"] = _metric_windows(metric_windows)
    scenarios = expand_scenarios(grid, vary, n, seed)
    workers, mode = _workers_and_mode(scheduler)
    # Validate the shared part once, loudly, before spending time on scenarios.
    _scenario_parts(resolved, {})
    sample_signals(
        resolved["reference"], resolved.get("disturbance"), Ts=resolved["Ts"], n=2, substeps=1
    )
    update, close = _progress_callback(progress, len(scenarios))
    try:
        if mode == "local":
            rows = _run_local(resolved, _chunks(scenarios, workers), workers, update)
        else:
            rows = _run_dask(resolved, scenarios, scheduler, update)
    finally:
        close()
    rows.sort(key=lambda row: row["scenario"])
    columns = [
        "scenario",
        *(list(grid or {}) + sorted(vary or {})),
        *METRIC_COLUMNS,
        "stable",
        "error",
    ]
    return pd.DataFrame(rows, columns=columns)
