"""Reading logged runs: read_log (CSV, Parquet, MATLAB .mat), Log and their validation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.io

from hpdob import Log, ParameterTypeError, ParameterValueError, read_log
from hpdob.identification import EMPS_FILE, emps

N = 200
TS = 1e-3


def signals():
    t = np.arange(N) * TS
    return t, 0.1 * np.sin(2 * np.pi * t), np.cos(2 * np.pi * t)


def write_csv(path, columns: dict, delimiter=","):
    names = list(columns)
    lines = [delimiter.join(names)]
    for row in zip(*columns.values(), strict=True):
        lines.append(delimiter.join(repr(float(v)) if not isinstance(v, str) else v for v in row))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_parquet(path, columns: dict):
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    pq.write_table(pa.table(columns), path)
    return path


def write_mat(path, columns: dict):
    scipy.io.savemat(path, {k: np.asarray(v).reshape(-1, 1) for k, v in columns.items()})
    return path


WRITERS = {"csv": write_csv, "parquet": write_parquet, "mat": write_mat}


@pytest.mark.parametrize("kind", WRITERS)
def test_each_format_reads_back_the_columns(tmp_path, kind):
    t, q, v = signals()
    path = WRITERS[kind](tmp_path / f"log.{kind}", {"time": t, "pos": q, "cmd": v, "ref": q})
    log = read_log(path, time="time", position="pos", input="cmd", input_gain=2.5, reference="ref")
    np.testing.assert_array_equal(log.t, t)
    np.testing.assert_array_equal(log.theta, q)
    np.testing.assert_array_equal(log.u, 2.5 * v)
    np.testing.assert_array_equal(log.reference, q)
    assert log.Ts == pytest.approx(TS, rel=1e-12)
    assert log.source == f"log.{kind}" and log.input_gain == 2.5
    assert dict(log.names) == {
        "time": "time",
        "position": "pos",
        "input": "cmd",
        "reference": "ref",
    }


def test_csv_with_semicolons_and_no_time_column(tmp_path):
    _, q, v = signals()
    path = write_csv(tmp_path / "log.csv", {"q": q, "u": v}, delimiter=";")
    log = read_log(path, position="q", input="u", Ts=2e-3, axis="linear")
    np.testing.assert_array_equal(log.t, np.arange(N) * 2e-3)
    assert log.Ts == pytest.approx(2e-3) and log.units["position"] == "m"


def test_shipped_emps_log_is_the_mat_file_scaled_by_gtau():
    log = emps()
    raw = scipy.io.loadmat(EMPS_FILE)
    np.testing.assert_array_equal(log.theta, raw["qm"].ravel())
    np.testing.assert_array_equal(log.u, raw["gtau"].item() * raw["vir"].ravel())
    np.testing.assert_array_equal(log.reference, raw["qg"].ravel())
    # the description's data set: 24 841 samples at 1 kHz, gtau = 35.15 N/V
    assert len(log) == 24841 and log.Ts == pytest.approx(1e-3, rel=1e-9)
    assert log.input_gain == pytest.approx(35.15, abs=0.01) and log.axis == "linear"


@pytest.mark.parametrize("kind", WRITERS)
def test_missing_column_lists_the_available_ones(tmp_path, kind):
    t, q, v = signals()
    path = WRITERS[kind](tmp_path / f"log.{kind}", {"t": t, "qm": q, "vir": v})
    with pytest.raises(ParameterValueError, match=r"position column 'qx' is not in log\.") as err:
        read_log(path, time="t", position="qx", input="vir")
    assert "available: qm, t, vir" in str(err.value)


def test_columns_of_different_lengths_are_refused(tmp_path):
    t, q, v = signals()
    path = tmp_path / "log.mat"
    scipy.io.savemat(path, {"t": t.reshape(-1, 1), "qm": q[:-3].reshape(-1, 1), "vir": v})
    with pytest.raises(ParameterValueError, match="same number of samples") as err:
        read_log(path, time="t", position="qm", input="vir")
    assert "position 'qm' has 197" in str(err.value) and "time 't' has 200" in str(err.value)


def test_non_numeric_csv_cell_names_column_and_sample(tmp_path):
    t, q, v = signals()
    cells = [repr(float(x)) for x in q]
    cells[17] = "oops"
    path = write_csv(tmp_path / "log.csv", {"t": t, "q": cells, "u": v})
    with pytest.raises(ParameterValueError, match=r"position column 'q'.*not numeric: sample 17"):
        read_log(path, time="t", position="q", input="u")


@pytest.mark.parametrize("kind", WRITERS)
def test_non_finite_sample_names_column_and_first_index(tmp_path, kind):
    t, q, v = signals()
    v = v.copy()
    v[[42, 60]] = np.nan
    path = WRITERS[kind](tmp_path / f"log.{kind}", {"t": t, "q": q, "u": v})
    with pytest.raises(
        ParameterValueError, match=r"input column 'u' has a non-finite sample nan at index 42"
    ):
        read_log(path, time="t", position="q", input="u")


def test_non_monotonic_time_is_refused(tmp_path):
    t, q, v = signals()
    t = t.copy()
    t[[30, 31]] = t[[31, 30]]
    path = write_csv(tmp_path / "log.csv", {"t": t, "q": q, "u": v})
    with pytest.raises(
        ParameterValueError, match=r"time column 't' must increase strictly.*\[31\]"
    ):
        read_log(path, time="t", position="q", input="u")


def test_non_uniform_time_is_refused(tmp_path):
    t, q, v = signals()
    t = t.copy()
    t[100:] += 0.5e-3  # one step of 1.5 ms
    path = write_csv(tmp_path / "log.csv", {"t": t, "q": q, "u": v})
    with pytest.raises(ParameterValueError, match=r"uniformly sampled.*t'\[100\].*by 50 %"):
        read_log(path, time="t", position="q", input="u")
    # a jitter below the tolerance (here 1e-5 relative, like EMPS's clock) is accepted
    jitter = np.arange(N) * TS + 1e-8 * np.random.default_rng(0).standard_normal(N)
    write_csv(tmp_path / "ok.csv", {"t": jitter, "q": q, "u": v})
    assert read_log(tmp_path / "ok.csv", time="t", position="q", input="u").Ts == pytest.approx(TS)


def test_too_short_log_is_refused(tmp_path):
    t, q, v = signals()
    path = write_csv(tmp_path / "log.csv", {"t": t[:5], "q": q[:5], "u": v[:5]})
    with pytest.raises(ParameterValueError, match="at least 10 samples, got 5"):
        read_log(path, time="t", position="q", input="u")


def test_time_or_Ts_exactly_one(tmp_path):
    t, q, v = signals()
    path = write_csv(tmp_path / "log.csv", {"t": t, "q": q, "u": v})
    with pytest.raises(ParameterValueError, match=r"time='column'.*Ts="):
        read_log(path, position="q", input="u")
    with pytest.raises(ParameterValueError, match=r"time='column'.*Ts="):
        read_log(path, time="t", position="q", input="u", Ts=1e-3)
    with pytest.raises(ParameterValueError, match="Ts must be a positive"):
        read_log(path, position="q", input="u", Ts=-1.0)


def test_unknown_format_and_missing_file(tmp_path):
    with pytest.raises(ParameterValueError, match=r"cannot tell the format of log\.xlsx"):
        read_log(tmp_path / "log.xlsx", time="t", position="q", input="u")
    with pytest.raises(ParameterValueError, match="does not exist"):
        read_log(tmp_path / "none.csv", time="t", position="q", input="u")


def test_input_gain_by_variable_name(tmp_path):
    t, q, v = signals()
    path = tmp_path / "log.mat"
    scipy.io.savemat(path, {"t": t, "q": q, "u": v, "g": 3.0, "bad": np.arange(3.0)})
    log = read_log(path, time="t", position="q", input="u", input_gain="g")
    np.testing.assert_allclose(log.u, 3.0 * v)
    with pytest.raises(ParameterValueError, match=r"input_gain 'bad' .* single number"):
        read_log(path, time="t", position="q", input="u", input_gain="bad")
    with pytest.raises(ParameterTypeError, match="input_gain must be a number or the name"):
        read_log(path, time="t", position="q", input="u", input_gain=[1.0])
    with pytest.raises(ParameterValueError, match="input_gain must be a finite non-zero"):
        read_log(path, time="t", position="q", input="u", input_gain=0.0)


def test_non_numeric_columns_are_refused(tmp_path):
    t, q, _ = signals()
    path = tmp_path / "log.mat"
    scipy.io.savemat(path, {"t": t, "q": q, "name": "axis 1"})
    with pytest.raises(ParameterValueError, match=r"input variable 'name' .* not numeric"):
        read_log(path, time="t", position="q", input="name")
    path = write_parquet(tmp_path / "log.parquet", {"t": t, "q": q, "s": ["x"] * N})
    with pytest.raises(ParameterValueError, match=r"input column 's' .* its type is string"):
        read_log(path, time="t", position="q", input="s")


def test_csv_row_with_missing_fields(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("t,q,u\n0,0,0\n0.001,1\n")
    with pytest.raises(ParameterValueError, match="line 3 has 2 fields, the header has 3"):
        read_log(path, time="t", position="q", input="u")


def test_column_names_must_be_strings(tmp_path):
    t, q, v = signals()
    path = write_csv(tmp_path / "log.csv", {"t": t, "q": q, "u": v})
    with pytest.raises(ParameterTypeError, match="position must be the name of a column"):
        read_log(path, time="t", position=3, input="u")


def test_log_is_frozen_with_read_only_arrays():
    t, q, v = signals()
    log = Log(t=t, theta=q, u=v)
    with pytest.raises(ValueError, match="read-only"):
        log.theta[0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        log.u = v
    assert log.units["input"] == "N m or N"  # axis not stated: neutral units
    assert list(log.to_pandas().columns) == ["t", "theta", "u"]


def test_log_validates_like_read_log():
    t, q, v = signals()
    with pytest.raises(ParameterValueError, match="theta has a non-finite sample inf at index 3"):
        Log(t=t, theta=np.where(np.arange(N) == 3, np.inf, q), u=v)
    with pytest.raises(ParameterValueError, match="t has 200, theta has 199"):
        Log(t=t, theta=q[1:], u=v)
    with pytest.raises(ParameterTypeError, match="theta must be positions"):
        Log(t=t, theta=["a"] * N, u=v)
    with pytest.raises(ParameterValueError, match="axis must be 'rotary', 'linear' or None"):
        Log(t=t, theta=q, u=v, axis="angular")


@pytest.mark.parametrize("kind", ["parquet", "mat"])
def test_a_log_file_is_held_once(tmp_path, kind):
    """Issue 25: the columns read are the Log's arrays (a float64 MATLAB variable views the
    file's bytes), not copied again by the Log's checks: read_log's tracemalloc peak is one
    copy of the three columns plus the time steps' check (one column), with 5 % to spare."""
    import tracemalloc

    n = 200_000
    t = np.arange(n) * TS
    columns = {"t": t, "q": np.sin(t), "u": np.cos(t)}
    path = WRITERS[kind](tmp_path / f"log.{kind}", columns)
    read_log(path, time="t", position="q", input="u")  # imports and caches: not counted
    tracemalloc.start()
    try:
        log = read_log(path, time="t", position="q", input="u")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    np.testing.assert_array_equal(log.theta, columns["q"])
    assert peak <= 1.05 * (3 + 1) * n * 8, peak / (n * 8)


