"""Are identify's standard deviations honest? A Monte Carlo over seeds on SYNTHETIC logs.

Each seed draws a new log of the same kind (tests/synthetic_logs.py: a new PRBS or pulse
sequence where the kind has one, and new noise on the logged input), identified with the
default settings. The spread of the estimates over the seeds (sample standard deviation) is
compared with the mean reported standard deviation: the batch-means one that ``identify``
reports (``J_std``, ...) and the textbook one for a white residual (``std_iid``). A ratio
spread / std of 1 is honest; below 1 the std is pessimistic, above 1 optimistic. Run with

    python benchmarks/bench_identify_std.py             # 24 seeds per kind (about a minute)
    python benchmarks/bench_identify_std.py --seeds 8   # quicker, noisier

Only logs whose motion changes with the seed say anything here: on a chirp, a PD run or the
torque pulses the motion is the same for every seed, so the quantisation error, the largest
part of the residual, repeats, and the spread over seeds shows the input noise alone (a
repeated error is a bias, which no standard deviation describes).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from synthetic_logs import synthetic_log

CASES = {  # name: synthetic_log arguments (the seed varies)
    "prbs 1024 counts, 2 ms": {"kind": "prbs", "counts": 1024, "Ts": 2e-3, "coulomb_fraction": 0.1},
    "prbs 4096 counts, 0.5 ms": {
        "kind": "prbs",
        "counts": 4096,
        "Ts": 5e-4,
        "coulomb_fraction": 0.1,
    },
    "prbs 65536 counts, 1 ms": {
        "kind": "prbs",
        "counts": 65536,
        "Ts": 1e-3,
        "coulomb_fraction": 0.3,
    },
}
NAMES = ("J", "b", "coulomb")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=24)
    args = parser.parse_args()
    print(f"spread of the estimates over {args.seeds} seeds / mean reported std (1 = honest)")
    print(
        f"{'log':<28}| {'batch means: J':>14}{'b':>6}{'c':>6} | {'textbook: J':>11}{'b':>6}{'c':>6}"
    )
    worst = 1.0
    for name, case in CASES.items():
        estimates, std, iid = [], [], []
        for seed in range(args.seeds):
            s = synthetic_log(**case, seed=seed)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fit = s.log.identify(diagnostics=False)
            estimates.append([fit.parameters[n] for n in NAMES])
            std.append([fit.std[n] for n in NAMES])
            iid.append([fit.std_iid[n] for n in NAMES])
        spread = np.std(estimates, axis=0, ddof=1)
        ratio, ratio_iid = spread / np.mean(std, axis=0), spread / np.mean(iid, axis=0)
        worst = max(worst, *np.maximum(ratio, 1.0 / ratio))
        print(f"{name:<28}| {ratio[0]:>14.2f}{ratio[1]:>6.2f}{ratio[2]:>6.2f} | "
              f"{ratio_iid[0]:>11.2f}{ratio_iid[1]:>6.2f}{ratio_iid[2]:>6.2f}")  # fmt: skip
    print(f"batch means: worst factor between spread and std {worst:.2f}")


if __name__ == "__main__":
    main()
