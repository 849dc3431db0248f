"""CSV rows of float columns, formatted column-wise in compiled code, with Python's text.

Every value is written as ``repr(float(value))`` (the shortest text that reads back as the same
double, Python's layout: ``1.0``, ``1e-05``, ``1e+16``, ``-0.0``, ``nan``, ``inf``), rows ending
in ``\\r\\n`` like :mod:`csv`'s default dialect, so the files are byte for byte those of the
row-by-row writer. The shortest digits are computed by Ryu (Adams 2018, the algorithm of
``ulfjack/ryu``'s ``d2s.c``, written here in numba with the 128-bit products split into 64-bit
halves): they are the shortest decimal that rounds back to the double, the nearest one to it
where several are as short, which is what Python's ``repr`` (David Gay's ``dtoa``, mode 0)
gives. A numba pass writes each value in Python's layout and interleaves the columns, in chunks
formatted on two threads, so the memory held is a few chunks, not the file.

Imported on first use (numba is not imported by ``import hpdob``).

References
----------
U. Adams, "Ryū: fast float-to-string conversion", PLDI 2018, doi:10.1145/3192366.3192369.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

__all__ = ["RowWriter", "format_rows", "write_float_rows"]

#: Rows per chunk: ~3 MB of text for five columns (a few chunks are held at a time).
CHUNK = 1 << 15
#: The shortest chunk of a short table (:func:`write_float_rows`) [rows].
SHORT_CHUNK = 1 << 8
#: Longest text of one value: ``-1.2345678901234567e-308``.
_WIDTH = 24

_DOT, _MINUS, _PLUS, _ZERO, _E = 46, 45, 43, 48, 101

_POW5_BITCOUNT = 125  # bits of the 5^i table entries (Ryu's DOUBLE_POW5_BITCOUNT)
_POW5_INV_BITCOUNT = 125  # and of the 2^k / 5^i ones (DOUBLE_POW5_INV_BITCOUNT)


def _tables() -> tuple[np.ndarray, np.ndarray]:
    """Ryu's tables, exact from Python integers: the top 125 bits of ``5^i`` (i < 326) and
    ``floor(2^(bits(5^i) - 1 + 125) / 5^i) + 1`` (i < 342), each as (low, high) 64-bit words."""
    mask = (1 << 64) - 1
    split = np.empty((326, 2), dtype=np.uint64)
    for i in range(326):
        p = 5**i
        shift = p.bit_length() - _POW5_BITCOUNT
        v = p >> shift if shift >= 0 else p << -shift
        split[i] = v & mask, v >> 64
    inverse = np.empty((342, 2), dtype=np.uint64)
    for i in range(342):
        p = 5**i
        v = (1 << (p.bit_length() - 1 + _POW5_INV_BITCOUNT)) // p + 1
        inverse[i] = v & mask, v >> 64
    return split, inverse


_POW5_SPLIT, _POW5_INV_SPLIT = _tables()

# uint64 constants: numba would turn a mix of uint64 and int64 operands into float64.
_U0, _U1, _U2, _U4, _U5, _U10, _U32, _U64, _U100 = map(np.uint64, (0, 1, 2, 4, 5, 10, 32, 64, 100))
_LOW32 = np.uint64(0xFFFFFFFF)
_MANTISSA = np.uint64((1 << 52) - 1)
_HIDDEN = np.uint64(1 << 52)
_SIGN = np.uint64(1 << 63)
_U10000 = np.uint64(10000)
_U1E8 = np.uint64(100_000_000)
#: ``10^i`` for i < 17, and the text of 00 to 99 (the digits are written two at a time).
_POW10 = np.array([10**i for i in range(17)], dtype=np.uint64)
_PAIRS = np.frombuffer(b"".join(b"%02d" % i for i in range(100)), dtype=np.uint8).copy()


@numba.njit(nogil=True, cache=True, inline="always")
def _mul_shift(m, low, high, j):
    """``floor(m * (high 2^64 + low) / 2^j)`` for ``m < 2^55`` and ``64 < j < 128`` (Ryu's
    ``mulShift64``)."""
    # m * high, 128 bits, from 32-bit halves
    a0, a1 = m & _LOW32, m >> _U32
    b0, b1 = high & _LOW32, high >> _U32
    p00 = a0 * b0
    mid = a1 * b0 + (p00 >> _U32)
    mid2 = a0 * b1 + (mid & _LOW32)
    high1 = a1 * b1 + (mid >> _U32) + (mid2 >> _U32)
    low1 = (mid2 << _U32) | (p00 & _LOW32)
    # the high word of m * low
    b0, b1 = low & _LOW32, low >> _U32
    p00 = a0 * b0
    mid = a1 * b0 + (p00 >> _U32)
    mid2 = a0 * b1 + (mid & _LOW32)
    high0 = a1 * b1 + (mid >> _U32) + (mid2 >> _U32)
    total = high0 + low1
    if total < high0:  # carry
        high1 += _U1
    shift = np.uint64(j - 64)
    return (high1 << (_U64 - shift)) | (total >> shift)


@numba.njit(nogil=True, cache=True, inline="always")
def _pow5_factor(value):
    count = 0
    while value % _U5 == _U0:
        value //= _U5
        count += 1
    return count


@numba.njit(nogil=True, cache=True, inline="always")
def _shortest(bits):
    """The shortest decimal ``(digits, exponent)`` of the finite non-zero double with the IEEE
    ``bits`` (its magnitude): ``digits * 10^exponent`` rounds back to it (Ryu's ``d2d``)."""
    mantissa = bits & _MANTISSA
    biased = np.int64((bits >> np.uint64(52)) & np.uint64(0x7FF))
    if biased == 0:
        e2 = 1 - 1023 - 52 - 2
        m2 = mantissa
    else:
        e2 = biased - 1023 - 52 - 2
        m2 = _HIDDEN | mantissa
    even = (m2 & _U1) == _U0
    mv = _U4 * m2
    mm_shift = _U1 if (mantissa != _U0 or biased <= 1) else _U0
    vm_zeros = False
    vr_zeros = False
    if e2 >= 0:
        q = ((e2 * 78913) >> 18) - (1 if e2 > 3 else 0)  # log10(2^e2), one less above 3
        e10 = q
        k = _POW5_INV_BITCOUNT + (((q * 1217359) >> 19) + 1) - 1
        i = -e2 + q + k
        low, high = _POW5_INV_SPLIT[q, 0], _POW5_INV_SPLIT[q, 1]
        vr = _mul_shift(_U4 * m2, low, high, i)
        vp = _mul_shift(_U4 * m2 + _U2, low, high, i)
        vm = _mul_shift(_U4 * m2 - _U1 - mm_shift, low, high, i)
        if q <= 21:
            if mv % _U5 == _U0:
                vr_zeros = _pow5_factor(mv) >= q
            elif even:
                vm_zeros = _pow5_factor(mv - _U1 - mm_shift) >= q
            elif _pow5_factor(mv + _U2) >= q:
                vp -= _U1
    else:
        q = ((-e2 * 732923) >> 20) - (1 if -e2 > 1 else 0)  # log10(5^-e2), one less above 1
        e10 = q + e2
        i = -e2 - q
        k = (((i * 1217359) >> 19) + 1) - _POW5_BITCOUNT
        j = q - k
        low, high = _POW5_SPLIT[i, 0], _POW5_SPLIT[i, 1]
        vr = _mul_shift(_U4 * m2, low, high, j)
        vp = _mul_shift(_U4 * m2 + _U2, low, high, j)
        vm = _mul_shift(_U4 * m2 - _U1 - mm_shift, low, high, j)
        if q <= 1:
            vr_zeros = True
            if even:
                vm_zeros = mm_shift == _U1
            else:
                vp -= _U1
        elif q < 63:
            vr_zeros = (mv & ((_U1 << np.uint64(q)) - _U1)) == _U0
    removed = 0
    last = _U0
    if vm_zeros or vr_zeros:  # the general case: trailing zeros decide the rounding
        while vp // _U10 > vm // _U10:
            vm_zeros = vm_zeros and vm % _U10 == _U0
            vr_zeros = vr_zeros and last == _U0
            last = vr % _U10
            vr //= _U10
            vp //= _U10
            vm //= _U10
            removed += 1
        if vm_zeros:
            while vm % _U10 == _U0:
                vr_zeros = vr_zeros and last == _U0
                last = vr % _U10
                vr //= _U10
                vp //= _U10
                vm //= _U10
                removed += 1
        if vr_zeros and last == _U5 and vr % _U2 == _U0:
            last = _U4  # an exact half rounds to even
        up = (vr == vm and (not even or not vm_zeros)) or last >= _U5
        output = vr + (_U1 if up else _U0)
    else:  # the common case; digits removed eight, four, two at a time where Ryu removes one
        # (if vp and vm differ above 10^k they do above every 10^j, j < k; the rounding is that
        # of the last digit removed, the block's leading one: up if the block is >= 5 10^(k-1))
        up = False
        if vp // _U1E8 > vm // _U1E8:
            up = vr % _U1E8 >= np.uint64(50_000_000)
            vr //= _U1E8
            vp //= _U1E8
            vm //= _U1E8
            removed += 8
        while vp // _U10000 > vm // _U10000:
            up = vr % _U10000 >= np.uint64(5000)
            vr //= _U10000
            vp //= _U10000
            vm //= _U10000
            removed += 4
        while vp // _U100 > vm // _U100:
            up = vr % _U100 >= np.uint64(50)
            vr //= _U100
            vp //= _U100
            vm //= _U100
            removed += 2
        while vp // _U10 > vm // _U10:
            up = vr % _U10 >= _U5
            vr //= _U10
            vp //= _U10
            vm //= _U10
            removed += 1
        output = vr + (_U1 if (vr == vm or up) else _U0)
    exponent = e10 + removed
    while output % _U10 == _U0:  # Python's digits end in a non-zero digit
        output //= _U10
        exponent += 1
    return output, exponent


@numba.njit(nogil=True, cache=True, inline="always")
def _digits(value, out, end):
    """Write the decimal digits of ``value`` (> 0) so that the last one is at ``out[end - 1]``:
    the last eight from one remainder by 10^8 (two independent groups of four), then four at a
    time, then two (a table of the pairs 00-99)."""
    if value >= _U1E8:
        low8 = np.int64(value % _U1E8)
        value //= _U1E8
        c, d = low8 % 10000, low8 // 10000
        a, b = 2 * (c % 100), 2 * (c // 100)
        out[end - 4], out[end - 3] = _PAIRS[b], _PAIRS[b + 1]
        out[end - 2], out[end - 1] = _PAIRS[a], _PAIRS[a + 1]
        a, b = 2 * (d % 100), 2 * (d // 100)
        out[end - 8], out[end - 7] = _PAIRS[b], _PAIRS[b + 1]
        out[end - 6], out[end - 5] = _PAIRS[a], _PAIRS[a + 1]
        end -= 8
    rest = np.int64(value)
    while rest >= 10000:
        c = rest % 10000
        rest //= 10000
        a, b = 2 * (c % 100), 2 * (c // 100)
        out[end - 4], out[end - 3] = _PAIRS[b], _PAIRS[b + 1]
        out[end - 2], out[end - 1] = _PAIRS[a], _PAIRS[a + 1]
        end -= 4
    while rest >= 100:
        low = 2 * (rest % 100)
        rest //= 100
        out[end - 2], out[end - 1] = _PAIRS[low], _PAIRS[low + 1]
        end -= 2
    if rest >= 10:
        out[end - 2], out[end - 1] = _PAIRS[2 * rest], _PAIRS[2 * rest + 1]
    else:
        out[end - 1] = _ZERO + rest


@numba.njit(nogil=True, cache=True, inline="always")  # a call would count references
def _value(bits, out, pos):
    """Write the double with the IEEE ``bits`` as Python's ``repr`` does at ``out[pos:]``;
    return the position after it."""
    magnitude = bits & ~_SIGN
    if magnitude >= np.uint64(0x7FF0000000000000):
        if magnitude > np.uint64(0x7FF0000000000000):  # nan, whatever its sign bit
            out[pos], out[pos + 1], out[pos + 2] = 110, 97, 110
            return pos + 3
        if bits & _SIGN:
            out[pos] = _MINUS
            pos += 1
        out[pos], out[pos + 1], out[pos + 2] = 105, 110, 102  # inf
        return pos + 3
    if bits & _SIGN:
        out[pos] = _MINUS
        pos += 1
    if magnitude == _U0:
        out[pos], out[pos + 1], out[pos + 2] = _ZERO, _DOT, _ZERO
        return pos + 3
    value, exponent = _shortest(magnitude)
    n = 17  # the number of digits d_1..d_n
    while n > 1 and value < _POW10[n - 1]:
        n -= 1
    point = exponent + n  # the value is 0.d_1..d_n 10^point
    if -4 < point <= 16:  # Python's repr: positional notation
        if point <= 0:  # 0.00ddd
            out[pos], out[pos + 1] = _ZERO, _DOT
            for j in range(pos + 2, pos + 2 - point):
                out[j] = _ZERO
            _digits(value, out, pos + 2 - point + n)
            return pos + 2 - point + n
        _digits(value, out, pos + n)
        if point >= n:  # ddd00.0
            for j in range(pos + n, pos + point):
                out[j] = _ZERO
            out[pos + point], out[pos + point + 1] = _DOT, _ZERO
            return pos + point + 2
        for j in range(pos + n, pos + point, -1):  # dd.ddd: the fraction moves up by one
            out[j] = out[j - 1]
        out[pos + point] = _DOT
        return pos + n + 1
    _digits(value, out, pos + 1 + n)  # scientific: d.ddd e+XX, at least two exponent digits
    out[pos] = out[pos + 1]
    if n > 1:
        out[pos + 1] = _DOT
        pos += n + 1
    else:
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
def _rows(bits, out):
    """CSV rows of the columns ``bits[c]`` (IEEE bits of float64) into ``out``; return the
    number of bytes written."""
    columns, n = bits.shape
    pos = 0
    for k in range(n):
        for c in range(columns):
            pos = _value(bits[c, k], out, pos)
            out[pos] = 44  # ","
            pos += 1
        out[pos - 1] = 13  # "\r\n" instead of the last ","
        out[pos] = 10
        pos += 1
    return pos


def format_rows(columns: list, start: int, stop: int) -> np.ndarray:
    """CSV text (bytes as uint8) of rows ``start:stop`` of equal-length float64 ``columns``."""
    block = np.empty((len(columns), stop - start), dtype=np.float64)
    for c, column in enumerate(columns):
        block[c] = column[start:stop]
    out = np.empty((stop - start) * len(columns) * (_WIDTH + 1) + 1, dtype=np.uint8)
    return out[: _rows(block.view(np.uint64), out)]


class RowWriter:
    """Writes rows of float64 columns to a binary file as they come, a block at a time.

    Chunks are formatted on two threads (the formatting releases the GIL) while this thread
    writes the previous ones, at most two chunks ahead: the memory held is a few chunks. Use as
    a context manager; :meth:`write` takes the columns of the next rows.
    """

    def __init__(self, handle, *, progress=None, rows: int = 0):
        self.handle = handle
        self._pool = ThreadPoolExecutor(2)
        self._pending: list = []  # (future, rows of its chunk)
        self._progress, self._rows, self._written = progress, rows, 0

    def _write_next(self) -> None:
        future, rows = self._pending.pop(0)
        self.handle.write(future.result())
        self._written += rows
        if self._progress is not None:  # rows written of ``rows`` (a chunk at a time)
            self._progress(self._written, self._rows)

    def write(self, columns: list, *, chunk: int | None = None) -> None:
        """Queue the rows of equal-length float64 ``columns`` (written in order), formatted
        ``chunk`` rows at a time (None: :data:`CHUNK`)."""
        n = len(columns[0]) if columns else 0
        chunk = CHUNK if chunk is None else chunk
        if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
            from ._validation import ParameterValueError

            raise ParameterValueError(f"chunk must be a positive number of rows, got {chunk!r}")
        for start in range(0, n, chunk):
            stop = min(start + chunk, n)
            self._pending.append((self._pool.submit(format_rows, columns, start, stop),
                                  stop - start))  # fmt: skip
            if len(self._pending) > 2:
                self._write_next()

    def drain(self) -> None:
        """Write every queued row: the columns given so far may change after this."""
        while self._pending:
            self._write_next()

    def __enter__(self) -> RowWriter:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        try:
            if kind is None:
                self.drain()
        finally:
            self._pool.shutdown(cancel_futures=True)


def write_float_rows(handle, columns: list, progress=None) -> None:
    """Write the rows of equal-length float64 ``columns`` to the binary file ``handle``
    (``progress(rows written, rows)`` after each chunk, if given)."""
    n = len(columns[0]) if columns else 0
    # a table shorter than 16 chunks in shorter chunks, CHUNK's halves: its text (25 bytes a
    # value at most) and copy are not held whole (the EMPS identification's 6 000 rows were
    # one chunk: more than the log); the same bytes, and progress still every CHUNK rows
    chunk = CHUNK
    while chunk % 2 == 0 and chunk // 2 >= SHORT_CHUNK and 16 * chunk > n:
        chunk //= 2
    report = progress
    if progress is not None and chunk < CHUNK:

        def report(done: int, total: int) -> None:
            if done % CHUNK == 0 or done == total:
                progress(done, total)

    with RowWriter(handle, progress=report, rows=n) as writer:
        writer.write(columns, chunk=chunk)
