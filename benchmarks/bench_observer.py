"""Per-sample cost of ``estimate`` + ``update`` of the runtime observer in plain CPython.

Target (issue: core synthesis): <= 5 us per sample for order <= 2. Run with

    python benchmarks/bench_observer.py

and copy the table into docs/performance.md. Each figure is the best of 7 repeats of 20 000
samples (the minimum is the least disturbed by other load on the machine).
"""

from __future__ import annotations

import platform
import timeit

import numpy as np

from hpdob import DisturbanceObserver, ServoModel


def per_sample_us(order: int, x) -> float:
    model = ServoModel(J=2.8e-4).discretize(1e-3)
    obs = DisturbanceObserver(model, order=order, bandwidth=100.0)
    u_pd = 0.01

    def one_sample():
        tau_hat = obs.estimate(x)
        obs.update(x, u_pd + tau_hat)

    n = 20_000
    best = min(timeit.repeat(one_sample, number=n, repeat=7))
    return best / n * 1e6


def main() -> None:
    print(f"Python {platform.python_version()} on {platform.machine()}, numpy {np.__version__}")
    print(f"{'order':>5}  {'x as tuple [us]':>16}  {'x as ndarray [us]':>18}")
    for order in range(5):
        as_tuple = per_sample_us(order, (0.1, 0.2))
        as_array = per_sample_us(order, np.array([0.1, 0.2]))
        print(f"{order:>5}  {as_tuple:>16.2f}  {as_array:>18.2f}")


if __name__ == "__main__":
    main()
