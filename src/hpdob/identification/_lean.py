"""Forward-backward filtering and differences of long signals in blocks, bit for bit.

:func:`filtfilt_blocks` gives ``scipy.signal.sosfiltfilt(sos, x)`` (odd padding, the default
pad length) block by block, holding a block and the filter's state at each block's start
instead of the padded signal and two filtered copies of it: the forward pass runs once to
record those states and again, block by block from the end, in front of the backward pass.
Both passes are ``scipy.signal.sosfilt``'s recurrence, compiled and run in place
(:mod:`._sos_kernel`), with its state carried from block to block: the same recursion on the
same numbers, so the result is the same to the last bit (``tests/identification/test_lean.py``
compares it with ``sosfiltfilt`` and ``np.gradient``). Compiled, a block costs no Python
overhead, so short signals are cut into short blocks; :func:`filtfilt` of a signal held in
memory needs no blocks at all: both passes run over it in place.

This keeps :func:`hpdob.identify` within two copies of a log (docs/performance.md, issue 25).
"""

from __future__ import annotations

import numpy as np

from ._sos_kernel import run

__all__ = [
    "BLOCK",
    "GRADIENT_BLOCK",
    "SHORT_BLOCK",
    "block_of",
    "decimated_at",
    "filtfilt",
    "filtfilt_blocks",
    "gradient_block",
    "gradient_blocks",
    "gradient_inplace",
    "pad_length",
    "welch",
]

#: The longest block [samples] (0.5 MB of float64); read when a function runs.
BLOCK = 1 << 16
#: The shortest block a signal is cut into by default [samples] (32 kB of float64).
SHORT_BLOCK = 1 << 11
#: The gradient's block [samples]: its few numpy calls a block cost nothing against the
#: arithmetic at this size, and a short log's gradient holds no array of its length.
GRADIENT_BLOCK = 1 << 13


def pad_length(sos: np.ndarray) -> int:
    """``sosfiltfilt``'s default pad length for ``sos``: three times its number of taps."""
    ntaps = 2 * sos.shape[0] + 1
    ntaps -= min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    return 3 * ntaps


