"""Tests of SimulationResult: metrics, CSV, pandas, plots."""

from __future__ import annotations

import json
import math

import matplotlib
import numpy as np
import pytest

from hpdob import SimulationResult, paper
from hpdob.simulation._result import COLUMNS, metrics_json

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def result():
    return paper.run("HPDOb-100", duration=5.0)


def synthetic(n=10, Ts=0.5):
    t = np.arange(n) * Ts
    arrays = {name: np.zeros(n) for name in COLUMNS}
    arrays["t"] = t
    return arrays, Ts


def test_metrics_by_hand():
    arrays, Ts = synthetic()
    arrays["theta"] = np.arange(10.0)  # r = 0: position error = theta
    arrays["tau_hat"] = np.full(10, 2.0)
    arrays["tau_dn"] = np.full(10, 1.0)
    res = SimulationResult(**arrays, Ts=Ts)
    m = res.metrics(regulation=(1.0, 2.0), tracking=(2.0, math.inf))  # t = 1.0, 1.5 | 2.0..4.5
    assert m["rms_estimation_error"] == 1.0
    assert m["rms_position_error_regulation"] == pytest.approx(math.sqrt((4 + 9) / 2))
    assert m["rms_position_error_tracking"] == pytest.approx(
        math.sqrt(np.mean(np.arange(4, 10) ** 2))
    )
    assert math.isnan(res.metrics(regulation=(100, 200))["rms_position_error_regulation"])
    assert res.max_abs_position_error() == 9.0


def test_metric_window_validation():
    arrays, Ts = synthetic()
    res = SimulationResult(**arrays, Ts=Ts)
    with pytest.raises(ValueError, match=r"^regulation must have start < stop"):
        res.metrics(regulation=(2.0, 1.0))
    with pytest.raises(ValueError, match=r"^tracking must be a \(start, stop\) pair"):
        res.metrics(tracking=3.0)


def test_arrays_are_readonly_and_checked(result):
    with pytest.raises(ValueError, match="read-only"):
        result.theta[0] = 1.0
    arrays, Ts = synthetic()
    arrays["u"] = np.zeros(3)
    with pytest.raises(ValueError, match=r"^u must have shape \(10,\) like t"):
        SimulationResult(**arrays, Ts=Ts)


def test_csv_round_trip(result, tmp_path):
    path = result.to_csv(tmp_path / "run.csv")
    back = SimulationResult.from_csv(path, label="back")
    for name in COLUMNS:
        np.testing.assert_array_equal(getattr(back, name), getattr(result, name), err_msg=name)
    assert back.Ts == pytest.approx(result.Ts, rel=1e-12)
    header = path.read_text().splitlines()[0]
    assert header == ",".join(COLUMNS)


def test_from_csv_rejects_other_files(tmp_path):
    path = tmp_path / "other.csv"
    path.write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="does not look like an hpdob trace file"):
        SimulationResult.from_csv(path)


def test_to_pandas(result):
    pytest.importorskip("pandas")
    frame = result.to_pandas()
    assert list(frame.columns) == list(COLUMNS)
    assert len(frame) == len(result)
    np.testing.assert_array_equal(frame["tau_hat"].to_numpy(), result.tau_hat)


def test_plot(result):
    import matplotlib.pyplot as plt

    fig = result.plot()
    try:
        axes = fig.get_axes()
        assert len(axes) == 3
        assert all(ax.get_ylabel() for ax in axes)
        assert "[rad]" in axes[0].get_ylabel()
        assert axes[-1].get_xlabel() == "time [s]"
    finally:
        plt.close(fig)


def test_metrics_json_is_strict():
    text = metrics_json({"run": {"a": 1.0, "b": math.nan}})
    assert json.loads(text) == {"run": {"a": 1.0, "b": None}}


@pytest.mark.parametrize(
    ("bounds", "error", "pattern"),
    [
        (["1", "4"], TypeError, r"^tracking must be a \(start, stop\) pair of times \[s\], got"),
        ([True, 4.0], TypeError, r"^tracking must be a \(start, stop\) pair .*bool entry"),
        ("14", TypeError, r"^tracking must be a \(start, stop\) pair .*of type str"),
        (
            (1.0, 2.0, 3.0),
            ValueError,
            r"^tracking must be a \(start, stop\) pair .*\(1.0, 2.0, 3.0\)",
        ),
        ((4.0, 1.0), ValueError, r"^tracking must have start < stop \[s\], got \(4.0, 1.0\)"),
        ((math.nan, 1.0), ValueError, r"^tracking must have start < stop"),
    ],
)
def test_bad_metric_windows(bounds, error, pattern):
    from hpdob.simulation._result import metric_window

    with pytest.raises(error, match=pattern):
        metric_window(bounds, "tracking")
    assert metric_window((1, math.inf), "tracking") == (1.0, math.inf)


def test_rms_of_huge_values_does_not_overflow():
    from hpdob.simulation._result import _rms

    # sqrt(mean(x^2)) of [3e200, 4e200]: x^2 overflows, the answer 3.5355e200 does not
    assert _rms(np.array([3e200, 4e200])) == pytest.approx(math.sqrt(12.5) * 1e200, rel=1e-15)
    assert _rms(np.array([3.0, 4.0])) == pytest.approx(math.sqrt(12.5), rel=1e-15)
    assert _rms(np.zeros(3)) == 0.0
    assert math.isnan(_rms(np.array([])))


