"""Test and benchmark helpers (not needed to use hpdob; documented for reuse).

These compile exported C with the system's C compiler, run it under the sanitizers, bound
the rounding error of a ``float`` build, and build fixed-point exports for a Cortex-M with
``zig cc`` and run them on the ``unicorn`` emulator. hpdob's own test suite and benchmarks use
them; nothing in the library does.

CObserver, compile_c, find_compiler, STRICT_FLAGS, CBuildError
    Build an exported observer into a shared library and drive it from Python (ctypes).
sanitized_run, sanitizer_available, SANITIZE_FLAGS
    Run an exported observer over a trace under AddressSanitizer and UBSan.
export_error_bound, error_amplification
    First-order bound of the error of a ``float`` build against ``double`` (docs/deployment.md).
HostFixedObserver, EmulatedCortexM, cross_compile, zig_cc, fixed_drive_source, float_step_source
    A fixed-point export on the host and on an emulated Cortex-M0+/M3 (docs/deployment.md).
read_elf, ElfFile, ElfSymbol
    A minimal ELF32 reader (symbols, sections, segments) for the objects zig writes.
"""

from ._c_harness import STRICT_FLAGS, CBuildError, CObserver, compile_c, find_compiler
from ._elf import ElfFile, ElfSymbol, read_elf
from ._rounding import error_amplification, export_error_bound
from ._sanitize import SANITIZE_FLAGS, sanitized_run, sanitizer_available
from ._target import (
    CPUS,
    EmulatedCortexM,
    HostFixedObserver,
    cross_compile,
    fixed_drive_source,
    float_step_source,
    zig_cc,
)

__all__ = [
    "CPUS",
    "SANITIZE_FLAGS",
    "STRICT_FLAGS",
    "CBuildError",
    "CObserver",
    "ElfFile",
    "ElfSymbol",
    "EmulatedCortexM",
    "HostFixedObserver",
    "compile_c",
    "cross_compile",
    "error_amplification",
    "export_error_bound",
    "find_compiler",
    "fixed_drive_source",
    "float_step_source",
    "read_elf",
    "sanitized_run",
    "sanitizer_available",
    "zig_cc",
]
