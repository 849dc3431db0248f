"""What a sweep scenario computes around its loop (issue 25): made once where it can be, the
same values as before.

A design shared by several scenarios (a sweep's plants) keeps its kernel record and its
initial state per ``x0``; the sweep's cache keys take plain scalars and string-keyed dicts by
a short path that must give the keys of the general one.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
import pytest

from hpdob import ServoLoop, SimulationDivergedWarning, paper, simulate, sweep
from hpdob.simulation import _simulate
from hpdob.simulation import _sweep as sweep_module

METRICS = (
    "rms_estimation_error",
    "rms_position_error_regulation",
    "rms_position_error_tracking",
    "max_abs_position_error",
)


def _general_key(value):
    """The sweep's key of ``value`` as it was computed before the short path (the reference)."""
    if isinstance(value, dict):
        items = tuple(
            (k, _general_key(v)) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))
        )
        return None if any(v is None for _, v in items) else items
    if isinstance(value, (list, tuple, np.ndarray)):
        items = tuple(
            _general_key(v) for v in (value.tolist() if isinstance(value, np.ndarray) else value)
        )
        return None if any(v is None for v in items) else items
    if isinstance(value, float):
        return ("float", value.hex())
    try:
        hash(value)
    except TypeError:
        return None
    return (type(value).__name__, value)


VALUES = [
    0.0, -0.0, 1.5, math.inf, math.nan, np.float64(2.5), 3, True, False, None, "state", 1 + 2j,
    np.int64(4), [1.0, -0.0], (1, "a"), np.array([0.5, -0.0]),
    {"order": 1, "bandwidth": 100.0, "poles": None},
    {"b": {"x": -0.0, "y": [1, 2]}, "a": "z"},
    {1: 2.0, "k": 1.0},  # a key that is not a string: the general path
    {"spec": {"order": 2}, "nominal": paper.scenario()["nominal"], "Ts": 1e-3},
    {"unhashable": [set()]},
    [{"a": 1.0}],
]  # fmt: skip


@pytest.mark.parametrize("value", VALUES, ids=range(len(VALUES)))
def test_short_key_path_gives_the_general_keys(value):
    assert sweep_module._frozen(value) == _general_key(value)


def test_signed_zeros_and_float_types_keep_their_keys():
    key = sweep_module._frozen
    assert key(0.0) != key(-0.0)
    assert key({"b": 0.0}) != key({"b": -0.0})
    assert key(np.float64(1.0)) == key(1.0)  # numpy's float64 is a float: the same scenario
    assert key(1) != key(1.0) and key(True) != key(1)


def _rows_loop(base: dict) -> ServoLoop:
    return ServoLoop(**{k: base[k] for k in ("plant", "nominal", "Ts", "controller")},
                     observer=base["observer"])  # fmt: skip


def test_a_shared_design_keeps_its_record_and_initial_state(monkeypatch):
    sweep_module.clear_kept_designs()
    made = {"record": 0, "state": 0, "controller": 0}
    real_record, real_state = _simulate._observer_record, ServoLoop.initial_observer_state
    real_controller = _simulate._controller_record

    def controller(loop):
        made["controller"] += 1
        return real_controller(loop)

    def record(system):
        made["record"] += 1
        return real_record(system)

    def state(self, x0):
        made["state"] += 1
        return real_state(self, x0)

    monkeypatch.setattr(_simulate, "_observer_record", record)
    monkeypatch.setattr(ServoLoop, "initial_observer_state", state)
    monkeypatch.setattr(_simulate, "_controller_record", controller)
    base = {**paper.scenario(), "duration": 0.3, "observer": {"order": 1, "bandwidth": 123.0}}
    grid = {"plant.J": [2.5e-4, 3e-4, 3.5e-4, 4e-4]}
    rows = sweep(base, grid=grid, scheduler=1, progress=False)
    made["controller"] = 0  # the controller's design may hold records from earlier tests
    rows = sweep(base, grid=grid, scheduler=1, progress=False)
    assert made["record"] == 1 and made["state"] == 1  # one design for the four plants
    assert made["controller"] <= 1
    moved = sweep({**base, "x0": (0.01, 0.0)}, grid=grid, scheduler=1, progress=False)
    assert made["record"] == 1 and made["state"] == 2  # another x0: its own initial state
    assert made["controller"] <= 1
    nominal = sweep(base, grid={"nominal.J": [2.6e-4, 2.7e-4]}, scheduler=1, progress=False)
    assert made["controller"] >= 2 and nominal["stable"].all()  # records per nominal model
    for frame, x0 in ((rows, (0.0, 0.0)), (moved, (0.01, 0.0))):
        for J, (_, row) in zip(grid["plant.J"], frame.iterrows(), strict=True):
            loop = _rows_loop({**base, "plant": base["plant"].replace(J=J)})
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", SimulationDivergedWarning)
                result = simulate(loop, duration=0.3, reference=base["reference"],
                                  disturbance=base["disturbance"], x0=x0)  # fmt: skip
            expected = result.metrics()
            expected["max_abs_position_error"] = result.max_abs_position_error()
            for name in METRICS:
                assert np.float64(row[name]).tobytes() == np.float64(expected[name]).tobytes()
    assert not rows.equals(moved)  # the initial state is not shared across x0


