"""A run's metrics from its two error traces in one compiled call (a sweep's row).

:func:`~hpdob.simulation._result.error_metrics` and ``max_abs`` compute a row with about a dozen
numpy calls (per RMS: ``max |x|``, the division, the square, ``np.add.reduce``), each a pass
over the trace and a temporary; after a sweep scenario's loop has streamed its megabyte they
cost ~0.1 ms of Python. :func:`error_row` does the same arithmetic in one ``nogil`` call: the
largest magnitude by a loop (``max`` is exact in any order), each ``(x / scale) ** 2`` as
numpy's division and square compute it, and their sum in numpy's own pairwise order
(:func:`pairwise_sum`: ``np.add.reduce`` of a contiguous float64 array), so each
metric is bit for bit the numpy path's. A trace holding a NaN is left to the numpy path (which
NaN ``np.max`` returns is numpy's business). Imported on a sweep's first row, after the compiled
loop (so numba is loaded already); never by ``import hpdob``.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from ._result import _rms, error_metrics, max_abs, metric_window

__all__ = ["error_row", "numpy_order", "pairwise_sum", "row_metrics"]

_jit = numba.njit(cache=True, nogil=True)

#: numpy's pairwise-sum block (``PW_BLOCKSIZE`` in its ``loops_utils.h``): up to this many
#: values are summed in eight interleaved accumulators, longer runs split in two.
BLOCK = 128


@_jit
def _block(values, start, n):
    """numpy's pairwise sum of ``n <= BLOCK`` values: fewer than 8 one by one from -0.0,
    else eight accumulators (term ``i`` into ``i % 8``) combined as ``((r0 + r1) + (r2 +
    r3)) + ((r4 + r5) + (r6 + r7))``, then the remainder one by one."""
    if n < 8:
        res = -0.0
        for i in range(start, start + n):
            res += values[i]
        return res
    r0, r1, r2, r3 = values[start], values[start + 1], values[start + 2], values[start + 3]
    r4, r5, r6, r7 = values[start + 4], values[start + 5], values[start + 6], values[start + 7]
    i = start + 8
    stop = start + n - n % 8
    while i < stop:
        r0 += values[i]
        r1 += values[i + 1]
        r2 += values[i + 2]
        r3 += values[i + 3]
        r4 += values[i + 4]
        r5 += values[i + 5]
        r6 += values[i + 6]
        r7 += values[i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < start + n:
        res += values[i]
        i += 1
    return res


@_jit
def pairwise_sum(values, start, n):
    """``np.add.reduce(values[start:start + n])``, ``n >= 1``, in numpy's order: up to
    :data:`BLOCK` values by :func:`_block`; longer, the left half's sum plus the right's, split
    at ``n / 2`` rounded down to a multiple of 8. The recursion is unrolled on an explicit
    stack (numba's on-disk cache does not hold a self-recursive function safely)."""
    if n <= BLOCK:
        return _block(values, start, n)
    # tasks: (start, n, whether its two halves' sums are on the value stack); at most two
    # tasks per level of halving, ~60 levels for any array that fits in memory
    task_start = np.empty(128, dtype=np.int64)
    task_n = np.empty(128, dtype=np.int64)
    task_join = np.empty(128, dtype=np.bool_)
    sums = np.empty(64)
    tasks, depth = 1, 0
    task_start[0], task_n[0], task_join[0] = start, n, False
    while tasks:
        tasks -= 1
        s, m, join = task_start[tasks], task_n[tasks], task_join[tasks]
        if join:  # left + right, as numpy adds the two recursive calls
            depth -= 1
            sums[depth - 1] = sums[depth - 1] + sums[depth]
        elif m <= BLOCK:
            sums[depth] = _block(values, s, m)
            depth += 1
        else:
            half = m // 2
            half -= half % 8
            task_start[tasks], task_n[tasks], task_join[tasks] = s, m, True
            task_start[tasks + 1], task_n[tasks + 1] = s + half, m - half
            task_join[tasks + 1] = False
            task_start[tasks + 2], task_n[tasks + 2], task_join[tasks + 2] = s, half, False
            tasks += 3
    return sums[0]


@_jit
def _largest(values, start, stop):
    """``(max |values[start:stop]|, whether a NaN is among them)`` (0.0 for an empty range;
    the NaN told apart so the loop needs no branch)."""
    peak = 0.0
    nan = False
    for i in range(start, stop):
        a = abs(values[i])
        nan |= a != a
        peak = a if a > peak else peak
    return peak, nan


@_jit
def _squares(values, start, stop, scale, out):
    """``out[:stop - start] = np.square(values[start:stop] / scale)``: numpy's division,
    then its square (``q * q``), element by element."""
    for i in range(start, stop):
        q = values[i] / scale
        out[i - start] = q * q


@_jit
def error_row(t, estimation_error, position_error, n, bounds, out):
    """The raw parts of a row over the first ``n`` samples: ``out`` gets, for the estimation
    error and the position error in the windows ``[bounds[0], bounds[1])`` and
    ``[bounds[2], bounds[3])``, each range's largest magnitude (NaN if the range holds one)
    and the sum of its squares scaled by that (numpy's :func:`pairwise_sum`; only where the
    magnitude is positive and finite), then the position error's largest magnitude over all
    ``n`` (NaN likewise); returns the three ranges' ``[start, stop)`` indices."""
    ranges = np.empty(6, dtype=np.int64)
    ranges[0], ranges[1] = 0, n
    for w in range(4):  # np.searchsorted(t[:n], bound, side="left") of the increasing grid
        lo, hi = 0, n
        while lo < hi:
            mid = (lo + hi) >> 1
            if t[mid] < bounds[w]:
                lo = mid + 1
            else:
                hi = mid
        ranges[2 + w] = lo
    squares = np.empty(n)
    for m in range(3):
        values = estimation_error if m == 0 else position_error
        start = ranges[2 * m]
        stop = max(start, ranges[2 * m + 1])  # an empty window: numpy's slice is empty too
        ranges[2 * m + 1] = stop
        scale, nan = _largest(values, start, stop)
        out[2 * m] = math.nan if nan else scale
        out[2 * m + 1] = 0.0
        if not nan and stop > start and 0.0 < scale < math.inf:
            _squares(values, start, stop, scale, squares)
            out[2 * m + 1] = pairwise_sum(squares, 0, stop - start)
    peak, nan = _largest(position_error, 0, n)
    out[6] = math.nan if nan else peak
    return ranges


#: Lengths the order check sums: short, one block, the first split, several levels.
_CHECK_LENGTHS = (7, 100, 128, 129, 1000, 9001, 70_000)


@functools.cache
def numpy_order() -> bool:
    """Whether :func:`pairwise_sum` gives ``np.add.reduce``'s bits here. numpy's summation
    order is its own business and may change between releases; where it differs from the one
    :func:`pairwise_sum` repeats, :func:`row_metrics` computes every row by numpy."""
    values = np.random.default_rng(0).random(max(_CHECK_LENGTHS)) * 1e3
    return all(
        float(np.add.reduce(values[:n])) == float(pairwise_sum(values, 0, n))
        for n in _CHECK_LENGTHS
    )


def row_metrics(t, estimation_error, position_error, *, regulation, tracking) -> dict:
    """``error_metrics(t, estimation_error, position_error, regulation=..., tracking=...,
    increasing=True)`` with ``max_abs_position_error`` (``max_abs(position_error)``), bit for
    bit, from one :func:`error_row` call: the arrays contiguous float64 of one length, ``t``
    increasing. A range whose largest magnitude is NaN is computed by numpy instead, and every
    range where numpy sums in another order (:func:`numpy_order`)."""
    if not numpy_order():
        return _numpy_row(t, estimation_error, position_error, regulation=regulation,
                          tracking=tracking)  # fmt: skip
    bounds = np.array([*metric_window(regulation, "regulation"),
                       *metric_window(tracking, "tracking")])  # fmt: skip
    n = len(t)
    parts = np.empty(7)
    ranges = error_row(t, estimation_error, position_error, n, bounds, parts)
    values = []
    for m, trace in enumerate((estimation_error, position_error, position_error)):
        start, stop = int(ranges[2 * m]), int(ranges[2 * m + 1])
        scale = float(parts[2 * m])
        if start == stop:
            values.append(math.nan)
        elif scale != scale:  # a NaN in the range: numpy's own answer
            values.append(_rms(trace[start:stop]))
        elif not 0.0 < scale < math.inf:
            values.append(scale)  # all zero, or inf in the trace (as _rms)
        else:  # _rms's last line, on the same sum
            values.append(scale * math.sqrt(float(parts[2 * m + 1]) / (stop - start)))
    peak = float(parts[6])
    return {
        "rms_estimation_error": values[0],
        "rms_position_error_regulation": values[1],
        "rms_position_error_tracking": values[2],
        "max_abs_position_error": (
            math.nan if not n else (max_abs(position_error) if peak != peak else peak)
        ),
    }


def _numpy_row(t, estimation_error, position_error, *, regulation, tracking) -> dict:
    """:func:`row_metrics` by numpy: ``error_metrics`` and ``max_abs``."""
    row = error_metrics(t, estimation_error, position_error, regulation=regulation,
                        tracking=tracking, increasing=True)  # fmt: skip
    row["max_abs_position_error"] = max_abs(position_error)
    return row
