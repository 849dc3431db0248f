"""The cases of ``bench_ab.py``, each checkout in processes of its own, alternating.

``bench_ab.py`` runs both checkouts in one process; on the loaded shared machine the
checkout imported as ``hpdob`` (from its own tree, its numba cache warm) ran faster than the
copy imported as ``hpdob_ref`` in both directions. Here each checkout runs as ``hpdob`` from
its own ``src`` in a fresh process, best of ``--repeat`` calls per process, the two checkouts'
processes alternating (which goes first alternating too); printed: the best over all
processes of each and the median of the per-pair ratios this/other. ``--clock cpu`` times
the process's CPU time instead of the wall time: what other processes take of the two cores
then counts far less (cache and memory contention still do).

    git worktree add /tmp/hpdob-pre20 93943a0
    python benchmarks/bench_ab_processes.py /tmp/hpdob-pre20 [--pairs 6] [CASE ...]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def _one(name: str, repeat: int, clock: str) -> None:
    """In the child: the best of ``repeat`` calls of case ``name`` [s], printed."""
    sys.path.insert(0, str(HERE))
    from bench_ab import case

    run, now = case("hpdob", name), CLOCKS[clock]
    best = float("inf")
    for _ in range(repeat):
        start = now()
        run()
        best = min(best, now() - start)
    print(best)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("other", type=Path, help="the other checkout (its src is used)")
    parser.add_argument("cases", nargs="*", default=["PD", "HPDOb-100", "sweep", "estimate"])
    parser.add_argument("--pairs", type=int, default=6, help="processes of each checkout")
    parser.add_argument("--repeat", type=int, default=30, help="calls per process (tune: 1)")
    parser.add_argument("--clock", choices=tuple(CLOCKS), default="wall",
                        help="wall time, or the process's CPU time (all its threads): less "
                        "sensitive to other processes on a loaded machine")  # fmt: skip
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _one(args.child[0], int(args.child[1]), args.clock)
        return
    sources = {"this": HERE.parent / "src", "other": args.other / "src"}
    print(f"{'case':<12}{'this [ms]':>11}{'other [ms]':>12}{'ratio':>8}{'median pair':>13}")
    for name in args.cases:
        repeat = 1 if name == "tune" else args.repeat
        best = {key: [] for key in sources}
        for i in range(args.pairs):
            for key in ("this", "other") if i % 2 == 0 else ("other", "this"):
                env = {**os.environ, "PYTHONPATH": str(sources[key])}
                done = subprocess.run(
                    [sys.executable, __file__, str(args.other), "--clock", args.clock, "--child",
                     name, str(repeat)],
                    env=env, capture_output=True, text=True, check=True,
                )  # fmt: skip
                best[key].append(float(done.stdout.split()[-1]))
        this, other = min(best["this"]), min(best["other"])
        pairs = statistics.median(a / b for a, b in zip(best["this"], best["other"], strict=True))
        print(f"{name:<12}{this * 1e3:>11.2f}{other * 1e3:>12.2f}{this / other:>8.3f}"
              f"{pairs:>13.3f}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
