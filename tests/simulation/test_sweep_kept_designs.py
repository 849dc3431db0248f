"""The observer designs a sweep keeps for the process's later sweeps (issue 25, second round).

A sweep run again takes its designs from ``_sweep._KEPT_DESIGNS`` instead of designing them
anew; the rows are those of fresh designs bit for bit, and only designs that are pure
functions of their key are kept (a frozen nominal model, a spec of plain values, the family's
record), so nothing a caller can change afterwards is served stale.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import hpdob.simulation._sweep as sweep_module
from hpdob import paper, sweep
from hpdob.observers import get_family, register_family

GRID = {"observer.order": [0, 1], "observer.bandwidth": [60.0, 150.0], "plant.J": [2.5e-4, 4e-4]}


def base(duration=0.3, **observer):
    return {
        **paper.scenario(),
        "duration": duration,
        "observer": {"order": 1, "bandwidth": 100.0, **observer},
    }


@pytest.fixture
def counted(monkeypatch):
    """The specs ``design_from_spec`` is called with (from an empty store of kept designs)."""
    calls = []
    real = sweep_module.design_from_spec

    def design(model, spec):
        calls.append(spec)
        return real(model, spec)

    monkeypatch.setattr(sweep_module, "design_from_spec", design)
    sweep_module.clear_kept_designs()
    yield calls
    sweep_module.clear_kept_designs()


def test_a_sweep_run_again_designs_nothing_and_its_rows_are_bit_for_bit(counted):
    first = sweep(base(), grid=GRID, progress=False)
    assert len(counted) == 1 + 4  # the base's up-front check, then one per (order, bandwidth)
    again = sweep(base(), grid=GRID, progress=False, scheduler=2)
    assert len(counted) == 5  # all kept
    sweep_module.clear_kept_designs()
    fresh = sweep(base(), grid=GRID, progress=False, scheduler=1)
    assert len(counted) == 10
    for rows in (again, fresh):
        for column in sweep_module.METRIC_COLUMNS:
            a, b = first[column].to_numpy(), rows[column].to_numpy()
            assert np.array_equal(a.view(np.uint64), b.view(np.uint64)), column
        assert rows.drop(columns=list(sweep_module.METRIC_COLUMNS)).equals(
            first.drop(columns=list(sweep_module.METRIC_COLUMNS))
        )


def test_the_kept_design_is_the_one_a_fresh_design_gives():
    nominal, Ts = paper.scenario()["nominal"], paper.scenario()["Ts"]
    spec = {"type": "dob", "order": 1, "bandwidth": 123.0}
    sweep_module.clear_kept_designs()
    kept = sweep_module._designed(spec, nominal, Ts, {})
    assert sweep_module._designed(dict(spec), nominal, Ts, {}) is kept  # a new sweep's cache
    direct = sweep_module.design_from_spec(nominal.discretize(Ts), spec)
    for name in ("k", "gains", "error_matrix", "state_input", "control_input", "poles"):
        assert np.array_equal(getattr(kept, name), getattr(direct, name)), name
    assert kept.system.program == direct.system.program


def test_signed_zeros_and_other_nominal_values_are_other_designs(counted):
    nominal, Ts = paper.scenario()["nominal"], paper.scenario()["Ts"]
    spec = {"type": "dob", "order": 0, "bandwidth": 80.0}
    for b in (0.0, -0.0, 0.0):
        sweep_module._designed(spec, nominal.replace(b=b), Ts, {})
    assert len(counted) == 2  # 0.0 and -0.0 apart; 0.0 again kept
    sweep_module._designed(spec, nominal.replace(J=nominal.J * 1.1), Ts, {})
    sweep_module._designed(spec, nominal, Ts * 2, {})
    assert len(counted) == 4


def test_only_pure_designs_are_kept(counted):
    nominal, Ts = paper.scenario()["nominal"], paper.scenario()["Ts"]
    # poles as an array: a value the caller could change after the sweep
    spec = {"type": "dob", "order": 1, "poles": np.array([0.9, 0.8])}
    for _ in range(2):
        sweep_module._designed(spec, nominal, Ts, {})
    assert len(counted) == 2

    @dataclasses.dataclass  # a nominal model that is not frozen
    class Mutable:
        J: float
        b: float

        def discretize(self, Ts):
            return nominal.replace(J=self.J, b=self.b).discretize(Ts)

    plain = {"type": "dob", "order": 1, "bandwidth": 100.0}
    for _ in range(2):
        sweep_module._designed(plain, Mutable(nominal.J, nominal.b), Ts, {})
    assert len(counted) == 4
    assert not sweep_module._KEPT_DESIGNS


def test_a_family_registered_again_designs_anew(counted):
    nominal, Ts = paper.scenario()["nominal"], paper.scenario()["Ts"]
    spec = {"type": "dob", "order": 1, "bandwidth": 100.0}
    sweep_module._designed(spec, nominal, Ts, {})
    dob = get_family("dob")
    register_family(dataclasses.replace(dob), replace=True)  # another record of the same name
    try:
        sweep_module._designed(spec, nominal, Ts, {})
        assert len(counted) == 2
    finally:
        register_family(dob, replace=True)
    sweep_module._designed(spec, nominal, Ts, {})
    assert len(counted) == 2  # the first record's design again


def test_a_bad_value_is_still_a_row_error_on_a_second_sweep(counted):
    grid = {"observer.bandwidth": [100.0, -5.0]}
    for _ in range(2):
        rows = sweep(base(), grid=grid, progress=False)
        assert rows["stable"].tolist() == [True, False]
        assert rows["error"][1].startswith("bandwidth must be")


def test_the_store_is_bounded(counted, monkeypatch):
    monkeypatch.setattr(sweep_module, "KEPT_DESIGNS_MAX", 3)
    nominal, Ts = paper.scenario()["nominal"], paper.scenario()["Ts"]
    for bandwidth in (50.0, 60.0, 70.0, 80.0, 50.0):
        sweep_module._designed({"type": "dob", "order": 0, "bandwidth": bandwidth}, nominal, Ts, {})
    assert len(sweep_module._KEPT_DESIGNS) == 3
    assert len(counted) == 5  # 50 was the oldest, dropped, designed again
