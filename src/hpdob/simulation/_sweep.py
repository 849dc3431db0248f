"""Batch sweeps and Monte Carlo studies over many closed-loop scenarios.

A sweep expands ``grid``/``vary`` into scenarios (``_sweep_spec``), runs them in chunks (local
threads by default; a dask.distributed cluster on request) and returns one row of parameters
and metrics per scenario. Traces are never kept, so memory grows with the number of scenarios
only.
"""

from __future__ import annotations

import dataclasses
import math
import os
import signal
import sys
import threading
from collections import OrderedDict
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

import numpy as np

from .._interrupts import checkpoint
from .._validation import (
    ParameterTypeError,
    ParameterValueError,
    as_int,
    check_keys,
    require_instance,
)
from ..observers import (
    FRICTION_PARAMETERS,
    ReactionObserverDesign,
    check_spec,
    design_from_spec,
    get_family,
    spec_of,
)
from ._derived import frozen, run_substeps
from ._force_run import force_run_columns, force_run_metrics, position_metrics_apply
from ._loop import LOOP_KEYS, ServoLoop
from ._result import CANONICAL_WINDOWS, metric_window
from ._scenario import Scenario
from ._simulate import (
    check_run_arguments,
    error_run_applies,
    metrics_run_inputs,
    run_loop,
    run_metrics,
    sample_count,
    sample_signals,
)
from ._sweep_dask import SweepIncomplete, SweepInterrupted, _Incomplete, _run_dask, resumed_rows
from ._sweep_spec import check_paths_apply, expand_scenarios, replaced_plant

__all__ = ["SweepIncomplete", "SweepInterrupted", "sweep"]


#: Keys of a sweep's ``base``: a ``loop`` (or the loop's keyword arguments) and the run's.
SIMULATE_KEYS = (*LOOP_KEYS, "duration", "reference", "disturbance", "substeps", "x0", "loop")
METRIC_COLUMNS = (
    "rms_estimation_error",
    "rms_position_error_regulation",
    "rms_position_error_tracking",
    "max_abs_position_error",
)


def _observer_parts(observer):
    """``(spec, object)``: a dict spec of a known family (redesigned per scenario), or an
    observer object used as it is."""
    if observer is None:
        return None, None
    if isinstance(observer, dict):
        return check_spec(observer, "observer", owner="base['observer']"), None
    spec = spec_of(observer)
    if spec is not None:
        return spec, None
    if getattr(observer, "system", None) is None:
        raise ParameterTypeError(
            "base['observer'] must be a dict of DisturbanceObserver arguments (order, poles, "
            "bandwidth, measurement, velocity_bandwidth, gain_direction), an observer object or "
            "None, got "
            f"{type(observer).__name__}"
        )
    return None, observer


def _base_dict(base, run: dict):
    """The dict form of ``base``; ``run`` holds the run settings given beside a ServoLoop."""
    given = {k: v for k, v in run.items() if v is not None}
    if isinstance(base, ServoLoop):  # like simulate(loop, reference=..., duration=...)
        missing = [k for k in ("duration", "reference") if k not in given]
        if missing:
            raise ParameterValueError(
                f"{missing[0]} is required with a ServoLoop base: "
                f"sweep(loop, grid=..., duration=..., reference=...), got None"
            )
        return {"loop": base, **given}
    if given:
        name = next(iter(given))
        raise ParameterValueError(
            f"{name} is a keyword of sweep(loop, ...) with a ServoLoop base only, got {name}="
            f"{given[name]!r} with a {type(base).__name__} base: put it in the base instead"
        )
    if isinstance(base, Scenario):  # a loop and its run settings (load_scenario)
        return {"loop": base.loop, **{k: v for k, v in base.run.items() if k != "label"}}
    return base


