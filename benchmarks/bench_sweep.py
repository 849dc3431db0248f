"""Sweep throughput in simulated samples per second, at 1 and 2 local workers.

The canonical scenario family (10 s at 1 kHz, default sub-steps, Coulomb friction): orders
0 and 1 x 25 bandwidths x 4 true inertias = 200 scenarios, 2 million samples per sweep.
Target (issue 11): >= 3 million simulated samples per second on 2 workers (2-core machine).

    python benchmarks/bench_sweep.py
"""

from __future__ import annotations

import time

import numpy as np

from hpdob import paper, sweep

GRID = {
    "observer.order": [0, 1],
    "observer.bandwidth": list(np.linspace(40.0, 280.0, 25)),
    "plant.J": [2.5e-4, 3.06e-4, 3.5e-4, 4e-4],
}


def main() -> None:
    base = {**paper.scenario(), "observer": {"order": 1, "bandwidth": 100.0}}
    sweep(base, grid={"observer.order": [0, 1]}, progress=False)  # warm the kernel
    scenarios = 2 * 25 * 4
    print(f"{'workers':>7}  {'scenarios':>9}  {'time [s]':>8}  {'Msamples/s':>10}")
    for workers in (1, 2):
        best = np.inf
        for _ in range(3):
            start = time.perf_counter()
            rows = sweep(base, grid=GRID, scheduler=workers, progress=False)
            best = min(best, time.perf_counter() - start)
        assert len(rows) == scenarios and rows["stable"].all()
        print(
            f"{workers:>7}  {scenarios:>9}  {best:>8.2f}  {scenarios * 10_000 / best / 1e6:>10.2f}"
        )


if __name__ == "__main__":
    main()
