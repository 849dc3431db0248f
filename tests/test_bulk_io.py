"""Long traces in and out (issue 25): the column-wise CSV writer gives the bytes of the csv
module with repr, Parquet logs are read row group by row group into arrays held once, and long
traces are drawn as their envelope."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from hpdob._plotting import envelope
from hpdob._table import columns_to_csv


def csv_module_text(columns: dict, path) -> bytes:
    """The reference: the csv module's default dialect, every value ``repr(float(v))``."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(list(columns))
        writer.writerows(
            [repr(float(v)) for v in row] for row in zip(*columns.values(), strict=True)
        )
    return path.read_bytes()


def test_column_wise_csv_is_byte_for_byte_the_csv_modules(tmp_path):
    rng = np.random.default_rng(7)
    n = 70_001  # several chunks and a partial one
    bits = rng.integers(0, 2**64, size=n, dtype=np.uint64).view(np.float64)  # every kind
    special = np.array([0.0, -0.0, 1.0, -1.0, 0.1, 1e-5, 1e-4, 9.999e-5, 1e15, 1e16, 1e17,
                        123456789012345678.0, 1234567890123456.7, 5e-324, 2.2250738585072014e-308,
                        1.7976931348623157e308, np.nan, -np.nan, np.inf, -np.inf, 2.0**60,
                        1e22, 1e100, 1e-100, 0.5, 100.0, 12.5])  # fmt: skip
    noise = rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n)
    columns = {
        "t": np.arange(n) * 1e-3,
        "bits": np.where(np.isfinite(bits), bits, 0.0),
        "special": np.resize(special, n),
        "noise": noise,
        "walk": np.cumsum(rng.standard_normal(n)) * 1e-4,
    }
    got = columns_to_csv(columns, tmp_path / "fast.csv").read_bytes()
    assert got == csv_module_text(columns, tmp_path / "reference.csv")


def test_shortest_digits_match_repr_where_ryu_takes_its_rare_paths(tmp_path):
    """The cases of the shortest-digit algorithm that random bit patterns rarely reach: the
    powers of two (the lower neighbour is half as far), subnormals, exact integers and powers of
    ten (trailing zeros: Ryu's general case), each with its neighbours, against ``repr``."""
    powers = np.ldexp(1.0, np.arange(-1074, 1024))
    tens = np.array([float(f"1e{k}") for k in range(-323, 309)])
    integers = np.concatenate([np.arange(1.0, 3000.0), 2.0**53 + np.arange(-50.0, 50.0) * 2.0,
                               np.arange(1, 200) * 1e15, np.arange(1, 200) * 1e16])  # fmt: skip
    subnormal = np.arange(1, 3000) * 5e-324
    base = np.concatenate([powers, tens, integers, subnormal, np.arange(1, 3000) * 0.001])
    values = np.concatenate([base, np.nextafter(base, np.inf), np.nextafter(base, 0.0)])
    values = np.concatenate([values, -values])
    columns = {"x": values, "y": values[::-1].copy()}
    got = columns_to_csv(columns, tmp_path / "fast.csv").read_bytes()
    assert got == csv_module_text(columns, tmp_path / "reference.csv")


def test_short_and_mixed_tables_keep_the_csv_module(tmp_path):
    columns = {"name": ["a", "b"], "flag": [True, False], "count": [1, 2], "x": [0.5, 1e-7]}
    text = columns_to_csv(columns, tmp_path / "table.csv").read_bytes().decode()
    assert text == "name,flag,count,x\r\na,true,1,0.5\r\nb,false,2,1e-07\r\n"


def test_parquet_log_is_read_by_row_groups_and_held_once(tmp_path):
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    from hpdob.identification import read_log

    n = 5000
    t = np.arange(n) * 1e-3
    theta = np.sin(t)
    u = np.arange(n, dtype=np.int32)  # an integer column is read as float
    path = tmp_path / "log.parquet"
    pq.write_table(pa.table({"t": t, "q": theta, "u": u}), path, row_group_size=1024)
    assert pq.ParquetFile(path).num_row_groups == 5
    log = read_log(path, time="t", position="q", input="u")
    assert np.array_equal(log.t, t) and np.array_equal(log.theta, theta)
    assert np.array_equal(log.u, u.astype(float)) and log.u.dtype == np.float64
    assert not log.theta.flags.writeable and log.theta.base is None  # no other copy exists
    doubled = read_log(path, time="t", position="q", input="u", input_gain=2.0)
    assert np.array_equal(doubled.u, 2.0 * u)
    with_null = tmp_path / "null.parquet"
    pq.write_table(pa.table({"t": t, "q": pa.array([0.0, None] + [1.0] * (n - 2)), "u": u}),
                   with_null, row_group_size=1024)  # fmt: skip
    with pytest.raises(ValueError, match=r"position column 'q' has a non-finite sample nan at "
                                         r"index 1"):  # fmt: skip
        read_log(with_null, time="t", position="q", input="u")