@pytest.mark.parametrize(
    ("where", "deviation", "accepted"),
    [
        (65_535, 0.3, True),  # within half the tolerance: no median needed
        (65_536, 0.7, True),  # beyond half of it: the median decides, still within
        (65_536, 0.999, True),
        (65_536, 1.001, False),
        (65_535, 1.5, False),  # the step across the first block's end
        (65_537, -1.5, False),
        (131_072, 3.0, False),  # the last block's first step
        (131_080, 3.0, False),  # the very last step
    ],
)
def test_uniform_time_rule_is_the_median_rule_at_every_step(where, deviation, accepted):
    """One step of 1e-3 s off by ``deviation`` times the tolerance (1e-3 relative), anywhere
    in a log of two blocks of steps and more: accepted exactly when every step is within the
    tolerance of the median step (docs/real-data.md), whether or not the check needs the
    median."""
    n = 131_082
    steps = np.full(n - 1, TS)
    steps[where] *= 1.0 + deviation * 1e-3
    t = np.concatenate([[0.0], np.cumsum(steps)])
    median = np.median(np.diff(t))
    expected = bool(np.all(np.abs(np.diff(t) - median) <= 1e-3 * median))
    assert expected is accepted  # the case is on the side it names
    zeros = np.zeros(n)
    if accepted:
        assert Log(t, zeros, zeros).Ts == pytest.approx(TS, rel=1e-5)
    else:
        with pytest.raises(ParameterValueError, match=rf"uniformly sampled.*t\[{where + 1}\]"):
            Log(t, zeros, zeros)