def test_rms_is_the_scaled_formula_bit_for_bit():
    # _rms writes the square in place; the value is that of the formula written out
    from hpdob.simulation._result import _rms

    rng = np.random.default_rng(7)
    for n in (1, 2, 7, 8, 9, 1000, 12345):
        for exponent in (-300, -3, 0, 3, 300):
            v = rng.standard_normal(n + 1)[1:] * 10.0**exponent  # an offset view too
            scale = float(np.max(np.abs(v)))
            assert _rms(v) == scale * float(np.sqrt(np.mean((v / scale) ** 2)))
    assert _rms(np.zeros(3)) == 0.0 and math.isnan(_rms(np.zeros(0)))
    assert _rms(np.array([1.0, math.inf])) == math.inf


@pytest.mark.parametrize(
    "bounds", [(1.2, 4.0), (4.0, math.inf), [1.0, 2.0], np.array([0.5, 1.5]), (1, 2)]
)
def test_a_window_of_floats_reads_as_the_generic_check_would(bounds):
    from hpdob.simulation._result import metric_window

    lo, hi = metric_window(bounds, "w")
    assert (lo, hi) == (float(bounds[0]), float(bounds[1]))
    assert type(lo) is float and type(hi) is float


@pytest.mark.parametrize(
    ("bounds", "pattern"),
    [((2.0, 1.0), "start < stop"), ((math.nan, 1.0), "start < stop"), ((1.0,), "pair"),
     ("ab", "pair"), ((True, 2.0), "bool")],
)  # fmt: skip
def test_a_bad_window_is_refused_whatever_its_type(bounds, pattern):
    from hpdob.simulation._result import metric_window

    with pytest.raises((ValueError, TypeError), match=pattern):
        metric_window(bounds, "w")


def _force_run(duration=1.5):
    from hpdob import Environment, ServoLoop, ServoModel, design_observer, simulate
    from hpdob.controllers import ForceControl
    from hpdob.observers import reaction_torque_observer

    nominal = ServoModel(2.8e-4)
    dob = design_observer(nominal.discretize(1e-3), order=1, bandwidth=100.0)
    loop = ServoLoop(plant=ServoModel(3.06e-4, environment=Environment(10.0)), nominal=nominal,
                     Ts=1e-3, observer=reaction_torque_observer(dob),
                     controller=ForceControl(1000.0, kv=40.0))  # fmt: skip
    step = lambda t: (np.where(t >= 0.1, 0.05, 0.0), 0 * t, 0 * t)  # noqa: E731
    return simulate(loop, reference=step, duration=duration, x0=(-0.01, 0.0))


def test_force_metrics_over_a_window():
    """The windowed RMS is the RMS over the samples start <= t < stop, recomputed here from the
    traces; "steady" starts 0.5 s after the first sample in contact. Without the approach, the
    impact and the step the force error is a small fraction of the whole run's."""
    from hpdob.simulation._result import FORCE_SETTLING

    run = _force_run()
    ref = run.r
    whole = run.force_metrics(ref)
    assert "window_start" not in whole
    assert whole["rms_force_error"] == pytest.approx(
        np.sqrt(np.mean((run.tau_contact - ref) ** 2)), rel=1e-12)  # fmt: skip
    w = (run.t >= 0.7) & (run.t < 1.2)
    part = run.force_metrics(ref, window=(0.7, 1.2))
    assert part["window_start"] == 0.7
    assert part["rms_force_error"] == pytest.approx(
        np.sqrt(np.mean((run.tau_contact[w] - ref[w]) ** 2)), rel=1e-12)  # fmt: skip
    assert part["rms_reaction_error"] == pytest.approx(
        np.sqrt(np.mean((run.tau_reac[w] - run.tau_contact[w]) ** 2)), rel=1e-12)  # fmt: skip
    first = run.t[np.argmax(run.in_contact > 0.0)]
    assert 0.1 < first < 0.3  # the approach from 0.01 rad before the wall
    steady = run.force_metrics(ref, window="steady")
    assert FORCE_SETTLING == 0.5
    assert steady["window_start"] == pytest.approx(first + 0.5, abs=1e-12)
    s = run.t >= first + 0.5
    assert steady["rms_force_error"] == pytest.approx(
        np.sqrt(np.mean((run.tau_contact[s] - ref[s]) ** 2)), rel=1e-12)  # fmt: skip
    assert steady["rms_force_error"] < 0.05 * whole["rms_force_error"]
    # only the estimate, without a reference
    assert set(run.force_metrics(window="steady")) == {"rms_reaction_error", "window_start"}


def test_force_metrics_window_refusals_and_empty_windows():
    run = _force_run(duration=0.3)
    for bad in ("last", (0.5, 0.2), (0.1,), (math.nan, 1.0)):
        with pytest.raises(ValueError, match="window"):
            run.force_metrics(run.r, window=bad)
    empty = run.force_metrics(run.r, window=(5.0, 6.0))  # after the run: no sample
    assert math.isnan(empty["rms_force_error"]) and math.isnan(empty["rms_reaction_error"])
    assert math.isnan(run.force_metrics(run.r, window="steady")["rms_force_error"])  # < 0.5 s


def test_force_metrics_steady_window_without_contact():
    import dataclasses

    run = _force_run(duration=0.3)
    never = dataclasses.replace(run, in_contact=np.zeros_like(run.in_contact))
    m = never.force_metrics(run.r, window="steady")
    assert math.isnan(m["window_start"]) and math.isnan(m["rms_force_error"])