def _resolve_base(base, *, varies_Ts: bool = False, run: dict | None = None) -> dict:
    base = _base_dict(base, run or {})
    if not isinstance(base, dict):
        raise ParameterTypeError(
            "base must be a ServoLoop, a Scenario or a dict of simulate() arguments, got "
            f"{type(base).__name__}"
        )
    check_keys(base, SIMULATE_KEYS, "base")
    if "loop" in base:
        loop = require_instance(base["loop"], ServoLoop, "base['loop']")
        clash = [k for k in LOOP_KEYS if k in base]
        if clash:
            raise ParameterValueError(
                f"base has a 'loop' and the loop argument {clash[0]!r}: vary the loop with "
                f"grid paths instead, or give the loop's arguments without 'loop'"
            )
        keywords = loop.keywords()
        required = ("duration", "reference")
    else:
        keywords = {k: base[k] for k in LOOP_KEYS if k in base}
        required = ("plant", "nominal", "Ts", "duration", "controller", "reference")
    missing = [k for k in required if k not in base]
    if missing:
        raise ParameterValueError(f"base is missing the required key {missing[0]!r}")
    spec, observer = _observer_parts(keywords.pop("observer", None))
    # The shared loop is validated here, once, so that a typo fails the call instead of
    # every scenario (substeps None: per scenario, the default or a MujocoServo's own). A fixed
    # observer object is part of it: a controller may read its outputs (tau_reac).
    if observer is not None:
        keywords["observer"] = observer
    loop = ServoLoop(**keywords)
    Ts, duration, substeps, x0 = check_run_arguments(
        loop.Ts, base["duration"], base.get("substeps"), base.get("x0", (0.0, 0.0))
    )
    if not varies_Ts:  # else checked per scenario, against that scenario's Ts
        sample_count(Ts, duration)
    return {
        "loop": loop,
        "observer_spec": spec,
        "observer_object": observer,
        "duration": duration,
        "reference": base["reference"],
        "disturbance": base.get("disturbance"),
        "substeps": substeps,
        "x0": tuple(x0.tolist()),
    }


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


#: The plain scalar types a key holds as ``(type name, value)`` (by exact type: a subclass,
#: numpy's float64 included, takes the general path below).
_SCALARS = frozenset((int, str, bool, type(None), complex))


def _frozen(value):
    """``value`` as a hashable key (lists and arrays become tuples), or None if it is not."""
    kind = type(value)
    if kind is float:  # the common cases first, by exact type (a sweep asks twice a scenario)
        return ("float", value.hex())
    if kind in _SCALARS:
        return (kind.__name__, value)
    if kind is dict and all(type(k) is str for k in value):  # sorted by the keys themselves
        items = tuple((k, _frozen(value[k])) for k in sorted(value))
        return None if any(v is None for _, v in items) else items
    if isinstance(value, dict):
        items = tuple((k, _frozen(v)) for k, v in sorted(value.items(), key=lambda kv: str(kv[0])))
        return None if any(v is None for _, v in items) else items
    if isinstance(value, (list, tuple, np.ndarray)):
        items = tuple(
            _frozen(v) for v in (value.tolist() if isinstance(value, np.ndarray) else value)
        )
        return None if any(v is None for v in items) else items
    if isinstance(value, float):  # by its bits: -0.0 and 0.0 are different scenarios
        return ("float", value.hex())
    try:
        hash(value)
    except TypeError:
        return None
    return (type(value).__name__, value)


#: Held while a sweep's cache is filled: a design (or plant, or time grid) is made once even
#: when two threads ask for it together. Filling holds the GIL anyway, so this costs no overlap.
_FILLING = threading.RLock()


def _cached(cache: dict | None, key, make):
    """``cache[key]``, made by ``make()`` on the first request (no cache, or a key with an
    unhashable part, ``None`` inside: ``make()`` each time)."""
    if cache is None or key is None or key[-1] is None:
        return make()
    value = cache.get(key)
    if value is None:
        with _FILLING:
            value = cache.get(key)
            if value is None:
                value = make()
                cache[key] = value
    return value


def _varied_spec(spec: dict, varied: dict) -> dict:
    """``spec`` with the swept design arguments ``varied``: a varied bandwidth replaces the
    poles, and the family's ``respec`` drops what no longer applies."""
    base_spec, spec = spec, {**spec, **varied}
    family = get_family(spec.get("type", "dob"))
    if family.tuned in varied:
        for key in family.replaced_by_bandwidth:
            spec.pop(key, None)
    if family.respec is not None:
        spec = family.respec(spec, set(varied), base_spec)
    return spec


