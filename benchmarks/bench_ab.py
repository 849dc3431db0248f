"""This checkout's closed-loop run against another checkout's, interleaved in one process.

The other checkout's ``src/hpdob`` is copied to a temporary directory as the package
``hpdob_ref`` (its modules import each other relatively), so both run side by side on the
same machine state: each canonical run is timed alternately, best of N, and the ratio printed.
For changes to the sample kernel (e.g. the controller protocol, issue 20: "no regression
> 5 %"); a busy machine scatters single figures by ±10 %, the ratio of interleaved bests
less.

    git worktree add /tmp/hpdob-main main        # or any other checkout
    python benchmarks/bench_ab.py /tmp/hpdob-main [--repeat 60] [RUN ...]
"""

from __future__ import annotations

import argparse
import importlib
import shutil
import sys
import tempfile
import time
from pathlib import Path


def timer(package, name: str):
    paper = importlib.import_module(package + ".paper")
    paper.run(name)  # compile / load the cached kernel
    return lambda: paper.run(name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("other", type=Path, help="the other checkout (its src/hpdob is used)")
    parser.add_argument("runs", nargs="*", default=["PD", "HPDOb-100"])
    parser.add_argument("--repeat", type=int, default=40)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(args.other / "src" / "hpdob", Path(tmp) / "hpdob_ref")
        sys.path.insert(0, tmp)
        print(f"{'run':<12}{'this [ms]':>11}{'other [ms]':>12}{'ratio':>8}")
        for name in args.runs:
            runs = {"this": timer("hpdob", name), "other": timer("hpdob_ref", name)}
            best = dict.fromkeys(runs, float("inf"))
            for _ in range(args.repeat):
                for key, run in runs.items():
                    start = time.perf_counter()
                    run()
                    best[key] = min(best[key], time.perf_counter() - start)
            ratio = best["this"] / best["other"]
            print(f"{name:<12}{best['this'] * 1e3:>11.2f}{best['other'] * 1e3:>12.2f}{ratio:>8.3f}")


if __name__ == "__main__":
    main()
