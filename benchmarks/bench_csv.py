"""The column-wise CSV writer behind every ``to_csv`` of a trace, against the csv module.

Runs ``estimate_disturbance`` over a synthetic log (a random walk and random torques;
synthetic), then writes its five columns (t, theta, omega, u, tau_hat) two ways in one process,
best of N interleaved repeats: (a) ``EstimationResult.to_csv`` (the compiled writer: Ryu's
shortest digits in numba, ``repr``'s layout, two threads) and (b) the csv module with ``repr``,
row by row (the reference, on a tenth of the rows). The bytes of the two files are compared.

    python benchmarks/bench_csv.py            # --rows N (default 1e6), --repeats N (default 5)
"""

from __future__ import annotations

import argparse
import csv
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from hpdob import ServoModel, design_observer, estimate_disturbance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=float, default=1e6)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    n = int(args.rows)
    rng = np.random.default_rng(25)
    design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    theta, u = np.cumsum(rng.standard_normal(n)) * 1e-4, rng.standard_normal(n) * 0.01
    whole = estimate_disturbance(design, theta=theta, u=u)
    part = estimate_disturbance(design, theta=theta[: n // 10], u=u[: n // 10])

    def csv_module(result, path):
        columns = [result.t, result.theta, result.omega, result.u, result.tau_hat]
        with open(path, "w", newline="", encoding="utf-8") as f:
            writer = csv.writer(f)
            writer.writerow(["t", "theta", "omega", "u", "tau_hat"])
            writer.writerows([repr(float(v)) for v in row] for row in zip(*columns, strict=True))

    with tempfile.TemporaryDirectory() as tmp:
        a, b = Path(tmp, "a.csv"), Path(tmp, "b.csv")
        part.to_csv(a)
        csv_module(part, b)
        assert a.read_bytes() == b.read_bytes(), "the compiled writer's bytes differ"
        compiled, reference = [], []
        for _ in range(args.repeats):  # interleaved: both see the same load
            start = time.perf_counter()
            whole.to_csv(a)
            compiled.append((time.perf_counter() - start) / (5 * n))
            start = time.perf_counter()
            csv_module(part, b)
            reference.append((time.perf_counter() - start) / (5 * (n // 10)))
    fast, slow = min(compiled) * 1e9, min(reference) * 1e9
    print(f"{n:.3g} rows x 5 columns, best of {args.repeats}, load {os.getloadavg()[0]:.1f}")
    print(f"  (a) EstimationResult.to_csv:  {fast:.0f} ns per value")
    print(f"  (b) csv module + repr:        {slow:.0f} ns per value; (a)/(b) = {fast / slow:.3f}")


if __name__ == "__main__":
    main()