#: The designs of the process's recent sweeps, most recently used last: a sweep run again (a
#: tuning loop, a notebook cell, a benchmark's repeats) takes its observers from here instead of
#: designing them again (0.3-0.6 ms each, the exact stability and realised-pole checks). Only
#: designs that are pure functions of their key: a frozen nominal model and a spec of plain
#: values (numbers, strings, booleans, None and tuples of them); the family's record is part of
#: the key, so a family registered again designs anew. Guarded by ``_FILLING``.
_KEPT_DESIGNS: OrderedDict = OrderedDict()
#: At most this many designs are kept (each a few kB: its matrices and program).
KEPT_DESIGNS_MAX = 1024
_PLAIN = (float, int, str, bool, complex, type(None))


def clear_kept_designs() -> None:
    """Forget the designs kept across sweeps (tests that count designs start from none)."""
    with _FILLING:
        _KEPT_DESIGNS.clear()


def _plain(value) -> bool:
    """Whether ``value`` is made of plain values only (numbers, strings, booleans, None, and
    dicts, lists and tuples of them): nothing that could change after it was designed."""
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v) for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return all(_plain(v) for v in value)
    return isinstance(value, _PLAIN)


def _kept_design(spec: dict, nominal, Ts, frozen_key):
    """``design_from_spec(nominal.discretize(Ts), spec)``, kept across sweeps when it is a pure
    function of ``frozen_key`` (see ``_KEPT_DESIGNS``); called under ``_FILLING``."""
    frozen_spec = frozen_key is not None and frozen(nominal) and _plain(spec)
    if frozen_spec:  # the nominal model by its fields' bits (0.0 and -0.0 differ)
        fields = {f.name: getattr(nominal, f.name) for f in dataclasses.fields(nominal)}
        frozen_spec = _plain(fields)
        fields = _frozen(fields)
    family = get_family(spec.get("type", "dob")) if frozen_spec else None
    key = (frozen_key, fields, family, type(nominal)) if frozen_spec else None
    with _FILLING:
        design = _KEPT_DESIGNS.get(key) if frozen_spec else None
        if design is not None:
            _KEPT_DESIGNS.move_to_end(key)
            return design
        design = design_from_spec(nominal.discretize(Ts), spec)
        if frozen_spec:
            _KEPT_DESIGNS[key] = design
            while len(_KEPT_DESIGNS) > KEPT_DESIGNS_MAX:
                _KEPT_DESIGNS.popitem(last=False)
    return design


def _designed(spec: dict, nominal, Ts, cache):
    """The design of ``spec`` on ``nominal.discretize(Ts)``, shared through ``cache`` (and
    across sweeps, :func:`_kept_design`)."""
    key = ("design", _frozen({"spec": spec, "nominal": nominal, "Ts": Ts}))
    return _cached(cache, key, lambda: _kept_design(spec, nominal, Ts, key[-1]))


def _recomposed(composition: ReactionObserverDesign, params: dict, nominal, Ts, cache):
    """A reaction-torque observer composition designed again for one scenario: the DOb from
    its spec with the ``observer.*`` values, the RTOB from its own spec (the DOb's, varied, if
    it is the DOb itself) with the ``reaction_observer.*`` design values, both on the scenario's
    nominal model (so the RTOB stays on the DOb's), and the friction model with the
    ``reaction_observer.*`` friction values. An RTOB that is the DOb itself stays so unless a
    ``reaction_observer.*`` design argument varies: then it is a separate observer. A friction
    model that follows the plant (``friction = "plant"``) keeps following it: the scenario's
    loop reads it from the scenario's plant (and on the scenario's nominal ``b_n``)."""

    def sub(prefix):
        return {k[len(prefix) :]: v for k, v in params.items() if k.startswith(prefix)}

    reaction = sub("reaction_observer.")
    friction = {name: getattr(composition, name) for name in FRICTION_PARAMETERS}
    friction.update({k: v for k, v in reaction.items() if k in FRICTION_PARAMETERS})
    own = {k: v for k, v in reaction.items() if k not in FRICTION_PARAMETERS}
    # a part of no registered family is kept as it is (check_paths_apply refused its design
    # paths; on another nominal model the loop refuses it, in that row's error)
    dob, dob_spec = composition.dob, spec_of(composition.dob)
    if dob_spec is not None:
        dob_spec = _varied_spec(dob_spec, sub("observer."))
        dob = _designed(dob_spec, nominal, Ts, cache)
    rtob = composition.reaction
    if rtob is not None and spec_of(rtob) is not None:
        rtob = _designed(_varied_spec(spec_of(rtob), own), nominal, Ts, cache)
    elif rtob is None and own:
        rtob = _designed(_varied_spec(dob_spec, own), nominal, Ts, cache)
    return ReactionObserverDesign(dob, rtob, **friction, follows_plant=composition.follows_plant)