def test_scratch_views_are_kept_per_length_and_fresh_beyond_the_limit():
    first = _simulate._scratch(1000)
    assert _simulate._scratch(1000) is first  # the same views: no new objects per scenario
    other = _simulate._scratch(500)
    assert len(other.u) == 500 and np.shares_memory(other.u, first.u)
    again = _simulate._scratch(1000)
    assert len(again.estimation_error) == 1000 and np.shares_memory(again.u, first.u)
    big = _simulate._scratch(_simulate.SCRATCH_SAMPLES + 1)  # not kept: the thread's stay
    assert not np.shares_memory(big.u, first.u)
    assert np.shares_memory(_simulate._scratch(1000).u, first.u)


def test_force_run_kind_is_the_controllers_class():
    from hpdob.controllers import PD, ForceControl, ImpedanceControl, PositionForceSwitch
    from hpdob.simulation import _force_run

    assert _force_run._kind(PD(50.0, 5.0)) is None
    for controller, kind in ((ForceControl, "force"), (ImpedanceControl, "impedance"),
                             (PositionForceSwitch, "position-force")):  # fmt: skip
        assert _force_run._kind_of_type(controller) == kind

        class Sub(controller):  # a subclass is of its base's kind, as isinstance says
            pass

        assert _force_run._kind_of_type(Sub) == kind


def test_a_batchs_runs_are_prepared_once_and_are_the_runs_made(monkeypatch):
    built = []
    real = sweep_module.scenario_loop

    def counted(base, params, cache=None):
        built.append(dict(params))
        return real(base, params, cache)

    monkeypatch.setattr(sweep_module, "scenario_loop", counted)
    base = {**paper.scenario(), "duration": 0.2, "observer": {"order": 1, "bandwidth": 100.0}}
    grid = {"observer.bandwidth": list(np.linspace(60.0, 240.0, 10)), "plant.J": [3e-4, 4e-4]}
    rows = sweep(base, grid=grid, scheduler=1, progress=False)
    assert len(built) == 1 + len(rows)  # the up-front check's loop, then one per scenario
    assert getattr(sweep_module._PREPARED, "runs", {}) == {}  # nothing left behind
    resolved = sweep_module._resolve_base(base)
    resolved["metric_windows"] = sweep_module._metric_windows(None)
    for (_, row), params in zip(rows.iterrows(), built[1:], strict=True):
        alone = sweep_module.run_scenario(resolved, params)  # no batch: builds its own loop
        for name in (*METRICS, "stable", "error"):
            assert np.asarray(row[name]).tobytes() == np.asarray(alone[name]).tobytes()


def test_a_refused_scenario_in_a_batch_keeps_its_message():
    base = {**paper.scenario(), "duration": 0.2, "observer": {"order": 1, "bandwidth": 100.0}}
    grid = {"plant.J": [3e-4, -1e-4, 4e-4], "observer.bandwidth": [80.0, -5.0]}
    rows = sweep(base, grid=grid, scheduler=1, progress=False)
    resolved = sweep_module._resolve_base(base)
    resolved["metric_windows"] = sweep_module._metric_windows(None)
    refused = 0
    for _, row in rows.iterrows():
        params = {path: row[path] for path in grid}
        alone = sweep_module.run_scenario(resolved, params)
        assert row["error"] == alone["error"] and row["stable"] == alone["stable"]
        refused += bool(row["error"])
    assert refused == 4  # a negative inertia or bandwidth: the row's message, not a failure


def test_run_chunk_pickles_by_value_when_wrapped(monkeypatch):
    """A wrapped ``run_chunk`` (the module's name then holds the wrapper) is pickled by value
    for a dask task: it must name nothing unpicklable, such as the prepared runs' store."""
    cloudpickle = pytest.importorskip("cloudpickle")
    real = sweep_module.run_chunk
    monkeypatch.setattr(sweep_module, "run_chunk", lambda *args: real(*args))
    again = cloudpickle.loads(cloudpickle.dumps(real))
    base = {**paper.scenario(), "duration": 0.05, "observer": {"order": 1, "bandwidth": 100.0}}
    resolved = sweep_module._resolve_base(base)
    resolved["metric_windows"] = sweep_module._metric_windows(None)
    rows = again(resolved, [(0, {"plant.J": 3e-4}), (1, {"plant.J": 4e-4})])
    assert [row["scenario"] for row in rows] == [0, 1] and all(row["stable"] for row in rows)


def test_a_batch_prepares_no_more_sub_steps_than_its_budget(monkeypatch):
    """Long scenarios are prepared one at a time (their scaled disturbances are their own);
    the rows are those of a sweep that prepares every run."""
    seen = []
    real = sweep_module._prepare_runs

    def spy(base, batch, stop, cache):
        real(base, batch, stop, cache)
        seen.append(len(sweep_module._PREPARED.runs))

    monkeypatch.setattr(sweep_module, "_prepare_runs", spy)
    base = {**paper.scenario(), "duration": 0.1, "observer": {"order": 1, "bandwidth": 100.0}}
    grid = {"disturbance_scale": list(np.linspace(0.5, 2.0, 32))}  # chunks of 4 on 1 worker
    everything = sweep(base, grid=grid, scheduler=1, progress=False)
    assert seen == [4] * 8
    samples = 100 * 8  # 0.1 s at 1 kHz, 8 sub-steps
    monkeypatch.setattr(sweep_module, "PREPARED_SUBSTEPS", 2 * samples)
    seen.clear()
    budgeted = sweep(base, grid=grid, scheduler=1, progress=False)
    assert seen == [2] * 8
    pd.testing.assert_frame_equal(budgeted, everything, check_exact=True)
