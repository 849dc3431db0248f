"""Test and benchmark helpers (not needed to use hpdob; documented for reuse).

These compile exported C with the system's C compiler, run it under the sanitizers and bound
the rounding error of a ``float`` build. hpdob's own test suite and benchmarks use them;
nothing in the library does.

CObserver, compile_c, find_compiler, STRICT_FLAGS, CBuildError
    Build an exported observer into a shared library and drive it from Python (ctypes).
sanitized_run, sanitizer_available, SANITIZE_FLAGS
    Run an exported observer over a trace under AddressSanitizer and UBSan.
export_error_bound, error_amplification
    First-order bound of the error of a ``float`` build against ``double`` (docs/deployment.md).
"""

from ._c_harness import STRICT_FLAGS, CBuildError, CObserver, compile_c, find_compiler
from ._rounding import error_amplification, export_error_bound
from ._sanitize import SANITIZE_FLAGS, sanitized_run, sanitizer_available

__all__ = [
    "SANITIZE_FLAGS",
    "STRICT_FLAGS",
    "CBuildError",
    "CObserver",
    "compile_c",
    "error_amplification",
    "export_error_bound",
    "find_compiler",
    "sanitized_run",
    "sanitizer_available",
]