def scenario_loop(base: dict, params: dict, cache: dict | None = None) -> ServoLoop:
    """The validated loop of one scenario (raises Parameter*Error on bad values).

    ``cache`` (a dict) keeps the observer designs and the plants of a chunk or a sweep:
    scenarios that vary only the plant, the gains or the disturbance share one design, those
    with the same plant parameters one plant (both immutable).
    """
    groups: dict = {}  # "plant.J" -> groups["plant"]["J"], in one pass over the parameters
    for name, value in params.items():
        head, dot, tail = name.partition(".")
        if dot:
            groups.setdefault(head, {})[tail] = value

    def sub(prefix):
        return groups.get(prefix[:-1], {})

    loop: ServoLoop = base["loop"]
    changes = {}
    if sub("plant."):
        # one plant object per parameter set: a frozen one keeps its sub-step matrices
        varied = sub("plant.")
        key = ("plant", _frozen(varied)) if frozen(loop.plant) else None
        changes["plant"] = _cached(cache, key, lambda: replaced_plant(loop.plant, varied))
    if sub("nominal."):
        changes["nominal"] = loop.nominal.replace(**sub("nominal."))
    if sub("controller."):
        # any controller specification (a dataclass: PD, PID, ...), through its constructor
        changes["controller"] = dataclasses.replace(loop.controller, **sub("controller."))
    if "Ts" in params:
        changes["Ts"] = params["Ts"]
    spec = base["observer_spec"]
    composition = base["observer_object"]
    if not isinstance(composition, ReactionObserverDesign):
        composition = None
    nominal = changes.get("nominal", loop.nominal)
    Ts = changes.get("Ts", loop.Ts)
    if spec is not None:
        changes["observer"] = _designed(_varied_spec(spec, sub("observer.")), nominal, Ts, cache)
    elif composition is not None and (sub("observer.") or sub("reaction_observer.")
                                      or "nominal" in changes or "Ts" in changes):  # fmt: skip
        changes["observer"] = _recomposed(composition, params, nominal, Ts, cache)
    elif sub("observer."):
        raise ParameterValueError(
            "observer.* parameters need base['observer'] as a dict of design arguments (or a "
            "design of a known family)"
        )
    elif base["observer_object"] is not None:
        changes["observer"] = base["observer_object"]
    return loop.replace(**changes) if changes else loop


def _scenario_run(base: dict, params: dict, cache: dict | None):
    """``(loop, signals, x0, inputs)``: what :func:`run_scenario` prepares before the run;
    ``inputs`` the compiled loop's (:func:`~hpdob.simulation._simulate.metrics_run_inputs`)
    where the row needs no trace, else None (a full run). Raises Parameter*Error on bad
    values."""
    loop = scenario_loop(base, params, cache)
    S = run_substeps(loop.plant, loop.Ts, base["substeps"])
    n = sample_count(loop.Ts, base["duration"])
    x0 = np.array(base["x0"])  # checked once in _resolve_base
    signals = _cached(
        cache,
        ("signals", loop.Ts, n, S),
        lambda: sample_signals(base["reference"], base["disturbance"], Ts=loop.Ts, n=n, substeps=S),
    )
    scale = float(params.get("disturbance_scale", 1.0))
    signals = signals.scaled(scale)
    inputs = None
    if error_run_applies(loop, loop.Ts, S):
        tau_mid = _midpoints(signals, cache, ("midpoints", loop.Ts, n, S))
        inputs = metrics_run_inputs(loop, signals, x0, tau_mid=tau_mid)
    return loop, signals, x0, inputs


