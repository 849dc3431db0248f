"""One BLAS thread for code that solves many small matrix problems (``tune``)."""

from __future__ import annotations

from .._blas import one_blas_thread

__all__ = ["one_blas_thread"]
