"""``hpdob identify``'s time and ``--emps``'s memory, this checkout against another.

Time: each checkout runs ``hpdob.cli.main(["identify", ...])`` as ``hpdob`` from its own
``src`` in fresh processes, the two checkouts' processes alternating (which goes first
alternating too); each process times its first call (the numba kernels loaded from their
disk cache, or compiled on a cold cache) and then the best of ``--repeat`` further calls.
Printed per case: the best over the processes of each checkout, their ratio this/other and
the median of the per-pair ratios. Cases:

``log48k``
    ``identify LOG --time t --position q --input u`` (the default method) of a synthetic
    48 000-sample Parquet log (a PD at 5 Hz around a rigid axis with Coulomb friction
    tracking three sines, 4096 counts, 1 % input noise; written once, read by both).
``emps``, ``emps-ls``, ``emps-iv``
    ``identify --emps`` by default, ``--method idim-ls``, ``--method idim-iv``.

Memory (``--memory``, this checkout alone, in one process): the tracemalloc peak of a second
``main(["identify", "--emps", "--no-plot", ...])`` after an untraced warm-up, after
``gc.collect()``, over the EMPS log's 24 841 x 4 x 8 bytes (docs/performance.md, "Memory of
the commands that read a log"), for each method.

    git worktree add --detach /tmp/hpdob-main main
    python benchmarks/bench_identify_ab.py /tmp/hpdob-main [--pairs 4] [--repeat 3] [CASE ...]
    python benchmarks/bench_identify_ab.py --memory
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import io
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ID = ["--time", "t", "--position", "q", "--input", "u"]
CASES = {
    "log48k": ["identify", "{log}", *ID],
    "emps": ["identify", "--emps"],
    "emps-ls": ["identify", "--emps", "--method", "idim-ls"],
    "emps-iv": ["identify", "--emps", "--method", "idim-iv"],
}
#: The EMPS log's copy [bytes]: 24 841 samples x 4 columns x 8 bytes.
EMPS_COPY = 24_841 * 4 * 8


def _write_log(path: Path, n: int = 48_000) -> None:
    """The synthetic closed-loop log of ``tests/cli/test_cli_memory.py`` (seed 0)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from hpdob.identification import FeedbackLoop, simulate_loop

    Ts, J, B, C = 1e-3, 1.2e-3, 2e-3, 0.03
    rng = np.random.default_rng(0)
    t = np.arange(n) * Ts
    r = (0.5 * np.sin(2 * np.pi * 0.3 * t) + 0.2 * np.sin(2 * np.pi * 1.7 * t + 1.0)
         + 0.05 * np.sin(2 * np.pi * 4.1 * t))  # fmt: skip
    w = 2 * np.pi * 5.0
    theta, u = simulate_loop(FeedbackLoop(r, kp=J * w * w, kd=J * 2 * w), (J, B, C, 0.0), Ts=Ts)
    q = 2 * np.pi / 4096
    columns = {"t": t, "q": np.round(theta / q) * q,
               "u": u + 0.01 * np.std(u) * rng.standard_normal(n), "r": r}  # fmt: skip
    pq.write_table(pa.table(columns), path)


def _call(words: list, out: str) -> None:
    from hpdob.cli import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main([*words, "--out", out, "--no-plot"])
    if code not in (0, 1):  # 1: an identification warning
        raise SystemExit(f"{' '.join(words)} exited with {code}")


def _child(words: list, repeat: int) -> None:
    """In the child: the first call's time and the best of ``repeat`` more [s], printed."""
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        _call(words, os.path.join(tmp, "first"))
        first = time.perf_counter() - start
        best = float("inf")
        for k in range(repeat):
            start = time.perf_counter()
            _call(words, os.path.join(tmp, str(k)))
            best = min(best, time.perf_counter() - start)
    print(first, best)


def _memory() -> None:
    import tracemalloc

    for name in ("emps", "emps-ls", "emps-iv"):
        with tempfile.TemporaryDirectory() as tmp:
            _call(CASES[name], os.path.join(tmp, "warm-up"))
            gc.collect()
            tracemalloc.start()
            try:
                base = tracemalloc.get_traced_memory()[0]
                _call(CASES[name], os.path.join(tmp, "traced"))
                peak = tracemalloc.get_traced_memory()[1] - base
            finally:
                tracemalloc.stop()
        print(f"{' '.join(CASES[name]):<36} peak {peak / EMPS_COPY:.3f} copies ({peak} bytes)",
              flush=True)  # fmt: skip


def main() -> None:
    if sys.argv[1:2] == ["--child"]:  # the child: --child REPEAT WORDS...
        _child(sys.argv[3:], int(sys.argv[2]))
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("other", type=Path, nargs="?", help="the other checkout (its src)")
    parser.add_argument("cases", nargs="*", default=list(CASES), help=", ".join(CASES))
    parser.add_argument("--pairs", type=int, default=4, help="processes of each checkout")
    parser.add_argument("--repeat", type=int, default=3, help="calls per process after the first")
    parser.add_argument("--memory", action="store_true", help="--emps's peaks, this checkout")
    args = parser.parse_args()
    if args.memory:
        _memory()
        return
    if args.other is None:
        parser.error("give the other checkout, or --memory")
    sources = {"this": HERE.parent / "src", "other": args.other / "src"}
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "log48k.parquet"
        _write_log(log)
        print(f"{'case':<10}{'this [ms]':>11}{'other [ms]':>12}{'ratio':>8}{'median pair':>13}"
              f"{'first: this':>13}{'other [ms]':>12}")  # fmt: skip
        for name in args.cases:
            words = [w.format(log=log) for w in CASES[name]]
            best = {key: [] for key in sources}
            first = {key: [] for key in sources}
            for i in range(args.pairs):
                for key in ("this", "other") if i % 2 == 0 else ("other", "this"):
                    env = {**os.environ, "PYTHONPATH": str(sources[key])}
                    done = subprocess.run(
                        [sys.executable, __file__, "--child", str(args.repeat), *words],
                        env=env, capture_output=True, text=True, check=True,
                    )  # fmt: skip
                    one, many = (float(v) for v in done.stdout.split()[-2:])
                    first[key].append(one)
                    best[key].append(many)
            this, other = min(best["this"]), min(best["other"])
            pairs = statistics.median(a / b for a, b in zip(best["this"], best["other"],
                                                            strict=True))  # fmt: skip
            print(f"{name:<10}{this * 1e3:>11.1f}{other * 1e3:>12.1f}{this / other:>8.3f}"
                  f"{pairs:>13.3f}{min(first['this']) * 1e3:>13.1f}"
                  f"{min(first['other']) * 1e3:>12.1f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
