"""Values a run derives from its frozen inputs, computed once (hpdob.simulation._derived), and
the result built from the run's own arrays without copies: the same numbers as recomputing
and copying, bit for bit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hpdob import PD, ServoLoop, ServoModel, SimulationResult, TwoMassServo, paper, simulate
from hpdob.simulation._derived import derived, frozen, plant_sampler, run_substeps
from hpdob.simulation._result import COLUMNS, OPTIONAL_COLUMNS


def canonical_loop(**changes):
    kw = paper.scenario()
    parts = {k: kw[k] for k in ("plant", "nominal", "Ts", "controller")}
    return ServoLoop(**{**parts, "observer": {"order": 1, "bandwidth": 100.0}, **changes})


def run(loop, duration=0.5):
    kw = paper.scenario()
    return simulate(loop, reference=kw["reference"], disturbance=kw["disturbance"],
                    duration=duration)  # fmt: skip


def test_derived_computes_once_per_owner_and_key():
    plant = ServoModel(2.8e-4)
    calls = []

    def make():
        calls.append(1)
        return object()

    first = derived(plant, "k", make)
    assert derived(plant, "k", make) is first and len(calls) == 1
    assert derived(plant, "other", make) is not first and len(calls) == 2
    # equal plants are different owners; the fields and equality do not see the cache
    twin = ServoModel(2.8e-4)
    assert twin == plant and derived(twin, "k", make) is not first
    assert dataclasses.replace(plant) == plant


def test_a_failing_make_stores_nothing():
    plant = ServoModel(2.8e-4)

    def fail():
        raise ValueError("no")

    with pytest.raises(ValueError, match="no"):
        derived(plant, "k", fail)
    assert derived(plant, "k", lambda: 3) == 3


def test_only_frozen_dataclasses_are_frozen():
    @dataclasses.dataclass
    class Mutable:
        x: float = 0.0

    assert frozen(ServoModel(2.8e-4)) and frozen(canonical_loop())
    assert not frozen(Mutable()) and not frozen(Mutable) and not frozen(3.0)


@pytest.mark.parametrize(
    "plant",
    [ServoModel(3.06e-4, 5e-5, coulomb=0.01, coulomb_velocity=0.01),
     TwoMassServo(J_motor=1.5e-4, J_load=1.5e-4, stiffness=10.0, damping=1e-3)],
)  # fmt: skip
def test_the_sampler_is_kept_and_equals_a_fresh_one(plant):
    kept = plant_sampler(plant, 1e-3, 8)
    assert plant_sampler(plant, 1e-3, 8) is kept
    assert plant_sampler(plant, 1e-3, 16) is not kept
    fresh = plant.sampler(1e-3, 8)
    for field in dataclasses.fields(fresh):
        a, b = getattr(kept, field.name), getattr(fresh, field.name)
        if isinstance(a, np.ndarray):
            assert a.tobytes() == b.tobytes()
        else:
            assert a == b


def test_default_substeps_are_kept_per_ts_and_a_given_number_checked():
    plant = ServoModel(3.06e-4, coulomb=0.01, coulomb_velocity=1e-3)
    assert run_substeps(plant, 1e-3, None) == plant.substeps(1e-3, None) == 66
    assert run_substeps(plant, 2e-3, None) == plant.substeps(2e-3, None)
    assert run_substeps(plant, 1e-3, 4) == 4
    with pytest.raises(ValueError, match="substeps"):
        run_substeps(plant, 1e-3, 0)


def test_a_second_run_of_a_loop_equals_the_first_and_a_fresh_loop_bit_for_bit():
    loop = canonical_loop()
    first, second = run(loop), run(loop)
    fresh = run(canonical_loop())
    for name in COLUMNS:
        a = getattr(first, name)
        assert a.tobytes() == getattr(second, name).tobytes() == getattr(fresh, name).tobytes()
    assert first.metrics() == second.metrics() == fresh.metrics()


def test_the_result_arrays_are_read_only_contiguous_and_do_not_share_between_runs():
    loop = canonical_loop(plant=TwoMassServo(J_motor=1.5e-4, J_load=1.5e-6 + 1.5e-4,
                                             stiffness=10.0, damping=1e-3))  # fmt: skip
    a, b = run(loop, 0.2), run(loop, 0.2)
    for name in (*COLUMNS, *OPTIONAL_COLUMNS):
        x = getattr(a, name)
        if x is None:
            continue
        assert not x.flags.writeable and x.flags.c_contiguous and x.dtype == np.float64
        assert len(x) == len(a) == 200
        assert not np.shares_memory(x, getattr(b, name))
        with pytest.raises(ValueError, match="read-only"):
            x[0] = 1.0


def test_a_result_of_arrays_equals_the_constructors():
    n = 5
    arrays = {name: np.arange(n, dtype=float) + i for i, name in enumerate(COLUMNS)}
    built = SimulationResult(**{k: v.copy() for k, v in arrays.items()}, Ts=0.1, label="x")
    fast = SimulationResult._of_arrays(**arrays, Ts=0.1, label="x")
    for f in dataclasses.fields(SimulationResult):
        x, y = getattr(built, f.name), getattr(fast, f.name)
        if isinstance(x, np.ndarray):
            assert x.tobytes() == y.tobytes() and not y.flags.writeable
        else:
            assert x == y
    assert fast.metrics(regulation=(0.1, 0.3)) == built.metrics(regulation=(0.1, 0.3))
    with pytest.raises(TypeError, match="missing"):
        SimulationResult._of_arrays(t=arrays["t"], Ts=0.1)
    with pytest.raises(TypeError, match="unknown"):
        SimulationResult._of_arrays(**arrays, Ts=0.1, bogus=1)


def test_a_pd_loop_without_observer_runs_twice_the_same():
    loop = canonical_loop(observer=None, controller=PD(50.0, 5.0))
    a, b = run(loop, 0.3), run(loop, 0.3)
    assert a.theta.tobytes() == b.theta.tobytes() and not a.tau_hat.any()


def test_an_owner_keeps_at_most_limit_entries():
    """Keys without a bound (a run's x0) cannot grow an owner's store past LIMIT."""
    from hpdob.simulation import _derived

    plant = ServoModel(2.8e-4)
    for i in range(3 * _derived.LIMIT):
        assert derived(plant, ("x0", i), lambda i=i: i) == i
    store = plant.__dict__["_hpdob_derived"]
    assert 0 < len(store) <= _derived.LIMIT
    assert derived(plant, ("x0", 3 * _derived.LIMIT - 1), lambda: -1) == 3 * _derived.LIMIT - 1


def test_runs_with_many_initial_states_keep_a_bounded_store_and_their_numbers():
    from hpdob.simulation import _derived

    loop = canonical_loop()
    kw = paper.scenario()
    runs = {}
    for i in range(_derived.LIMIT + 5):
        x0 = (1e-3 * i, 0.0)
        runs[i] = simulate(loop, reference=kw["reference"], disturbance=kw["disturbance"],
                           duration=0.05, x0=x0)  # fmt: skip
    assert len(loop.system.__dict__["_hpdob_derived"]) <= _derived.LIMIT
    again = simulate(canonical_loop(), reference=kw["reference"], disturbance=kw["disturbance"],
                     duration=0.05, x0=(0.0, 0.0))  # fmt: skip
    np.testing.assert_array_equal(again.tau_hat, runs[0].tau_hat)


def test_pickled_designs_leave_the_simulations_values_behind():
    import pickle

    loop = canonical_loop()
    first = run(loop, duration=0.05)
    for design in (loop.system, loop.controller_system):
        assert "_hpdob_derived" in design.__dict__
        assert "_hpdob_derived" not in pickle.loads(pickle.dumps(design)).__dict__
    copy = pickle.loads(pickle.dumps(loop.system))
    again = run(canonical_loop(observer=copy), duration=0.05)
    np.testing.assert_array_equal(again.tau_hat, first.tau_hat)
