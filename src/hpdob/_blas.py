"""One BLAS thread for code that solves many small matrix problems (``tune``, the
describing-function scan of :func:`hpdob.analysis.contact_limit_cycle`)."""

from __future__ import annotations

import functools

__all__ = ["one_blas_thread"]


def one_blas_thread(function):
    """Run ``function`` with one BLAS thread where threadpoolctl is installed.

    ``tune`` solves thousands of matrix problems of size 2-12 (eigenvalues, Riccati equations);
    BLAS threads give them nothing, and on a loaded machine their spin-waiting starved the
    calling thread (measured: 19-30 s with OpenBLAS's default 2 threads against 4.6-6 s with
    one, the same table bit for bit, on the shared 2-core machine of 2026-12-01; a 4 x 4
    ``scipy.linalg.expm``: 6 ms against 0.01 ms of CPU at a load of 5, 2026-12-02).
    """

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        try:
            from threadpoolctl import threadpool_limits
        except ImportError:  # pragma: no cover - an optional speed-up
            return function(*args, **kwargs)
        with threadpool_limits(1, user_api="blas"):
            return function(*args, **kwargs)

    return wrapper
