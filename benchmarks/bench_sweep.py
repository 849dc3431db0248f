"""Sweep throughput in simulated samples per second, against a minimal hand-written kernel.

The canonical scenario family (1 kHz, default sub-steps, Coulomb friction): orders 0 and 1 x
25 bandwidths x 4 true inertias = 200 scenarios, of 10 s (2 million samples per sweep) and of
1 s. For each: ``hpdob.sweep`` on 1 and 2 local threads, and the minimal kernel
(``_minimal_kernel.py``: the same loop written out by hand in numba, its row computed inline,
its inputs prepared before the clock starts) over the same scenarios on 1 and 2 threads, its
rows first checked against hpdob's. Interleaved, best of ``--repeat``; printed: wall time,
Msamples/s, the CPU time per scenario (all threads; robust on a loaded machine) and the
ratios sweep / minimal kernel; then, on one thread, how much of a scenario's CPU time is the
compiled kernel (the GIL released) and how much holds the GIL (what bounds 2 threads).

Targets (issue 25): >= 6 M samples/s on 2 threads for the 10 s family and >= 90 % of the
minimal kernel's throughput. (Issue 11's: >= 3 M samples/s on 2 workers.)

    python benchmarks/bench_sweep.py [--repeat 3] [--durations 10 1]
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _minimal_kernel import check, minimal_row, scenario_inputs

from hpdob import paper, sweep
from hpdob.simulation import sample_signals
from hpdob.simulation._result import CANONICAL_WINDOWS
from hpdob.simulation._sweep import _resolve_base, scenario_loop
from hpdob.simulation._sweep_spec import expand_scenarios

GRID = {
    "observer.order": [0, 1],
    "observer.bandwidth": list(np.linspace(40.0, 280.0, 25)),
    "plant.J": [2.5e-4, 3.06e-4, 3.5e-4, 4e-4],
}


def minimal_inputs(base: dict) -> list:
    """The minimal kernel's arguments for every scenario of the grid (made before timing)."""
    resolved = _resolve_base(base)
    loop0 = resolved["loop"]
    S = loop0.plant.substeps(loop0.Ts, None)
    n = round(base["duration"] / loop0.Ts)
    signals = sample_signals(base["reference"], base["disturbance"], Ts=loop0.Ts, n=n, substeps=S)
    cache: dict = {}
    return [
        scenario_inputs(scenario_loop(resolved, params, cache), signals, CANONICAL_WINDOWS)
        for params in expand_scenarios(GRID, None, None, 0)
    ]


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


def kernel_share(base: dict, repeat: int) -> tuple[float, float] | None:
    """``(CPU per scenario, of it in the compiled kernel)`` [s] of the sweep on one thread:
    the rest holds the GIL, which caps what a second thread can add. None if the kernel's
    entry point is not ``hpdob.simulation._kernel.run_samples`` (it may have moved)."""
    from hpdob.simulation import _kernel

    inner = getattr(_kernel, "run_samples", None)
    if inner is None:
        return None
    spent = [0.0]

    def timed(*args, **kwargs):
        start = time.thread_time()
        try:
            return inner(*args, **kwargs)
        finally:
            spent[0] += time.thread_time() - start

    best = (np.inf, 0.0)
    _kernel.run_samples = timed
    try:
        for _ in range(repeat):
            spent[0] = 0.0
            _, cpu = timed_call(lambda: sweep(base, grid=GRID, scheduler=1, progress=False))
            best = min(best, (cpu, spent[0]))
    finally:
        _kernel.run_samples = inner
    scenarios = len(expand_scenarios(GRID, None, None, 0))
    return best[0] / scenarios, best[1] / scenarios


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
        share = kernel_share(base, args.repeat)
        if share is not None:
            cpu, kernel = share
            print(f"  one thread, per scenario: {cpu * 1e3:.3f} ms CPU, {kernel * 1e3:.3f} ms "
                  f"of it in the kernel (GIL released), {(cpu - kernel) * 1e3:.3f} ms holding "
                  "the GIL; "
                  f"2-thread bound {inputs[0][0] / max(cpu - kernel, cpu / 2) / 1e6:.2f} "
                  "M samples/s")  # fmt: skip
        for workers in (1, 2):
            ours, ref = best["hpdob.sweep", workers], best["minimal kernel", workers]
            print(
                f"  {workers} thread(s): sweep / minimal kernel throughput "
                f"{ref[0] / ours[0]:.2f} (wall), CPU per scenario {ours[1] / ref[1]:.2f}x"
            )


if __name__ == "__main__":
    main()
