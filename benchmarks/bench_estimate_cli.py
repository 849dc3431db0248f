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
    python benchmarks/bench_estimate_cli.py --other ../main   # and another checkout's command,
                                                              # interleaved (ratio this/other)
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def child(command: list, source: str | None = None) -> tuple[float, float]:
    """Wall time [s] and peak RSS [MB] of a fresh process running ``command`` (``/usr/bin/time
    -v`` reports the child's maximum resident set size), with ``source`` (a checkout's ``src``)
    first on its path if given."""
    env = dict(os.environ, PYTHONPATH=source) if source else None
    start = time.perf_counter()
    done = subprocess.run(["/usr/bin/time", "-v", *command], check=True, capture_output=True,
                          text=True, env=env)  # fmt: skip
    wall = time.perf_counter() - start

    def field(name):
        return float(next(x for x in done.stderr.splitlines() if name in x).split(": ")[1])

    CPU.append(field("User time (seconds)") + field("System time (seconds)"))
    return wall, field("Maximum resident set size") / 1024


#: CPU seconds (user + system) of each child, in order: less sensitive to a busy machine's load
#: than the wall time.
CPU: list = []


def main() -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, default=1e7)
    parser.add_argument("--no-plot", action="store_true")
    parser.add_argument("--other", metavar="CHECKOUT", help="also time this checkout's command")
    parser.add_argument("--repeats", type=int, default=1, help="best of N (interleaved)")
    args = parser.parse_args()
    here = str(Path(__file__).resolve().parents[1] / "src")
    other = str(Path(args.other).resolve() / "src") if args.other else None
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

        child(command("warm"), here)  # numba's caches
        if other:
            child(command("warm-other"), other)
        runs, others, cpu, other_cpu = [], [], [], []
        for _ in range(args.repeats):  # interleaved: both see the same load
            runs.append(child(command("out"), here))
            cpu.append(CPU[-1])
            if other:
                others.append(child(command("out-other"), other))
                other_cpu.append(CPU[-1])
        wall, rss = min(w for w, _ in runs), max(r for _, r in runs)
        size = Path(tmp, "out", "estimate.csv").stat().st_size
        if other:
            same = Path(tmp, "out", "estimate.csv").read_bytes() == Path(
                tmp, "out-other", "estimate.csv").read_bytes()  # fmt: skip
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
    print(f"  CPU time (user + system) {min(cpu):.2f} s; ratio hpdob estimate / (a): "
          f"{wall / api:.0f}; load average {os.getloadavg()[0]:.1f}")  # fmt: skip
    if other:
        other_wall, other_rss = min(w for w, _ in others), max(r for _, r in others)
        print(f"  {args.other}: {other_wall:.2f} s wall, peak RSS {other_rss:.0f} MB; ratio "
              f"this/other {wall / other_wall:.2f} wall, {min(cpu) / min(other_cpu):.2f} CPU, "
              f"{rss / other_rss:.2f} RSS; "
              f"estimate.csv {'identical' if same else 'DIFFERENT'}")  # fmt: skip


if __name__ == "__main__":
    main()
