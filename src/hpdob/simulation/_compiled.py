"""Lazily compiled numba versions of hpdob's kernels.

numba is imported on first use only, so ``import hpdob`` stays fast; compiled machine code is
cached on disk (``cache=True``), so only the first run on a machine pays the compilation
(about 1-2 s). Set ``NUMBA_DISABLE_JIT=1`` to run the same kernels as plain Python, e.g. in a
debugger.
"""

from __future__ import annotations

import functools
import warnings

from ._kernel import run_closed_loop

__all__ = ["closed_loop_kernel"]


@functools.cache
def closed_loop_kernel():
    """The closed-loop kernel, compiled with numba (pure Python if numba is missing)."""
    try:
        import numba
    except ImportError:  # pragma: no cover - numba is a core dependency
        warnings.warn(
            "numba is not installed: hpdob.simulate runs its kernel as plain Python, "
            "about 50x slower; install numba to fix this",
            RuntimeWarning,
            stacklevel=3,
        )
        return run_closed_loop
    return numba.njit(cache=True, nogil=True)(run_closed_loop)
