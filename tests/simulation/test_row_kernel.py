"""A sweep row's metrics in one compiled call (issue 25): bit for bit the numpy path's.

``_row_kernel.row_metrics`` replaces ``error_metrics(..., increasing=True)`` and ``max_abs``
in ``run_metrics``; its sum of squares follows numpy's pairwise order, so every size class of
that order (fewer than 8 terms, one block of up to 128, split halves) and every special value
(zeros, inf, NaN, empty windows) is compared here by the bits.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob.simulation import _result, _row_kernel

SIZES = [0, 1, 2, 7, 8, 9, 15, 16, 17, 127, 128, 129, 136, 255, 256, 257, 1000, 1023, 1024,
         1025, 4095, 8191, 8192, 8193, 10000, 16385]  # fmt: skip


def _bits(value) -> bytes:
    return np.float64(value).tobytes()


def _numpy_row(t, est, pos, regulation, tracking) -> dict:
    row = _result.error_metrics(t, est, pos, regulation=regulation, tracking=tracking,
                                increasing=True)  # fmt: skip
    row["max_abs_position_error"] = _result.max_abs(pos)
    return row


def _assert_same(t, est, pos, regulation=(1.2, 4.0), tracking=(4.0, math.inf)) -> None:
    expected = _numpy_row(t, est, pos, regulation, tracking)
    got = _row_kernel.row_metrics(t, est, pos, regulation=regulation, tracking=tracking)
    assert list(got) == list(expected)
    for name, value in expected.items():
        assert _bits(got[name]) == _bits(value), (name, len(t), got[name], value)


@pytest.mark.parametrize("n", SIZES[1:])  # a window's sum has a term (empty ones: NaN)
def test_pairwise_sum_is_numpys(n):
    rng = np.random.default_rng(n)
    for _ in range(4):  # magnitudes over 20 decades: the order of the sum shows in the bits
        x = rng.standard_normal(n) * 10.0 ** rng.integers(-10, 10, n)
        scale = float(np.max(np.abs(x))) if n else 1.0
        squares = np.square(x / scale)
        assert _bits(_row_kernel.pairwise_sum(squares, 0, n)) == _bits(np.add.reduce(squares))
        if n > 3:  # an interior range: a window's slice
            expected = np.add.reduce(squares[3:])
            assert _bits(_row_kernel.pairwise_sum(squares, 3, n - 3)) == _bits(expected)


@pytest.mark.parametrize("n", SIZES)
def test_row_is_error_metrics_and_max_abs(n):
    rng = np.random.default_rng(100 + n)
    t = np.arange(n) * (10.0 / max(n, 1))  # the windows cut it at every size
    t.setflags(write=False)  # a run's grid is read-only
    est = rng.standard_normal(n) * 10.0 ** rng.integers(-8, 3, n)
    pos = rng.standard_normal(n) * 1e-3
    _assert_same(t, est, pos)
    _assert_same(t, est, pos, regulation=(0.0, 0.05), tracking=(9.99, 20.0))


def test_special_values_follow_numpy():
    n = 300
    t = np.arange(n) * 0.01
    zeros = np.zeros(n)
    _assert_same(t, zeros, zeros)
    _assert_same(t, -zeros, -zeros)
    for bad in (math.inf, -math.inf, math.nan):
        for index in (0, 150, 299):  # in the regulation window, the tracking window, the end
            est, pos = np.ones(n), np.full(n, 1e-3)
            est[index] = pos[index] = bad
            _assert_same(t, est, pos, regulation=(1.2, 2.0), tracking=(1.4, math.inf))
    nan_and_inf = np.ones(n)
    nan_and_inf[10], nan_and_inf[20] = math.inf, math.nan
    _assert_same(t, nan_and_inf, nan_and_inf, regulation=(0.0, 1.0), tracking=(0.0, 3.0))


def test_empty_windows_and_a_diverged_run_are_nan():
    t = np.arange(50) * 1e-3  # a run that stopped at 0.05 s: both canonical windows empty
    est, pos = np.linspace(-1.0, 1.0, 50), np.linspace(0.0, 1e-3, 50)
    _assert_same(t, est, pos)
    row = _row_kernel.row_metrics(t, est, pos, regulation=(1.2, 4.0), tracking=(4.0, math.inf))
    assert math.isnan(row["rms_position_error_regulation"])
    assert math.isnan(row["rms_position_error_tracking"])
    empty = np.zeros(0)
    _assert_same(empty, empty, empty)
    assert all(math.isnan(v) for v in _row_kernel.row_metrics(
        empty, empty, empty, regulation=(1.2, 4.0), tracking=(4.0, math.inf)).values())  # fmt: skip


def test_bad_windows_are_refused_as_before():
    t = np.arange(10) * 0.1
    with pytest.raises(ValueError, match="regulation"):
        _row_kernel.row_metrics(t, t, t, regulation=(2.0, 1.0), tracking=(0.0, 1.0))


def test_the_order_check_holds_here_and_its_failure_leaves_rows_to_numpy(monkeypatch):
    """numpy's summation order is checked once: it holds on this machine (else every other
    test of this file would fail too), and where it does not, the rows are numpy's own."""
    assert _row_kernel.numpy_order()
    rng = np.random.default_rng(5)
    t = np.arange(3000) * 1e-3
    est, pos = rng.standard_normal(3000), rng.standard_normal(3000) * 1e-3
    monkeypatch.setattr(_row_kernel, "numpy_order", lambda: False)
    monkeypatch.setattr(_row_kernel, "error_row", None)  # not called: numpy computes the row
    _assert_same(t, est, pos)
    _assert_same(t[:0], est[:0], pos[:0])
