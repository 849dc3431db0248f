"""Sweep throughput in simulated samples per second, against a minimal hand-written kernel.

The canonical scenario family (1 kHz, default sub-steps, Coulomb friction): orders 0 and 1 x
25 bandwidths x 4 true inertias = 200 scenarios, of 10 s (2 million samples per sweep) and of
1 s. For each: ``hpdob.sweep`` on 1 and 2 local threads, and the minimal kernel
(``_minimal_kernel.py``: the same loop written out by hand in numba, its row computed inline,
its inputs prepared before the clock starts) over the same scenarios on 1 and 2 threads, its
rows first checked against hpdob's. Interleaved, best of ``--repeat``; printed: wall time,
Msamples/s, the CPU time per scenario (all threads; robust on a loaded machine) and the
ratios sweep / minimal kernel.

Targets (issue 25): >= 6 M samples/s on 2 threads for the 10 s family and >= 90 % of the
minimal kernel's throughput. (Issue 11's: >= 3 M samples/s on 2 workers.)

    python benchmarks/bench_sweep.py [--repeat 3] [--durations 10 1]
"""

from __future__ import annotations

import argparse
import functools
import itertools
import math
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _minimal_kernel import check, minimal_row, sampled, scenario_inputs

from hpdob import ServoLoop, design_observer, paper, sweep

GRID = {
    "observer.order": [0, 1],
    "observer.bandwidth": list(np.linspace(40.0, 280.0, 25)),
    "plant.J": [2.5e-4, 3.06e-4, 3.5e-4, 4e-4],
}


#: The canonical windows of the position metrics [s] (``SimulationResult.metrics``' defaults).
WINDOWS = {"regulation": (1.2, 4.0), "tracking": (4.0, math.inf)}


def minimal_inputs(base: dict) -> list:
    """The minimal kernel's arguments for every scenario of the grid, in the sweep's order
    (the grid's Cartesian product in its key order), made before timing."""
    Ts, nominal = base["Ts"], base["nominal"]
    S = base["plant"].substeps(Ts, None)
    signals = sampled(base["reference"], base["disturbance"], Ts=Ts,
                      n=round(base["duration"] / Ts), S=S)  # fmt: skip
    inputs = []
    for order, bandwidth, J in itertools.product(*GRID.values()):
        design = design_observer(nominal.discretize(Ts), order=order, bandwidth=bandwidth)
        loop = ServoLoop(plant=base["plant"].replace(J=J), nominal=nominal, Ts=Ts,
                         controller=base["controller"], observer=design)  # fmt: skip
        inputs.append(scenario_inputs(loop, signals, WINDOWS))
    return inputs


def run_minimal(inputs: list, workers: int) -> list:
    if workers == 1:
        return [minimal_row(*args) for args in inputs]
    with ThreadPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(lambda args: minimal_row(*args), inputs, chunksize=8))


def timed_call(function) -> tuple[float, float]:
    """``(wall, CPU of the process)`` of ``function()`` [s]."""
    wall, cpu = time.perf_counter(), time.process_time()
    function()
    return time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--durations", type=float, nargs="+", default=[10.0, 1.0])
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}, {os.cpu_count()} cores")
    header = (f"{'duration':>8}  {'run':>14}  {'threads':>7}  {'wall [s]':>8}  "
              f"{'Msamples/s':>10}  {'CPU/scenario [ms]':>17}")  # fmt: skip
    for duration in args.durations:
        base = {**paper.scenario(), "duration": duration,
                "observer": {"order": 1, "bandwidth": 100.0}}  # fmt: skip
        inputs = minimal_inputs(base)
        rows = sweep(base, grid=GRID, progress=False)  # warm the kernels, check the reference
        assert len(rows) == len(inputs) and rows["stable"].all()
        order = list(zip(*(rows[path] for path in GRID), strict=True))
        assert order == list(itertools.product(*GRID.values()))  # the inputs' order
        worst = check(rows, inputs)
        samples = len(inputs) * inputs[0][0]
        cases = {}
        for workers in (1, 2):
            cases["hpdob.sweep", workers] = functools.partial(
                sweep, base, grid=GRID, scheduler=workers, progress=False
            )
            cases["minimal kernel", workers] = functools.partial(run_minimal, inputs, workers)
        best = dict.fromkeys(cases, (np.inf, np.inf))
        for _ in range(args.repeat):  # interleaved
            for key, call in cases.items():
                wall, cpu = timed_call(call)
                best[key] = (min(best[key][0], wall), min(best[key][1], cpu))
        print(f"\n{duration:g} s scenarios ({len(inputs)}, {samples / 1e6:g} M samples; minimal "
              f"kernel's rows within {worst:.1e} of hpdob's)")  # fmt: skip
        print(header)
        for (name, workers), (wall, cpu) in best.items():
            print(f"{duration:>8g}  {name:>14}  {workers:>7}  {wall:>8.3f}  "
                  f"{samples / wall / 1e6:>10.2f}  {cpu / len(inputs) * 1e3:>17.3f}")  # fmt: skip
        for workers in (1, 2):
            ours, ref = best["hpdob.sweep", workers], best["minimal kernel", workers]
            print(
                f"  {workers} thread(s): sweep / minimal kernel throughput "
                f"{ref[0] / ours[0]:.2f} (wall), CPU per scenario {ours[1] / ref[1]:.2f}x"
            )


if __name__ == "__main__":
    main()