def block_of(n: int) -> int:
    """The block of a signal of ``n`` samples: a sixteenth of it, from :data:`SHORT_BLOCK` to
    :data:`BLOCK` (read when called: the tests set ``BLOCK``)."""
    return min(BLOCK, max(SHORT_BLOCK, -(-n // 16)))


def _edges(sos: np.ndarray, n: int, read):
    """``sosfiltfilt``'s odd extension of the signal ``read`` gives at both ends (new arrays),
    as ``scipy.signal._arraytools.odd_ext``.

    Raises
    ------
    ValueError
        As ``sosfiltfilt``, if ``n`` is not above the pad length.
    """
    edge = pad_length(sos)
    if n <= edge:
        raise ValueError(
            f"The length of the input vector x must be greater than padlen, which is {edge}."
        )
    left = 2 * read(0, 1) - read(1, edge + 1)[::-1]
    right = 2 * read(n - 1, n) - read(n - 1 - edge, n - 1)[::-1]
    return np.ascontiguousarray(left, dtype=float), np.ascontiguousarray(right, dtype=float)


def filtfilt_blocks(sos: np.ndarray, n: int, read, block: int | None = None):
    """``scipy.signal.sosfiltfilt(sos, x)`` of a signal of ``n`` samples in blocks.

    ``read(lo, hi)`` returns ``x[lo:hi]`` as float64 (it is called twice per block); a new
    C-contiguous float64 array it returns that owns its data (not a view) is filtered in
    place, anything else is copied first. Yields ``(lo, hi, y)`` with ``y`` equal to
    ``sosfiltfilt(sos, x)[lo:hi]``, from the last block to the first. ``block`` None: a
    sixteenth of the signal, from :data:`SHORT_BLOCK` to :data:`BLOCK` samples (the
    compiled passes cost nothing per block).

    Raises
    ------
    ValueError
        As ``sosfiltfilt``, if ``n`` is not above the pad length.
    """
    from scipy import signal

    block = block_of(n) if block is None else block
    left, right = _edges(sos, n, read)
    edge = left.size
    pieces = [(-edge, 0)] + [(lo, min(lo + block, n)) for lo in range(0, n, block)]
    pieces.append((n, n + edge))

    def get(lo, hi):  # a block of the padded signal that may be filtered in place
        if lo < 0:
            return left.copy()
        if lo >= n:
            return right.copy()
        y = read(lo, hi)
        mine = y.flags.owndata and y.flags.writeable and y.flags.c_contiguous
        return y if mine and y.dtype == np.float64 else np.array(y, dtype=float)

    zi = signal.sosfilt_zi(sos)
    state = zi * left[:1]
    starts = []
    for lo, hi in pieces:
        starts.append(state.copy())
        y = get(lo, hi)
        run(sos, y, state)
        last = y[-1:].copy()
        del y  # not beside the next block
    back = zi * last
    for (lo, hi), start in zip(reversed(pieces), reversed(starts), strict=True):
        y = get(lo, hi)
        run(sos, y, start)  # the forward pass again
        run(sos, y, back, reverse=True)
        if 0 <= lo < n:
            yield lo, hi, y
        del y  # the callers let go of the yielded one


def filtfilt(sos: np.ndarray, x: np.ndarray, block: int | None = None, *, out=None):
    """``scipy.signal.sosfiltfilt(sos, x)`` of a 1-D float64 array, bit for bit, holding one
    new array of ``x``'s size (``sosfiltfilt`` holds three, of the padded size), or none with
    ``out=x`` (written over ``x``).

    Both passes run in place over the whole signal, between the padding's two ends
    (:func:`_edges`, built first); ``block`` is not needed for that (accepted as
    :func:`filtfilt_blocks`'s)."""
    from scipy import signal

    del block
    left, right = _edges(sos, x.size, lambda a, b: x[a:b])
    given = out
    if out is None or not (out.dtype == np.float64 and out.flags.c_contiguous
                           and out.flags.writeable):  # fmt: skip
        out = np.array(x, dtype=float)  # a strided ``out`` is written at the end
    elif out is not x:
        out[...] = x
    zi = signal.sosfilt_zi(sos)
    state = zi * left[:1]
    for piece in (left, out, right):  # forward: sosfilt of the padded signal, piece by piece
        run(sos, piece, state)
    back = zi * right[-1:]
    run(sos, right, back, reverse=True)  # backward, from the padding's end
    run(sos, out, back, reverse=True)  # the left padding's backward pass is not kept
    if given is not None and given is not out:
        given[...] = out
        return given
    return out


def gradient_inplace(f: np.ndarray, dx: float, block: int | None = None) -> np.ndarray:
    """Overwrite ``f`` (1-D float64, at least 2 samples) with ``np.gradient(f, dx)``, bit for
    bit (central differences inside, one-sided at the ends), holding one block beside it
    (the difference and the quotient are written into it and into ``f``: no temporaries)."""
    block = GRADIENT_BLOCK if block is None else block
    n = f.size
    first = (f[1] - f[0]) / dx
    last = (f[-1] - f[-2]) / dx
    twice = 2.0 * dx
    before = np.empty(min(block, n))
    previous = f[0]  # f[lo - 1] before it was overwritten
    for lo in range(1, n - 1, block):
        hi = min(lo + block, n - 1)
        m = hi - lo
        before[0] = previous
        before[1:m] = f[lo : hi - 1]
        previous = f[hi - 1]
        np.subtract(f[lo + 1 : hi + 1], before[:m], out=before[:m])
        np.divide(before[:m], twice, out=f[lo:hi])
    f[0] = first
    f[-1] = last
    return f


def gradient_blocks(blocks, n: int, dx: float):
    """``np.gradient(f, dx)`` of a signal of ``n`` samples (at least 2) given block by block
    from its last block to its first as ``(lo, hi, f[lo:hi])`` (:func:`filtfilt_blocks`'
    order, new arrays): yields ``(lo, hi, g)``, ``g = np.gradient(f, dx)[lo:hi]`` bit for bit
    (the same two operations on each sample), in the same order, written over the block. A
    block waits for the last sample of the one before it: two blocks and a copy of one are
    held, never an array of the signal's length."""
    twice = 2.0 * dx
    pending = None  # (lo, hi, f[lo:hi], f[hi] or None): the block whose gradient waits
    for lo, hi, f in blocks:
        after = None
        if pending is not None:
            after = float(pending[2][0])  # before the block's gradient overwrites it
            yield _gradient_piece(*pending, f[-1], n, dx, twice)
        pending = (lo, hi, f, after)
    if pending is not None:
        yield _gradient_piece(*pending, None, n, dx, twice)


def _gradient_piece(lo, hi, f, after, before, n, dx, twice):
    """:func:`gradient_blocks`' block ``f = x[lo:hi]`` with its neighbours ``x[hi]`` (None at
    the end) and ``x[lo - 1]`` (None at the start), as ``np.gradient``: central differences
    over ``2 dx`` inside, one-sided over ``dx`` at the ends."""
    m = hi - lo
    ext = np.empty(m + 2)  # x[lo - 1 : hi + 1]
    ext[0] = np.nan if before is None else before
    ext[1 : m + 1] = f
    ext[m + 1] = np.nan if after is None else after
    a = 1 if lo == 0 else 0
    b = m - 1 if hi == n else m
    np.subtract(ext[a + 2 : b + 2], ext[a:b], out=f[a:b])
    np.divide(f[a:b], twice, out=f[a:b])
    if lo == 0:
        f[0] = (ext[2] - ext[1]) / dx
    if hi == n:
        f[m - 1] = (ext[m] - ext[m - 1]) / dx
    return lo, hi, f


def gradient_block(f: np.ndarray, lo: int, hi: int, dx: float) -> np.ndarray:
    """``np.gradient(f, dx)[lo:hi]`` (1-D ``f`` of at least 2 samples), bit for bit."""
    n = f.size
    a, b = max(lo, 1), min(hi, n - 1)
    out = np.empty(hi - lo)
    if b > a:  # the difference and the quotient written into out: no temporaries
        inside = out[a - lo : b - lo]
        np.subtract(f[a + 1 : b + 1], f[a - 1 : b - 1], out=inside)
        np.divide(inside, 2.0 * dx, out=inside)
    if lo == 0:
        out[0] = (f[1] - f[0]) / dx
    if hi == n:
        out[-1] = (f[-1] - f[-2]) / dx
    return out


def decimated_at(sos: np.ndarray, n: int, read, samples: np.ndarray, block: int | None = None,
                 *, out: np.ndarray | None = None):  # fmt: skip
    """``scipy.signal.sosfiltfilt(sos, x)[samples]`` of the signal ``read`` gives (see
    :func:`filtfilt_blocks`) at increasing sample indices ``samples``, holding blocks and the
    result only (written into ``out``, of ``samples``' size, if given)."""
    out = np.empty(samples.size) if out is None else out
    for lo, hi, y in filtfilt_blocks(sos, n, read, block):
        a, b = np.searchsorted(samples, (lo, hi))
        out[a:b] = y[samples[a:b] - lo]
        del y  # not beside the next block
    return out


def welch(x: np.ndarray, *, fs: float, nperseg: int, window=None):
    """``scipy.signal.welch(x, fs=fs, window=window, nperseg=nperseg)`` of a 1-D float64
    array (its other defaults: half-overlapping segments, constant detrend, one-sided density,
    mean), bit for bit, one segment at a time: it holds the segments' periodograms (about
    ``x.size`` values) and one segment's detrended, windowed and transformed copies, not those
    of every segment, nor ``ShortTimeFFT.spectrogram``'s further copies of a segment (padded,
    its complex spectrum stored, squared parts; issue 25).

    ``x`` may also be ``(n, read)``: the signal's length and ``read(lo, hi)`` returning
    ``x[lo:hi]`` as float64, called for the samples of one segment at a time (the signal
    itself is then never held); a new array it returns that owns its data (not a view) is
    detrended in place. ``window`` None is ``welch``'s default window. ``nperseg`` must not
    exceed the signal's length.
    """
    import inspect

    from scipy import fft, signal

    if window is None:
        window = inspect.signature(signal.welch).parameters["window"].default
    if isinstance(x, tuple):
        n, read = x
    else:
        n, read = x.size, lambda lo, hi: x[lo:hi]
    if not 0 < nperseg <= n:
        raise ValueError(f"nperseg must be from 1 to {n}, got {nperseg}")
    noverlap = nperseg // 2
    sft = signal.ShortTimeFFT(signal.get_window(window, nperseg), nperseg - noverlap, fs,
                              fft_mode="onesided", mfft=nperseg, scale_to="psd",
                              phase_shift=None)  # fmt: skip
    count = (n - noverlap) // sft.hop  # as scipy.signal.csd
    window = sft.win  # scaled to a density, as the spectrogram applies it
    power = np.empty((sft.f_pts, count))
    for p in range(count):
        # what ShortTimeFFT.spectrogram(x, x, detr="constant", k_offset=nperseg // 2)
        # computes for segment p, x[p hop : p hop + nperseg] (no padding: none hangs over an
        # end), in the same operations: x - mean(x), times the window, rfft, |.|^2
        segment = read(p * sft.hop, p * sft.hop + nperseg)
        mine = segment.flags.owndata and segment.flags.writeable
        segment = np.subtract(segment, np.mean(segment), out=segment if mine else None)
        segment *= window
        spectrum = fft.rfft(segment, n=nperseg)
        del segment
        np.square(spectrum.real, out=power[:, p])
        power[:, p] += np.square(spectrum.imag)
        del spectrum
    # csd's one-sided doubling and its mean over the segments, on the same layout
    power = np.moveaxis(power, 0, -1)
    power[..., 1 : -1 if sft.mfft % 2 == 0 else None] *= 2
    power = np.moveaxis(power, -1, 0)
    power = power.mean(axis=-1) if power.shape[-1] > 1 else power.reshape(power.shape[:-1])
    return sft.f, power
