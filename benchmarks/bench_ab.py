"""This checkout's hot paths against another checkout's, interleaved in one process.

The other checkout's ``src/hpdob`` is copied to a temporary directory as the package
``hpdob_ref`` (its modules import each other relatively), so both run side by side on the
same machine state: each case is timed alternately (which goes first alternating too), best
of N, and the ratio this/other printed. For changes that must not slow the hot paths
(issue 20: "no benchmark regresses by more than 5 %"); a busy machine scatters single
figures by +-10 % and more, the ratio of interleaved bests less. Cases (every one the same
call in both checkouts):

``PD``, ``HPDOb-100`` (any canonical run name)
    ``paper.run(name)``: the canonical 10 s run, 8 sub-steps per sample.
``sweep``
    ``sweep`` of 10 canonical scenarios (orders 0 and 1 x 5 bandwidths; 100 000 samples) on
    one worker.
``estimate``
    ``estimate_disturbance`` of the HPDOb-100 over a synthetic 10^6-sample log.
``tune``
    ``tune`` of the paper's motor over the position-only family (encoder 16384 counts/rev,
    J in [0.9, 1.1] J_n, a 1 s verification run): best of ``--tune-repeat``.

    git worktree add /tmp/hpdob-main main        # or any other checkout
    python benchmarks/bench_ab.py /tmp/hpdob-main [--repeat 40] [CASE ...]
"""

from __future__ import annotations

import argparse
import importlib
import shutil
import sys
import tempfile
import time
from pathlib import Path

CASES = ("PD", "HPDOb-100", "1s", "sweep", "sweep10", "estimate", "tune")


def case(package: str, name: str):
    """A zero-argument callable running case ``name`` with ``package`` (warmed once)."""
    hpdob = importlib.import_module(package)
    paper = importlib.import_module(package + ".paper")
    if name == "sweep":
        base = {**paper.scenario(), "duration": 1.0, "observer": {"order": 1, "bandwidth": 100.0}}
        grid = {"observer.order": [0, 1], "observer.bandwidth": [50.0, 100.0, 150.0, 200.0, 250.0]}

        def run():
            return hpdob.sweep(base, grid=grid, scheduler=1, progress=False)

    elif name == "sweep10":  # the canonical family of bench_sweep.py, 10 s, one thread
        import numpy as np

        base = {**paper.scenario(), "observer": {"order": 1, "bandwidth": 100.0}}
        grid = {"observer.order": [0, 1], "observer.bandwidth": list(np.linspace(40.0, 280.0, 5)),
                "plant.J": [2.5e-4, 3.06e-4, 3.5e-4, 4e-4]}  # fmt: skip

        def run():
            return hpdob.sweep(base, grid=grid, scheduler=1, progress=False)

    elif name == "1s":  # the canonical HPDOb-100 run over 1 s: the per-call overhead

        def run():
            return paper.run("HPDOb-100", duration=1.0)

    elif name == "estimate":
        import numpy as np

        rng = np.random.default_rng(0)  # a synthetic log: a random walk and white torques
        theta, u = np.cumsum(rng.normal(scale=1e-4, size=10**6)), rng.normal(size=10**6) * 1e-2
        design = hpdob.design_observer(paper.NOMINAL.discretize(paper.TS), order=1,
                                       bandwidth=100.0)  # fmt: skip

        def run():
            return hpdob.estimate_disturbance(design, theta=theta, u=u)

    elif name == "tune":
        settings = {"nominal": paper.NOMINAL, "Ts": paper.TS, "sensor": hpdob.Encoder(16384),
                    "J_range": (0.9, 1.1), "families": ["position"], "disturbance_frequency": 2.0,
                    "scenario": {"reference": paper.REFERENCE, "duration": 1.0}}  # fmt: skip

        def run():
            return hpdob.tune(**settings)

    else:

        def run():
            return paper.run(name)

    run()  # compile / load the cached kernels
    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("other", type=Path, help="the other checkout (its src/hpdob is used)")
    parser.add_argument("cases", nargs="*", default=["PD", "HPDOb-100"],
                        help=f"any of {', '.join(CASES)} or a canonical run name")  # fmt: skip
    parser.add_argument("--repeat", type=int, default=40)
    parser.add_argument("--tune-repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(args.other / "src" / "hpdob", Path(tmp) / "hpdob_ref")
        sys.path.insert(0, tmp)
        print(f"{'case':<12}{'this [ms]':>11}{'other [ms]':>12}{'ratio':>8}")
        for name in args.cases:
            runs = {"this": case("hpdob", name), "other": case("hpdob_ref", name)}
            best = dict.fromkeys(runs, float("inf"))
            for i in range(args.tune_repeat if name == "tune" else args.repeat):
                # alternate which goes first: the second of a pair finds the first's freed
                # memory and warm caches
                for key in ("this", "other") if i % 2 == 0 else ("other", "this"):
                    start = time.perf_counter()
                    runs[key]()
                    best[key] = min(best[key], time.perf_counter() - start)
            ratio = best["this"] / best["other"]
            print(f"{name:<12}{best['this'] * 1e3:>11.2f}{best['other'] * 1e3:>12.2f}{ratio:>8.3f}",
                  flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