def run_scenario(base: dict, params: dict, cache: dict | None = None) -> dict:
    """Simulate one scenario and return its row (metrics, ``stable``, ``error``).

    ``base`` comes from :func:`_resolve_base`. ``cache`` keeps, besides the designs and
    plants of :func:`scenario_loop`, the sampled reference and disturbance per ``(Ts, n,
    substeps)``, shared by scenarios with the same time grid.
    """
    row = dict(params)
    try:
        prepared = getattr(_PREPARED, "runs", {}).pop(id(params), None)  # run_chunk's batch
        if prepared is None:
            prepared = _scenario_run(base, params, cache)
        loop, signals, x0, inputs = prepared
        if inputs is not None:  # the row needs no trace: none is recorded
            metrics, diverged, message = run_metrics(
                loop, signals, x0, windows=base["metric_windows"], inputs=inputs
            )
            result = None
        else:
            result = run_loop(loop, signals, x0)
    except (ParameterValueError, ParameterTypeError) as err:
        row.update(dict.fromkeys(METRIC_COLUMNS, math.nan), stable=False, error=str(err))
        return row
    if result is not None:
        metrics = result.metrics(**base["metric_windows"])
        metrics["max_abs_position_error"] = result.max_abs_position_error()
        diverged, message = result.diverged, result.message
    row.update(metrics)
    if not position_metrics_apply(loop.controller):  # r is tau_ref [N m], not an angle
        row.update(dict.fromkeys(METRIC_COLUMNS[1:], math.nan))
    if result is not None:  # against a wall: the same contact and force metrics as hpdob simulate's
        row.update(force_run_metrics(result, loop.controller))
    row["stable"] = not diverged
    row["error"] = message if diverged else ""
    return row


#: A time grid's sub-step midpoints are filled once per sweep up to this many values (32 MB);
#: beyond, each scenario's loop evaluates the disturbance's table itself (the same values).
MIDPOINTS_MAX = 1 << 22


def _midpoints(signals, cache, key):
    """The disturbance at the sub-step midpoints of ``signals`` (scaled), as the compiled loop
    evaluates its table, for the loop to read: filled once per time grid (``key``) through
    ``cache`` by :func:`~hpdob.simulation._kernel.midpoint_filler` (the loop's own statements,
    so bit for bit the loop's values) and multiplied by the scenario's factor as the loop
    multiplies it; None where the signals hold no table or the grid is too large (the loop
    then evaluates the table, or reads ``signals.tau_mid``)."""
    if signals.midpoint is None or cache is None:
        return None
    n, S = signals.t.size, signals.substeps
    if n * S > MIDPOINTS_MAX:
        return None

    def fill():
        from ._kernel import midpoint_filler

        form, coefficients = signals.midpoint
        values = np.empty(n * S)
        midpoint_filler(form)(n, S, signals.Ts, np.concatenate(([1.0], coefficients)), values)
        values.setflags(write=False)
        return values

    values = _cached(cache, key, fill)
    # the loop computes factor * tau_e per midpoint: the same product, elementwise
    return values if signals.factor == 1.0 else signals.factor * values


class SweepCancelled(Exception):
    """Raised inside a local chunk when the sweep was cancelled (e.g. by Ctrl-C)."""


def run_chunk(
    base: dict, chunk: list, stop: threading.Event | None = None, cache: dict | None = None
) -> list:
    """Rows of ``chunk``, a list of ``(index, params)``; runs anywhere (local or a worker).

    ``stop`` (local runs): checked before every scenario, so a cancelled sweep ends within one
    scenario instead of one chunk. ``cache`` (local runs): the sweep's, shared by all chunks
    and threads (designs, plants and sampled signals are immutable and a pure function of
    their key; :func:`_cached` makes each once); default a new one for this chunk.
    """
    cache = {} if cache is None else cache
    rows = []
    for start in range(0, len(chunk), PREPARED_RUNS):
        batch = chunk[start : start + PREPARED_RUNS]
        _prepare_runs(base, batch, stop, cache)
        try:
            for index, params in batch:
                if stop is not None and stop.is_set():
                    raise SweepCancelled
                if stop is None:  # on a dask worker: a test hook only (hpdob._interrupts)
                    checkpoint("sweep-scenario")
                rows.append({"scenario": index, **run_scenario(base, params, cache)})
        finally:
            _forget_prepared()
    return rows


#: Scenarios whose runs :func:`run_chunk` prepares one after another before running them
#: (:func:`_scenario_run`: the loop, the signals, the compiled loop's inputs): that Python (cache
#: keys, the designs looked up, the loop's checks, the records) then runs with the
#: interpreter's data in the processor's caches, not each after a loop's run has streamed its
#: megabyte through them. At most ~1-2 ms of holding the GIL at a time (another thread's
#: scenario may wait for it that long).
PREPARED_RUNS = 16
#: ... and at most this many sub-steps in all (``n * substeps`` per scenario): a scaled
#: disturbance's arrays are the scenario's own, so long runs are prepared one at a time.
PREPARED_SUBSTEPS = 1 << 21

