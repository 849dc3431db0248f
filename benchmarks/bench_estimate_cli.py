"""Wall time and peak memory of ``hpdob estimate`` on a large Parquet log.

Writes a synthetic 1e7-sample log (time, position, input as float64 columns: a random walk and
random torques; synthetic, not measured) to a temporary directory, then runs
``hpdob estimate LOG --time t --position theta --input u --J-n 2.8e-4`` in a fresh process
(``python -m hpdob``) and reports its wall time and peak resident memory (``ru_maxrss`` of the
child), next to (a) ``estimate_disturbance`` alone on the same arrays in this process and (b)
a fresh process that only imports hpdob, numba, pyarrow and matplotlib (the fixed cost).
Target (issue 25): <= 8 s wall and <= 400 MB peak RSS for 1e7 samples.

    python benchmarks/bench_estimate_cli.py              # --samples N (default 1e7)
    python benchmarks/bench_estimate_cli.py --no-plot    # without the figure
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def child(command: list) -> tuple[float, float]:
    """Wall time [s] and peak RSS [MB] of a fresh process running ``command`` (``/usr/bin/time
    -v`` reports the child's maximum resident set size)."""
    start = time.perf_counter()
    done = subprocess.run(["/usr/bin/time", "-v", *command], check=True, capture_output=True,
                          text=True)  # fmt: skip
    wall = time.perf_counter() - start
    line = next(x for x in done.stderr.splitlines() if "Maximum resident set size" in x)
    return wall, int(line.split(":")[1]) / 1024


def main() -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, default=1e7)
    parser.add_argument("--no-plot", action="store_true")
    args = parser.parse_args()
    n = int(args.samples)
    rng = np.random.default_rng(25)
    t = np.arange(n) * 1e-3
    theta = np.cumsum(rng.standard_normal(n)) * 1e-4
    u = rng.standard_normal(n) * 0.01
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp, "log.parquet")
        pq.write_table(pa.table({"t": t, "theta": theta, "u": u}), log)
        fixed, fixed_rss = child(
            [sys.executable, "-c", "import hpdob, numba, pyarrow, matplotlib.pyplot"]
        )

        def command(out):
            options = ["--no-plot"] if args.no_plot else []
            return [sys.executable, "-m", "hpdob", "estimate", str(log), "--time", "t",
                    "--position", "theta", "--input", "u", "--J-n", "2.8e-4",
                    "--out", str(Path(tmp, out)), *options]  # fmt: skip

        child(command("warm"))  # numba's caches
        wall, rss = child(command("out"))
        size = Path(tmp, "out", "estimate.csv").stat().st_size
    from hpdob import ServoModel, design_observer, estimate_disturbance

    design = design_observer(ServoModel(2.8e-4).discretize(1e-3), order=1, bandwidth=100.0)
    estimate_disturbance(design, theta=theta[:100], u=u[:100])
    start = time.perf_counter()
    estimate_disturbance(design, theta=theta, u=u, t=t)
    api = time.perf_counter() - start
    print(f"{n:.3g} samples (synthetic Parquet log), estimate.csv {size / 1e6:.0f} MB")
    print(f"hpdob estimate{' --no-plot' if args.no_plot else ''}: {wall:.2f} s wall, "
          f"peak RSS {rss:.0f} MB (targets <= 8 s, <= 400 MB)")  # fmt: skip
    print(f"  (a) estimate_disturbance alone: {api:.3f} s; (b) a process importing hpdob, "
          f"numba, pyarrow, matplotlib: {fixed:.2f} s, {fixed_rss:.0f} MB")  # fmt: skip
    print(f"  ratio hpdob estimate / (a): {wall / api:.0f}")


if __name__ == "__main__":
    main()
