"""A second-order-section filter run in place, scipy's own recurrence compiled with numba.

:func:`sos_run` repeats ``scipy.signal.sosfilt``'s transposed direct form II
(``scipy/signal/_sosfilt.pyx``, ``_sosfilt_float``) operation for operation, in the same
order, so that it gives the same numbers to the last bit (``tests/identification/
test_lean.py`` compares it with ``sosfilt`` and ``sosfiltfilt`` over random filters and
signals). It writes the output over its input and carries the state in place: no copy of
the signal, and (compiled) no Python overhead per call, so that the block-wise filters of
:mod:`._lean` may use short blocks, or none. :func:`sos_kernel` compiles it lazily (machine
code cached on disk); without numba it is ``scipy.signal.sosfilt`` written back in place.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["run", "sos_kernel", "sos_run"]


def sos_run(sos, x, zi, reverse):
    """Filter ``x`` (1-D float64) through ``sos`` (``(sections, 6)``) from state ``zi``
    (``(sections, 2)``), both in place: ``x`` becomes ``sosfilt(sos, x, zi=zi)[0]`` and ``zi``
    its final state; with ``reverse`` the samples are taken from the last (``x[::-1]``
    filtered, written back where they were read)."""
    n = x.shape[0]
    sections = sos.shape[0]
    for k in range(n):
        i = n - 1 - k if reverse else k
        x_cur = x[i]
        for s in range(sections):
            # _sosfilt_float's three statements, the same operands in the same order
            x_new = sos[s, 0] * x_cur + zi[s, 0]
            zi[s, 0] = sos[s, 1] * x_cur - sos[s, 4] * x_new + zi[s, 1]
            zi[s, 1] = sos[s, 2] * x_cur - sos[s, 5] * x_new
            x_cur = x_new
        x[i] = x_cur


def _scipy_run(sos, x, zi, reverse):
    """:func:`sos_run` by ``scipy.signal.sosfilt`` (which works on a copy of ``x``)."""
    from scipy import signal

    view = x[::-1] if reverse else x
    y, zf = signal.sosfilt(sos, view, zi=zi)
    view[...] = y
    zi[...] = zf


@functools.cache
def sos_kernel():
    """:func:`sos_run` compiled with numba, or ``scipy.signal.sosfilt`` written back in place
    if numba is missing (the same numbers; a copy of each signal filtered)."""
    try:
        import numba
    except ImportError:
        return _scipy_run
    compiled = numba.njit(cache=True, nogil=True)(sos_run)
    return compiled if _agrees(compiled) else _scipy_run


def _agrees(kernel) -> bool:
    """Whether ``kernel`` gives scipy's bits on a fixed filter and signal. scipy's Cython
    source is compiled by the platform's C compiler, which may contract a multiply and an add
    into one fused operation (clang does by default; numba never does without fastmath): where
    the two differ, scipy's own ``sosfilt`` is used, so that the numbers stay scipy's."""
    from scipy import signal

    sos = signal.butter(6, 0.07, output="sos")
    x = np.random.default_rng(0).standard_normal(512)
    expected, zf = signal.sosfilt(sos, x, zi=signal.sosfilt_zi(sos) * 0.3)
    y, zi = x.copy(), signal.sosfilt_zi(sos) * 0.3
    kernel(np.ascontiguousarray(sos), y, zi, False)
    return bool(np.array_equal(y, expected) and np.array_equal(zi, zf))


def run(sos: np.ndarray, x: np.ndarray, zi: np.ndarray, *, reverse: bool = False) -> None:
    """:func:`sos_kernel` on C-contiguous float64 ``sos``, ``x`` and ``zi`` (checked: the
    compiled code has one signature, reads without bounds checks and writes where it reads)."""
    sos = np.ascontiguousarray(sos, dtype=np.float64)
    if sos.ndim != 2 or sos.shape[1] != 6:
        raise ValueError(f"sos must be an array of shape (sections, 6), got shape {sos.shape}")
    if x.ndim != 1:
        raise ValueError(f"x must be a 1-D array, got shape {x.shape}")
    if zi.shape != (sos.shape[0], 2):
        raise ValueError(
            f"zi must be an array of shape ({sos.shape[0]}, 2) for {sos.shape[0]} sections, "
            f"got shape {zi.shape}"
        )
    for name, a in (("x", x), ("zi", zi)):
        if not (a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable):
            got = f"{a.dtype} {'' if a.flags.writeable else 'read-only '}"
            got += "C-contiguous" if a.flags.c_contiguous else "strided"
            raise ValueError(f"{name} must be a writeable C-contiguous float64 array, got {got}")
    sos_kernel()(sos, x, zi, reverse)
