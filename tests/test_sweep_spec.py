"""Tests of sweep scenario expansion: paths, grids, distributions, seeds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob.simulation._sweep_spec import expand_scenarios, sweep_paths


def test_grid_is_a_cartesian_product_in_key_order():
    scenarios = expand_scenarios({"plant.J": [1e-4, 2e-4], "observer.order": [0, 1, 2]})
    assert len(scenarios) == 6
    assert scenarios[0] == {"plant.J": 1e-4, "observer.order": 0}
    assert scenarios[1] == {"plant.J": 1e-4, "observer.order": 1}
    assert scenarios[-1] == {"plant.J": 2e-4, "observer.order": 2}
    assert type(scenarios[0]["observer.order"]) is int


def test_no_grid_no_vary_is_one_scenario():
    assert expand_scenarios() == [{}]


def test_draws_follow_the_distributions_and_the_seed():
    vary = {
        "plant.J": ("uniform", 1.0, 2.0),
        "controller.kp": ("normal", 50.0, 5.0),
        "observer.bandwidth": ("loguniform", 10.0, 1000.0),
    }
    a = expand_scenarios(vary=vary, n=2000, seed=3)
    b = expand_scenarios(vary=dict(reversed(vary.items())), n=2000, seed=3)
    assert a == b  # independent of dict order
    assert a != expand_scenarios(vary=vary, n=2000, seed=4)
    J = np.array([s["plant.J"] for s in a])
    kp = np.array([s["controller.kp"] for s in a])
    bw = np.array([s["observer.bandwidth"] for s in a])
    assert J.min() >= 1.0
    assert J.max() < 2.0
    assert J.mean() == pytest.approx(1.5, abs=0.03)
    assert kp.mean() == pytest.approx(50.0, abs=0.5)
    assert kp.std() == pytest.approx(5.0, rel=0.08)
    assert np.log10(bw).mean() == pytest.approx(2.0, abs=0.05)  # uniform in log
    # reference draws: sorted paths, one rng (controller.kp, observer.bandwidth, plant.J)
    rng = np.random.default_rng(3)
    expected_kp = rng.normal(50.0, 5.0, 2000)
    np.testing.assert_array_equal(kp, expected_kp)


def test_grid_times_draws():
    scenarios = expand_scenarios(
        {"observer.order": [0, 1]}, {"plant.J": ("uniform", 1, 2)}, n=3, seed=0
    )
    assert len(scenarios) == 6
    assert [s["plant.J"] for s in scenarios[:3]] == [s["plant.J"] for s in scenarios[3:]]


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        (
            {"grid": {"plant.inertia": [1.0]}},
            r"grid path 'plant.inertia' is not a sweep parameter; "
            r"valid paths: plant.J, plant.b",
        ),
        ({"vary": {"J": ("uniform", 1, 2)}, "n": 2}, r"vary path 'J' is not a sweep parameter"),
        ({"grid": {"plant.J": []}}, r"grid\['plant.J'\] must be a non-empty list"),
        (
            {"vary": {"plant.J": ("gamma", 1, 2)}, "n": 2},
            r"vary\['plant.J'\] must be one of \('uniform', low, high\); \('normal', mean, "
            r"standard deviation\); \('loguniform', low, high \(0 < low\)\); "
            r"got \('gamma', 1, 2\)$",
        ),
        ({"vary": {"plant.J": ("uniform", 2, 1)}, "n": 2}, r"uniform needs low < high"),
        ({"vary": {"plant.J": ("normal", 2, 0)}, "n": 2}, r"positive standard deviation"),
        ({"vary": {"plant.J": ("loguniform", 0, 1)}, "n": 2}, r"0 < low < high"),
        ({"vary": {"plant.J": ("uniform", 1, 2)}}, r"n \(the number of random draws\) is required"),
        ({"grid": {"plant.J": [1]}, "n": 3}, r"n=3 needs vary"),
        ({"vary": {"plant.J": ("uniform", 1, 2)}, "n": 0}, r"^n must be a positive integer"),
        (
            {"grid": {"plant.J": [1]}, "vary": {"plant.J": ("uniform", 1, 2)}, "n": 1},
            r"in both grid and vary",
        ),
        ({"vary": {"observer.order": ("uniform", 0, 2)}, "n": 1}, r"put it in grid"),
        ({"grid": {"observer.order": [-1]}}, r"must be a non-negative integer order, got -1"),
        ({"grid": {"plant.J": [math.nan]}}, r"must be a finite number, got nan"),
        ({"seed": -1}, r"^seed must be a non-negative integer"),
    ],
)
def test_bad_specs(kwargs, pattern):
    with pytest.raises(ValueError, match=pattern):
        expand_scenarios(**kwargs)


def test_bad_types():
    with pytest.raises(TypeError, match="grid must be a dict"):
        expand_scenarios(grid=[("plant.J", [1])])
    with pytest.raises(TypeError, match=r"grid\['plant.J'\] must be a list"):
        expand_scenarios(grid={"plant.J": 1.0})


def test_paths_are_documented():
    assert "disturbance_scale" in sweep_paths()
    assert "Ts" in sweep_paths()
