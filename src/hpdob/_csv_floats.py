"""CSV rows of float columns, formatted column-wise in compiled code, with Python's text.

Every value is written as ``repr(float(value))`` (the shortest text that reads back as the same
double, Python's layout: ``1.0``, ``1e-05``, ``1e+16``, ``-0.0``, ``nan``, ``inf``), rows ending
in ``\\r\\n`` like :mod:`csv`'s default dialect, so the files are byte for byte those of the
row-by-row writer. The shortest digits come from pyarrow's cast to text (the double-conversion
library's shortest mode, vectorised in C++); a numba pass rewrites each value into Python's
layout and interleaves the columns. A log of 1e7 samples is written in chunks, two at a time,
so the memory held is a few chunks, not the file.

Imported on first use (numba and pyarrow are not imported by ``import hpdob``).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
import pyarrow as pa

__all__ = ["write_float_rows"]

#: Rows per chunk: ~3 MB of text for five columns.
CHUNK = 1 << 15
#: Longest text of one value: ``-1.2345678901234567e-308``.
_WIDTH = 24

_DOT, _MINUS, _PLUS, _ZERO, _E, _N, _I = 46, 45, 43, 48, 101, 110, 105


@numba.njit(nogil=True, cache=True, inline="always")  # a call would count references
def _value(data, start, stop, out, pos, digits):
    """Rewrite one shortest-digit token ``data[start:stop]`` as Python's ``repr``; return the
    position after it in ``out``."""
    i = start
    negative = data[i] == _MINUS
    if negative:
        i += 1
    if data[i] == _N:  # nan, whatever its sign bit (repr writes "nan")
        out[pos], out[pos + 1], out[pos + 2] = _N, 97, _N
        return pos + 3
    if negative:
        out[pos] = _MINUS
        pos += 1
    if data[i] == _I:  # inf
        out[pos], out[pos + 1], out[pos + 2] = _I, _N, 102
        return pos + 3
    # digits d_1..d_n (no leading zeros) and the decimal point's place: value 0.d_1..d_n 10^point
    n = 0
    point = 0
    fraction = False
    leading = True
    while i < stop:
        c = data[i]
        if c == _DOT:
            fraction = True
        elif c == _E:
            break
        elif leading and c == _ZERO:
            if fraction:
                point -= 1
        else:
            leading = False
            digits[n] = c
            n += 1
            if not fraction:
                point += 1
        i += 1
    if i < stop:  # exponent
        i += 1
        sign = 1
        if data[i] == _MINUS:
            sign = -1
            i += 1
        elif data[i] == _PLUS:
            i += 1
        e = 0
        while i < stop:
            e = 10 * e + (data[i] - _ZERO)
            i += 1
        point += sign * e
    while n > 0 and digits[n - 1] == _ZERO:
        n -= 1
    if n == 0:  # zero (its sign written above)
        out[pos], out[pos + 1], out[pos + 2] = _ZERO, _DOT, _ZERO
        return pos + 3
    if -4 < point <= 16:  # Python's repr: positional notation
        if point <= 0:
            out[pos], out[pos + 1] = _ZERO, _DOT
            pos += 2
            for _ in range(-point):
                out[pos] = _ZERO
                pos += 1
            for j in range(n):
                out[pos] = digits[j]
                pos += 1
        elif point >= n:
            for j in range(n):
                out[pos] = digits[j]
                pos += 1
            for _ in range(point - n):
                out[pos] = _ZERO
                pos += 1
            out[pos], out[pos + 1] = _DOT, _ZERO
            pos += 2
        else:
            for j in range(point):
                out[pos] = digits[j]
                pos += 1
            out[pos] = _DOT
            pos += 1
            for j in range(point, n):
                out[pos] = digits[j]
                pos += 1
        return pos
    out[pos] = digits[0]  # scientific: d.ddd e+XX, at least two exponent digits
    pos += 1
    if n > 1:
        out[pos] = _DOT
        pos += 1
        for j in range(1, n):
            out[pos] = digits[j]
            pos += 1
    e = point - 1
    out[pos] = _E
    out[pos + 1] = _MINUS if e < 0 else _PLUS
    pos += 2
    e = abs(e)
    if e >= 100:
        out[pos] = _ZERO + e // 100
        pos += 1
        e %= 100
    out[pos], out[pos + 1] = _ZERO + e // 10, _ZERO + e % 10
    return pos + 2


@numba.njit(nogil=True, cache=True)
def _rows(offsets, data, out):
    """Interleave the columns' tokens (``offsets[c, k]:offsets[c, k + 1]`` of ``data``) into
    CSV rows; return the number of bytes written."""
    digits = np.empty(32, np.uint8)
    columns, n = offsets.shape[0], offsets.shape[1] - 1
    pos = 0
    for k in range(n):
        for c in range(columns):
            pos = _value(data, offsets[c, k], offsets[c, k + 1], out, pos, digits)
            out[pos] = 44  # ","
            pos += 1
        out[pos - 1] = 13  # "\r\n" instead of the last ","
        out[pos] = 10
        pos += 1
    return pos


def _chunk(columns: list, start: int, stop: int) -> np.ndarray:
    """CSV text of rows ``start:stop``."""
    texts = [pa.array(c[start:stop]).cast(pa.string()) for c in columns]
    offsets = np.empty((len(texts), stop - start + 1), dtype=np.int64)
    data, base = [], 0
    for c, text in enumerate(texts):
        _, ends, chars = text.buffers()
        ends = np.frombuffer(ends, dtype=np.int32)[text.offset : text.offset + len(text) + 1]
        chars = np.frombuffer(chars, dtype=np.uint8)[ends[0] : ends[-1]]
        offsets[c] = ends - ends[0] + base
        data.append(chars)
        base += chars.size
    out = np.empty((stop - start) * len(texts) * (_WIDTH + 1) + 1, dtype=np.uint8)
    return out[: _rows(offsets, np.concatenate(data), out)]


def write_float_rows(handle, columns: list, progress=None) -> None:
    """Write the rows of equal-length float64 ``columns`` to the binary file ``handle``
    (``progress(rows written, rows)`` after each chunk, if given)."""
    n = len(columns[0]) if columns else 0
    starts = range(0, n, CHUNK)
    written = [0]

    def write(future):
        text = future.result()
        handle.write(text)
        if progress is not None:
            written[0] = min(written[0] + CHUNK, n)
            progress(written[0], n)

    with ThreadPoolExecutor(2) as pool:  # numba and pyarrow release the GIL
        pending = []
        for start in starts:
            pending.append(pool.submit(_chunk, columns, start, min(start + CHUNK, n)))
            if len(pending) > 2:
                write(pending.pop(0))
        for future in pending:
            write(future)