#: Per thread: ``{id(params): run}`` of the batch being run (:func:`run_chunk`), taken by
#: :func:`run_scenario` instead of preparing the run again; empty between batches.
_PREPARED = threading.local()


def _prepare_runs(base: dict, batch: list, stop, cache: dict) -> None:
    """Prepare the runs of ``batch`` (``[(index, params)]``) for :func:`run_scenario` to take:
    the same :func:`_scenario_run` calls it would make, earlier. A scenario refused there is
    left out: its row gets the message from :func:`run_scenario`'s own call."""
    runs = {}
    held = 0
    for _, params in batch:
        if (stop is not None and stop.is_set()) or held >= PREPARED_SUBSTEPS:
            break  # the rest are prepared by run_scenario as they run
        try:
            run = _scenario_run(base, params, cache)
        except (ParameterValueError, ParameterTypeError):
            continue
        runs[id(params)] = run
        held += run[1].t.size * run[1].substeps
    _PREPARED.runs = runs


def _forget_prepared() -> None:
    """Drop this thread's prepared runs (:func:`run_chunk`, after each batch). A function, so
    that ``run_chunk`` names no thread-local object: pickled by value (cloudpickle, when a test
    or a user wraps it) it then needs none."""
    _PREPARED.runs = {}


def _chunks(indexed: list, workers: int) -> list:
    """Split ``[(index, params)]`` into chunks: ~8 per worker, 1-64 scenarios each."""
    size = max(1, min(64, math.ceil(len(indexed) / (8 * max(workers, 1)))))
    return [indexed[i : i + size] for i in range(0, len(indexed), size)]


def _check_progress(progress):
    if progress is None or isinstance(progress, (bool, np.bool_)) or callable(progress):
        return progress
    raise ParameterTypeError(
        f"progress must be None, True, False or a callable progress(done, total), got "
        f"{progress!r} of type {type(progress).__name__}"
    )


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