def test_time_refusals_name_the_samples_and_decide_at_every_sampling_rate():
    """The uniform-time rule's decisions with exact binary times (each step exactly 1 s, 2 s,
    1.25 s: no rounding in the steps), and at 10 kHz: a step twice the others, or 1.5 times
    them, is refused; a step exactly at the tolerance passes. The error for times that go back
    names both samples and their values."""
    q, u = np.zeros(12), np.zeros(12)
    steps = np.ones(11)
    with pytest.raises(ParameterValueError, match=r"t\[6\] = 4\.5 s is not after t\[5\] = 5\.0 s"):
        Log(np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 4.5, 7.0, 8.0, 9.0, 10.0, 11.0]), q, u)
    doubled = np.concatenate([[0.0], np.cumsum(np.where(np.arange(11) == 7, 2.0, steps))])
    with pytest.raises(ParameterValueError, match=r"uniformly sampled: the step t\[8\] - t\[7\]"):
        Log(doubled, q, u)
    fast = np.concatenate([[0.0], np.cumsum(np.where(np.arange(11) == 4, 1.5e-4, 1e-4))])
    with pytest.raises(ParameterValueError, match=r"uniformly sampled: the step t\[5\] - t\[4\]"):
        Log(fast, q, u)
    edge = np.concatenate([[0.0], np.cumsum(np.where(np.arange(11) == 3, 1.25, steps))])
    assert Log(edge, q, u, time_tolerance=0.25).Ts == 11.25 / 11  # the mean step
    with pytest.raises(ParameterValueError, match=r"uniformly sampled"):
        Log(edge, q, u, time_tolerance=0.2)
