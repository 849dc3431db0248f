"""Cost of identifying the EMPS measured run (24 841 samples at 1 kHz): IDIM-LS, IDIM-IV, defaults.

Run with

    python benchmarks/bench_identify.py

and copy the figures into docs/real-data.md. Each is the best of 7 calls after one warm-up call
(which imports scipy.signal and compiles the loop simulation with numba, or loads it from the
cache); the loop simulation alone is timed too.
"""

from __future__ import annotations

import platform
import time
import timeit

import numpy as np

from hpdob.identification import emps, emps_loop, identify, simulate_loop


def main() -> None:
    print(f"Python {platform.python_version()} on {platform.machine()}, numpy {np.__version__}")
    log = emps()
    loop = emps_loop(log)
    start = time.perf_counter()
    iv = identify(log, method="idim-iv", loop=loop, diagnostics=False)
    print(f"first IDIM-IV call (imports, numba compile or cache load): "
          f"{time.perf_counter() - start:.2f} s")  # fmt: skip
    auto = identify(log)
    cases = {
        "IDIM-LS": lambda: identify(log, method="idim-ls", diagnostics=False),
        f"IDIM-IV ({iv.iterations} iterations)": lambda: identify(
            log, method="idim-iv", loop=loop, diagnostics=False
        ),
        f"defaults, no diagnostics ({auto.iterations} it.)": lambda: identify(
            log, diagnostics=False
        ),
        "defaults (with diagnostics)": lambda: identify(log),
        "defaults with the EMPS loop": lambda: identify(log, loop=loop),
        "one loop simulation": lambda: simulate_loop(
            loop, (95.1, 203.5, 20.4, -3.16), Ts=log.Ts, theta0=log.theta[0]
        ),
    }
    for name, call in cases.items():
        best = min(timeit.repeat(call, number=1, repeat=7))
        print(f"{name:<36}{1e3 * best:8.2f} ms")


if __name__ == "__main__":
    main()