def _run_local(base, chunks, workers, update, rows) -> list:
    """Run the chunks on ``workers`` threads (the kernel releases the GIL), appending the
    finished rows to ``rows`` (the caller keeps them if an interrupt ends the run).

    Chunks are submitted lazily, at most two per worker in flight, so that an interrupt
    (KeyboardInterrupt in the main thread) or a failure leaves little to cancel: pending
    chunks are cancelled, running ones stop before their next scenario, and the call returns
    (re-raising) without waiting for the rest of the sweep.
    """
    stop = threading.Event()
    cache: dict = {}  # one for the whole sweep: each design, plant and time grid made once
    pending = iter(chunks)
    pool = ThreadPoolExecutor(max_workers=workers)
    running = set()
    try:
        for chunk in pending:
            running.add(pool.submit(run_chunk, base, chunk, stop, cache))
            if len(running) >= 2 * workers:
                break
        while running:
            done, running = wait(running, return_when=FIRST_COMPLETED)
            for future in done:
                chunk_rows = future.result()
                rows.extend(chunk_rows)  # one call: an interrupt cannot split a chunk
                update(len(chunk_rows))
                checkpoint("sweep-chunk")  # a test hook (hpdob._interrupts); no-op otherwise
                chunk = next(pending, None)
                if chunk is not None:
                    running.add(pool.submit(run_chunk, base, chunk, stop, cache))
    except BaseException:
        stop.set()
        for future in running:
            future.cancel()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return rows


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
    base: ServoLoop | Scenario | dict,
    *,
    grid=None,
    duration=None,
    reference=None,
    disturbance=None,
    substeps=None,
    x0=None,
    vary=None,
    n=None,
    seed=0,
    metric_windows=None,
    scheduler=None,
    progress=None,
    resume=None,
):
    """Run many closed-loop scenarios and return one row of parameters and metrics each.

    Parameters
    ----------
    base : ServoLoop, Scenario or dict
        What the scenarios share: a :class:`~hpdob.ServoLoop` (``sweep(loop, grid=...,
        duration=..., reference=...)``, the run settings given as :func:`hpdob.simulate`
        takes them), a
        :class:`~hpdob.simulation.Scenario` (a loop and its run settings, as
        :func:`~hpdob.simulation.load_scenario` reads them), or a dict of ``loop`` (a
        :class:`~hpdob.ServoLoop`) or the loop's keyword arguments (``plant``, ``nominal``,
        ``Ts``, ``controller``, ``observer``, ``sensor``, ``actuator``), and the keyword
        arguments of :func:`hpdob.simulate` (``duration``, ``reference``, ``disturbance``,
        ``substeps``, ``x0``). The observer may be a spec of any registered family
        (``{"type": "eso", "bandwidth": 150.0}``; the DOb's ``order``, ``bandwidth`` or
        ``poles``, ``measurement``, ...; see :func:`hpdob.observers.register_family`), built
        per scenario on ``nominal.discretize(Ts)`` and started at ``x0`` with ``tau0 = 0``; a
        design of a registered family is turned into its spec, any other observer is used as
        it is (and then ``nominal``, ``Ts`` and ``observer.*`` cannot vary).
    grid : dict, optional
        Dotted path -> list of values; the scenarios are their Cartesian product. Paths:
        ``plant.J``, ``plant.b``, ``plant.coulomb``, ``plant.coulomb_velocity`` (a
        :class:`ServoModel` plant), ``plant.link_mass``, ``plant.link_length`` (a
        :class:`MujocoServo` plant), ``nominal.J``,
        ``nominal.b``, ``observer.order``, ``observer.bandwidth``,
        ``observer.velocity_bandwidth``, ``observer.measurement`` (``"state"`` or
        ``"position"``; the other family's ``gain_direction`` or ``velocity_bandwidth`` is
        dropped; every sweepable design argument of every registered family),
        ``reaction_observer.*`` of a base whose observer is a
        :class:`~hpdob.observers.ReactionObserverDesign` (its friction model ``viscous``,
        ``coulomb``, ``coulomb_velocity``, ``velocity_filter``, and the RTOB's own design
        arguments; ``observer.*`` is then the DOb's; a friction model that follows the plant,
        ``friction = "plant"``, is read from each row's plant instead, and only its
        ``velocity_filter`` is a path), ``controller.kp``, ``controller.kd``,
        ``controller.ki``,
        ``controller.time_constant``, ``controller.tracking_time``, ``controller.bandwidth``,
        ``controller.observer_bandwidth``, ``controller.kf``, ``controller.kv``,
        ``controller.M_d``, ``controller.D_d``, ``controller.K_d``, ``controller.tau_ref``,
        ``controller.threshold`` (the parameters of the base's controller, through
        its constructor), ``Ts``, ``disturbance_scale`` (multiplies the disturbance).
    duration, reference, disturbance, substeps, x0 : optional
        The run settings of every scenario, as :func:`hpdob.simulate` takes them, with a
        :class:`~hpdob.ServoLoop` base only (``duration`` and ``reference`` then required); a
        dict or :class:`~hpdob.simulation.Scenario` base holds them itself.
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
    resume : pandas.DataFrame, optional
        Rows of an earlier run of the same sweep (same base, grid, vary, n and seed) that did
        not finish: the ``rows`` of a :class:`SweepIncomplete`, or the partial file ``hpdob
        sweep`` writes, read back. Only the scenarios missing from it run (``progress`` counts
        those), and the result holds every row, equal to a run from scratch: a row depends
        only on its scenario. Its columns and the parameters of every row are checked
        against this sweep first.

    Returns
    -------
    pandas.DataFrame
        One row per scenario, in scenario order: ``scenario``, the varied parameters, the
        three metrics of :meth:`SimulationResult.metrics`, ``max_abs_position_error`` [rad]
        (these position metrics NaN with a force controller, whose reference is tau_ref
        [N m]), for a plant against an environment the ``contact_*`` and ``force_*`` metrics
        ``hpdob simulate`` reports (docs/sweep.md), ``stable`` (False if the run diverged or
        its parameters were invalid: not a stability verdict, a bounded unstable force loop
        is ``True`` and its ``force_rms_force_error_steady`` tells it) and ``error`` (the
        divergence or validation message; empty when all went well).

    Raises
    ------
    SweepIncomplete
        When a dask cluster fails part-way (the scheduler lost, a task's workers killed
        repeatedly): it carries the finished rows (those of ``resume`` included) and the
        numbers of the missing scenarios; pass its ``rows`` as ``resume`` to complete them.
    SweepInterrupted
        When Ctrl-C (a ``KeyboardInterrupt``; under ``hpdob`` also SIGTERM and SIGHUP) ends
        the sweep, local or on dask: a ``KeyboardInterrupt`` itself, carrying the finished
        rows and the missing scenarios in the same way.
    ValueError, TypeError
        For a bad ``base``, an unknown path (the valid ones are listed), a bad distribution,
        a bad scheduler, or ``resume`` rows of another sweep. Bad *values* in a scenario (e.g.
        a negative inertia drawn from a normal distribution) do not raise: that row gets
        ``stable=False`` and the message.

    Examples
    --------
    >>> from hpdob import sweep
    >>> from hpdob import paper
    >>> base = {**paper.scenario(), "duration": 2.0, "observer": {"order": 1,
    ...         "bandwidth": 100.0}}
    >>> rows = sweep(base, grid={"observer.order": [0, 1]}, progress=False)
    >>> rows[["observer.order", "stable"]].to_dict("records")
    [{'observer.order': 0, 'stable': True}, {'observer.order': 1, 'stable': True}]

    The same sweep from a :class:`~hpdob.ServoLoop`:

    >>> from hpdob import ServoLoop
    >>> loop = ServoLoop(**{k: v for k, v in base.items() if k in ("plant", "nominal", "Ts",
    ...                     "controller", "observer")})
    >>> rows2 = sweep(loop, grid={"observer.order": [0, 1]}, duration=2.0,
    ...               reference=base["reference"], disturbance=base["disturbance"],
    ...               progress=False)
    >>> rows2.equals(rows)
    True
    """
    try:
        import pandas as pd
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "hpdob.sweep returns a pandas DataFrame: pip install 'hpdob[sweep]'"
        ) from err
    varies_Ts = "Ts" in (grid or {}) or "Ts" in (vary or {})
    run = {"duration": duration, "reference": reference, "disturbance": disturbance}
    run |= {"substeps": substeps, "x0": x0}
    resolved = _resolve_base(base, varies_Ts=varies_Ts, run=run)
    resolved["metric_windows"] = _metric_windows(metric_windows)
    scenarios = expand_scenarios(grid, vary, n, seed)
    workers, mode = _workers_and_mode(scheduler)
    progress = _check_progress(progress)
    # Validate the shared part once, loudly, before spending time on scenarios.
    loop = scenario_loop(resolved, {})
    check_paths_apply([*(grid or {}), *(vary or {})], resolved["loop"], resolved["observer_spec"])
    sample_signals(
        resolved["reference"], resolved["disturbance"], Ts=resolved["loop"].Ts, n=2, substeps=1
    )
    columns = [
        "scenario",
        *(list(grid or {}) + sorted(vary or {})),
        *METRIC_COLUMNS,
        *force_run_columns(loop),
        "stable",
        "error",
    ]
    finished = [] if resume is None else resumed_rows(resume, scenarios, columns)
    done = {row["scenario"] for row in finished}
    todo = [(i, params) for i, params in enumerate(scenarios) if i not in done]
    update, close = _progress_callback(progress, len(todo))

    def kept(new):
        """The finished rows so far, in scenario order, and the numbers of the others."""
        rows = sorted(finished + new, key=lambda row: row["scenario"])
        done = {row["scenario"] for row in rows}
        missing = [i for i in range(len(scenarios)) if i not in done]
        return pd.DataFrame(rows, columns=columns), missing

    rows: list = []  # filled chunk by chunk: what finished survives an interrupt
    try:
        if not todo:
            pass
        elif mode == "local":
            _run_local(resolved, _chunks(todo, workers), workers, update, rows)
        else:
            _run_dask(
                resolved, todo, scheduler, update, rows, run_chunk=run_chunk, chunks_of=_chunks
            )
    except _Incomplete as failure:  # keep what finished: the caller decides what to write
        raise SweepIncomplete(*kept(failure.rows), failure.__cause__) from None
    except KeyboardInterrupt as err:  # Ctrl-C (hpdob: SIGTERM, SIGHUP): keep what finished
        raise SweepInterrupted(*kept(rows), getattr(err, "signum", int(signal.SIGINT))) from err
    finally:
        close()
    return kept(rows)[0]
