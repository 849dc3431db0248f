"""``tune()`` and a warm ``hpdob reproduce``: this checkout against another, in one run (issue 25).

Each case runs in fresh processes, this checkout's and the other's alternating; a process
makes one warm-up call and then times ``--repeats`` calls by CPU time (``time.process_time``,
all threads: what the other users of a loaded machine disturb least) and by wall time. Prints
the best of each and the ratio this/other. Targets (issue 25): ``tune()`` <= 1.5 s for the
paper's motor with the same recommendation, ``hpdob reproduce`` warm <= 4 s.

    python benchmarks/bench_wait.py ../main --processes 3 --repeats 2
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent

CHILD = r"""
import json, sys, tempfile, time
sys.path.insert(0, {bench!r})
case, repeats = sys.argv[1], int(sys.argv[2])
if case == "tune":
    from bench_tune import SETTINGS
    from hpdob import tune
    def call():
        return tune(**SETTINGS).report()
else:
    from hpdob import paper
    out = tempfile.mkdtemp()
    def call():
        paper.reproduce(out)
        return open(out + "/metrics.json").read()
first = call()
cpu, wall = [], []
for _ in range(repeats):
    c, w = time.process_time(), time.perf_counter()
    assert call() == first
    cpu.append(time.process_time() - c)
    wall.append(time.perf_counter() - w)
print(json.dumps({{"cpu": min(cpu), "wall": min(wall), "output": first}}))
"""


def run(checkout: Path, case: str, repeats: int) -> dict:
    env = {**os.environ, "PYTHONPATH": str(checkout / "src"), "OPENBLAS_NUM_THREADS": "1"}
    code = CHILD.format(bench=str(HERE / "benchmarks"))
    done = subprocess.run([sys.executable, "-c", code, case, str(repeats)], env=env,
                          check=True, capture_output=True, text=True)  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("other", type=Path, help="the other checkout (e.g. ../main)")
    parser.add_argument("--cases", nargs="+", default=["tune", "reproduce"])
    parser.add_argument("--processes", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args(argv)
    summary = {}
    for case in args.cases:
        this, other = [], []
        for _ in range(args.processes):
            this.append(run(HERE, case, args.repeats))
            other.append(run(args.other.resolve(), case, args.repeats))
        same = this[0]["output"] == other[0]["output"]
        best = {clock: (min(r[clock] for r in this), min(r[clock] for r in other))
                for clock in ("cpu", "wall")}  # fmt: skip
        summary[case] = {**best, "same_output": same}
        for clock, (a, b) in best.items():
            print(f"{case:9s} {clock:4s}: this {a:6.2f} s, other {b:6.2f} s, ratio {a / b:.2f}")
        what = "report" if case == "tune" else "metrics.json"
        print(f"{case:9s} same {what} as the other checkout: {same}")
    return summary


if __name__ == "__main__":
    main()
