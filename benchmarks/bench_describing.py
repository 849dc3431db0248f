"""``contact_limit_cycle`` against the code before its speed-up, bit for bit.

The describing-function scan runs thousands of fixed-point iterations per loop, each a DF
per nonlinearity, the quasi-linear loop's matrices and an eigenvalue problem. This times it
on three fixed loops of the paper's motor in contact (the force loop of
``tests/analysis/test_contact_limit_cycle.py``: ForceControl(1000, kv=40), the RTOB with the
plant's friction model and a 100 rad/s velocity filter, the virtual encoder and actuator,
tau_ref = 0.05 N m):

- ``hpdob``: the HPDOb at k_e = 10 N m/rad, g = 100 rad/s (the docstrings' loop);
- ``dob``: the DOb at k_e = 12.6 N m/rad, g = 155.9 rad/s (a point of the DF grid of
  ``examples/force_contact_verdict.py``; the RTOB term's noisy DF mostly on its erf branch);
- ``deadband``: the HPDOb at k_e = 3.17 N m/rad, g = 607.8 rad/s with the RTOB term's
  dead band of 0.02 rad/s (its noisy dead-band DF),

each with ``levels`` amplitudes (default 16), the min of ``--repeats`` runs (default 3) of the
current code and of the reference: the module ``hpdob.analysis._describing`` (and
``_linear_loop``) as they are at ``--reference`` (a git revision, default ``b3e2765``: the
code before the speed-up), loaded from ``git show`` under another name. Every field of the
results (verdict, amplitude, frequency, levels, radius, frequencies, converged,
limit_cycles) is compared exactly (NaN equal to NaN).

    python benchmarks/bench_describing.py [--repeats 3] [--levels 16] [--reference REV]
    python benchmarks/bench_describing.py --split   # the current code's time per step
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import pathlib
import subprocess
import sys
import time

import numpy as np

from hpdob import Environment, ServoLoop, paper
from hpdob.analysis import contact_limit_cycle, contact_stability_map
from hpdob.controllers import ForceControl
from hpdob.observers import design_observer, reaction_torque_observer

ROOT = pathlib.Path(__file__).resolve().parent.parent
TAU_REF = 0.05
FRICTION = {"friction": paper.PLANT, "velocity_filter": 100.0}
LOOPS = {
    "hpdob": (1, 10.0, 100.0, 0.0),
    "dob": (0, 12.6191, 155.94, 0.0),
    "deadband": (1, 3.17, 607.8, 0.02),
}


def point(order: int, k_e: float, g: float, deadband: float) -> ServoLoop:
    """The contact map's loop at (k_e, g) with the observer of ``order``."""
    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=order, bandwidth=g)
    loop = ServoLoop(plant=paper.PLANT.replace(environment=Environment(k_e)),
                     nominal=paper.NOMINAL, Ts=paper.TS,
                     controller=ForceControl(1000.0, kv=40.0),
                     observer=reaction_torque_observer(dob, **FRICTION),
                     sensor=paper.VIRTUAL_SENSOR, actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip
    cmap = contact_stability_map(loop, stiffness=[k_e], bandwidth=[g], observer={"order": order},
                                 coulomb_deadband=deadband, **FRICTION)  # fmt: skip
    return cmap.loop_at(k_e, g)


def reference(revision: str):
    """``contact_limit_cycle`` of ``revision``: its ``_describing`` module (with its own
    ``_linear_loop``) loaded from git as ``hpdob.analysis._describing_reference``."""
    modules = {}
    for name in ("_linear_loop", "_describing"):
        source = subprocess.run(
            ["git", "show", f"{revision}:src/hpdob/analysis/{name}.py"],
            cwd=ROOT, check=True, capture_output=True, text=True,
        ).stdout  # fmt: skip
        full = f"hpdob.analysis.{name}_reference"
        spec = importlib.util.spec_from_loader(full, loader=None)
        module = importlib.util.module_from_spec(spec)
        module.__package__ = "hpdob.analysis"
        if name == "_describing":  # the reference's own loop assembly
            source = source.replace(
                "from ._linear_loop import", "from ._linear_loop_reference import"
            )
        sys.modules[full] = module
        exec(compile(source, f"{revision}:{name}.py", "exec"), module.__dict__)
        modules[name] = module
    return modules["_describing"].contact_limit_cycle


def fields(cycle) -> tuple:
    return (cycle.verdict, cycle.amplitude, cycle.frequency, cycle.tau_ref, cycle.levels,
            cycle.radius, cycle.frequencies, cycle.converged, cycle.limit_cycles,
            cycle.nonlinearities)  # fmt: skip


def same(a, b) -> bool:
    """Exactly equal, NaN equal to NaN, arrays of the same dtype and shape."""
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    if isinstance(a, float):
        return (math.isnan(a) and math.isnan(b)) or a == b
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


def best(function, loop, levels: int, repeats: int):
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function(loop, tau_ref=TAU_REF, levels=levels)
        times.append(time.perf_counter() - start)
    return min(times), result


def split(loop, levels: int) -> dict:
    """Seconds of one run of the current code spent in each step of the fixed-point
    iterations (wall-clock wrappers around the private steps; the DFs are their cores, as
    the harmonic balance calls them)."""
    module = importlib.import_module("hpdob.analysis._describing")  # its internals: timed
    spent = {}

    def timed(name, function):
        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                spent[name] = spent.get(name, 0.0) + time.perf_counter() - start

        return wrapper

    steps = {"tanh DF": "_tanh_df", "quantiser DF": "_quantiser_df",
             "saturation DF": "_saturation_df", "loop matrices": "loop_matrices",
             "viscous reaction": "_with_viscous_reaction"}  # fmt: skip
    saved = {attr: getattr(module, attr) for attr in steps.values()}
    eig = np.linalg.eig
    try:
        for name, attr in steps.items():
            setattr(module, attr, timed(name, saved[attr]))
        np.linalg.eig = timed("eig", eig)
        start = time.perf_counter()
        contact_limit_cycle(loop, tau_ref=TAU_REF, levels=levels)
        spent["total"] = time.perf_counter() - start
    finally:
        for attr, function in saved.items():
            setattr(module, attr, function)
        np.linalg.eig = eig
    return spent


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--levels", type=int, default=16)
    parser.add_argument("--reference", default="b3e2765")
    parser.add_argument("--split", action="store_true",
                        help="only the current code's time per step, one run per loop")  # fmt: skip
    args = parser.parse_args(argv)
    if args.split:
        for name, where in LOOPS.items():
            spent = split(point(*where), args.levels)
            total = spent.pop("total")
            parts = ", ".join(f"{k} {v:.2f}" for k, v in spent.items())
            print(f"{name:10s} total {total:.2f} s: {parts}, the rest "
                  f"{total - sum(spent.values()):.2f}")  # fmt: skip
        return 0
    old = reference(args.reference)
    print(f"levels {args.levels}, min of {args.repeats}; reference {args.reference}")
    print(f"{'loop':10s} {'new [s]':>9s} {'old [s]':>9s} {'old/new':>8s}  bit for bit")
    identical = True
    for name, where in LOOPS.items():
        loop = point(*where)
        new_time, new = best(contact_limit_cycle, loop, args.levels, args.repeats)
        old_time, ref = best(old, loop, args.levels, args.repeats)
        equal = same(fields(new), fields(ref))
        identical &= equal
        print(f"{name:10s} {new_time:9.3f} {old_time:9.3f} {old_time / new_time:8.2f}  {equal}"
              f"  ({new.verdict})")  # fmt: skip
    return 0 if identical else 1


if __name__ == "__main__":
    raise SystemExit(main())