def test_envelope_keeps_short_traces_and_the_extremes_of_long_ones():
    t = np.arange(1000) * 1e-3
    y = np.sin(40 * t)
    same_t, same_y = envelope(t, y)
    assert same_t is t and same_y is y
    rng = np.random.default_rng(3)
    t = np.arange(1_000_003) * 1e-3
    y = rng.standard_normal(t.size)
    et, ey = envelope(t, y, samples=2000)
    assert ey.size == 2 * 1000 + 1_000_003 - 1000 * 1000  # two per run and the remainder
    assert np.all(np.diff(et) >= 0)  # in time order
    runs = y[:1_000_000].reshape(1000, 1000)
    assert np.array_equal(np.sort(ey[:2000].reshape(1000, 2), axis=1),
                          np.column_stack([runs.min(axis=1), runs.max(axis=1)]))  # fmt: skip
    assert np.array_equal(ey, y[np.searchsorted(t, et)])  # points of the trace itself


def test_envelope_of_a_trace_given_in_blocks_is_the_whole_traces():
    from hpdob._plotting import Envelope

    rng = np.random.default_rng(3)
    for n, samples in [(1000, 2000), (1000, 100), (1003, 100), (12345, 64), (100_000, 1000)]:
        t = np.arange(n) * 1e-3
        y = rng.integers(0, 5, n).astype(float)  # ties: the first extreme wins
        y[rng.integers(0, n, 3)] = np.nan  # and a NaN, as np.argmin
        for _ in range(10):
            cuts = np.sort(rng.integers(0, n, rng.integers(0, 8)))
            streamed = Envelope(n, samples=samples)
            for a, b in zip([0, *cuts], [*cuts, n], strict=True):
                streamed.add(t[a:b], y[a:b])
            (t1, y1), (t2, y2) = streamed.trace, envelope(t, y, samples=samples)
            assert np.array_equal(t1, t2) and np.array_equal(y1, y2, equal_nan=True)


def test_the_column_wise_writer_reports_rows_written_per_chunk(tmp_path):
    # issue 27 (rel4, item 3): simulate's and estimate's "writing" stage counts the chunks
    pytest.importorskip("pyarrow")
    from hpdob._csv_floats import CHUNK

    n = 2 * CHUNK + 5  # two whole chunks and a partial one
    columns = {"t": np.arange(n) * 1e-3, "x": np.sin(np.arange(n) * 1e-3)}
    calls = []
    got = columns_to_csv(columns, tmp_path / "a.csv", lambda *call: calls.append(call))
    assert calls == [(CHUNK, n), (2 * CHUNK, n), (n, n)]
    assert got.read_bytes() == csv_module_text(columns, tmp_path / "reference.csv")
    short = []  # the csv module's path (a short table): once, at the end
    columns_to_csv({"x": [0.5, 1.5]}, tmp_path / "b.csv", lambda *call: short.append(call))
    assert short == [(2, 2)]
    with pytest.raises(TypeError, match=r"^progress must be a callable .* got 'yes'"):
        columns_to_csv(columns, tmp_path / "c.csv", "yes")
    assert not (tmp_path / "c.csv").exists()


@pytest.mark.parametrize("n", [2000, 6210, 40_000])
def test_a_short_table_is_formatted_in_short_chunks_same_bytes_and_progress(tmp_path, n):
    """A table shorter than 16 chunks goes in halves of CHUNK (at least SHORT_CHUNK rows): its
    text is never held whole (the EMPS identification.csv's 6 000 rows were one chunk of 25
    bytes a value, more than the log), the same bytes, progress still per CHUNK rows."""
    import tracemalloc

    from hpdob import _csv_floats

    rng = np.random.default_rng(n)
    columns = {name: rng.standard_normal(n) * 10.0 ** rng.integers(-9, 9, n)
               for name in ("t", "u", "u_model", "residual")}  # fmt: skip
    calls = []
    columns_to_csv(columns, tmp_path / "warm.csv")  # compiled before it is traced
    tracemalloc.start()
    try:
        got = columns_to_csv(columns, tmp_path / "a.csv", lambda *call: calls.append(call))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert got.read_bytes() == csv_module_text(columns, tmp_path / "reference.csv")
    chunk = _csv_floats.CHUNK
    assert calls == [(k, n) for k in range(chunk, n, chunk)] + [(n, n)]
    whole = n * 4 * (8 + _csv_floats._WIDTH + 1)  # a chunk of all the rows: text and copy
    if n >= 16 * _csv_floats.SHORT_CHUNK:
        assert peak < whole / 2


@pytest.mark.parametrize("chunk", [0, -4, 2.5, True])
def test_a_row_writer_refuses_a_chunk_that_is_not_a_positive_row_count(chunk, tmp_path):
    from hpdob._csv_floats import RowWriter
    from hpdob._validation import ParameterValueError

    with open(tmp_path / "rows.csv", "wb") as handle, RowWriter(handle, rows=3) as writer:
        with pytest.raises(ParameterValueError, match="chunk must be a positive number of rows"):
            writer.write([np.arange(3.0)], chunk=chunk)
        writer.write([np.arange(3.0)], chunk=2)
    assert (tmp_path / "rows.csv").read_bytes() == b"0.0\r\n1.0\r\n2.0\r\n"  # csv's rows
