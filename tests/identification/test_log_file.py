"""``open_log``: a log file checked as ``read_log`` checks it, then read block by block (issue
25: a Parquet log of 1e7 samples is never held whole); the blocks hold ``read_log``'s values and
every refusal has ``read_log``'s message."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob.identification import LogFile, open_log, read_log

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

N = 5003


def parquet(path, row_group_size=1024, **columns):
    pq.write_table(pa.table(columns), path, row_group_size=row_group_size)
    return path


@pytest.fixture
def columns():
    rng = np.random.default_rng(11)
    t = 0.25 + np.arange(N) * 1e-3 + rng.uniform(-1e-8, 1e-8, N)  # a clock with jitter
    return {"t": t, "q": np.cumsum(rng.standard_normal(N)) * 1e-4,
            "u": rng.integers(-500, 500, N).astype(np.int32)}  # fmt: skip


@pytest.mark.parametrize("options", [{"time": "t"}, {"time": "t", "input_gain": 0.35},
                                     {"Ts": 2e-3}, {"time": "t", "input_gain": "g"}])  # fmt: skip
def test_blocks_hold_read_logs_values(tmp_path, columns, options):
    path = parquet(tmp_path / "log.parquet", **columns, g=np.full(N, 0.5))
    whole = read_log(path, position="q", input="u", axis="linear", **options)
    log = open_log(path, position="q", input="u", axis="linear", **options)
    assert isinstance(log, LogFile) and len(log) == len(whole) == N
    assert log.Ts == whole.Ts and log.input_gain == whole.input_gain
    assert (log.t_first, log.t_last) == (whole.t[0], whole.t[-1])
    assert dict(log.names) == dict(whole.names) and log.source == whole.source
    assert log.units == whole.units
    blocks = list(log.blocks())
    assert len(blocks) > 1 and all(not a.flags.writeable for block in blocks for a in block)
    for got, want in zip(zip(*blocks, strict=True), (whole.t, whole.theta, whole.u),
                         strict=True):  # fmt: skip
        assert np.array_equal(np.concatenate(got), want)
    again = log.read()
    assert np.array_equal(again.t, whole.t) and np.array_equal(again.u, whole.u)


def test_csv_logs_are_read_whole(tmp_path, columns):
    path = tmp_path / "log.csv"
    rows = ["t,q,u"] + [
        f"{float(a)!r},{float(b)!r},{c}" for a, b, c in zip(*columns.values(), strict=True)
    ]
    path.write_text("\n".join(rows))
    whole = read_log(path, time="t", position="q", input="u")
    log = open_log(path, time="t", position="q", input="u")
    assert log.read() is not whole and np.array_equal(log.read().theta, whole.theta)
    t, _, u = (np.concatenate(parts) for parts in zip(*log.blocks(), strict=True))
    assert np.array_equal(t, whole.t) and np.array_equal(u, whole.u) and log.Ts == whole.Ts


def spoiled(columns, name, index, value):
    columns = {k: np.array(v, dtype=float) for k, v in columns.items()}
    columns[name][index] = value
    return columns


@pytest.mark.parametrize(
    "change",
    [
        lambda c: spoiled(c, "q", 3000, np.nan),  # in a later row group
        lambda c: spoiled(spoiled(c, "q", 4000, np.inf), "u", 10, np.nan),  # position first
        lambda c: spoiled(c, "t", 2047, 0.0),  # time going back, at a row group's edge
        lambda c: spoiled(c, "t", 2048, c["t"][2048] + 3e-4),  # a step 30 % too long
        lambda c: {k: v[:5] for k, v in c.items()},  # too short
        lambda c: {k: v[:1] for k, v in c.items()},  # one sample
        lambda c: {**c, "q": np.array(["x"] * N)},  # not numeric
    ],
    ids=["nan", "first-column-first", "backwards", "not-uniform", "short", "one", "text"],
)
def test_refusals_are_read_logs(tmp_path, columns, change):
    path = parquet(tmp_path / "bad.parquet", **change(columns))
    with pytest.raises(ValueError, match=r".") as expected:
        read_log(path, time="t", position="q", input="u")
    with pytest.raises(ValueError, match=r".") as got:
        open_log(path, time="t", position="q", input="u")
    assert str(got.value) == str(expected.value)


@pytest.mark.parametrize(
    ("options", "error"),
    [({"time": "t", "Ts": 1e-3}, ValueError), ({"time": 3}, TypeError),
     ({"time": "t", "input_gain": 0.0}, ValueError), ({"time": "missing"}, ValueError),
     ({"time": "t", "time_tolerance": -1.0}, ValueError)],
)  # fmt: skip
def test_bad_arguments(tmp_path, columns, options, error):
    path = parquet(tmp_path / "log.parquet", **columns)
    with pytest.raises(error):
        open_log(path, position="q", input="u", **options)
