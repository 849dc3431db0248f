"""Speed of offline estimation (``estimate_disturbance``) against a minimal hand-written kernel.

(a) ``hpdob.estimate_disturbance`` on a synthetic 1e7-sample log (random-walk position, random
input; synthetic, not measured) for every family at orders 0-2, the whole call: checks, the
compiled loop, the result's arrays. Two ways a log reaches it: writable ``theta`` and ``u``
(copied on a second thread while the loop runs; no ``t``) and read-only ``theta``, ``u``
and ``t`` (a ``Log``'s columns, as ``hpdob estimate`` passes them: shared, not copied). The
time ``k Ts`` and a differenced velocity are derived when the result's field is first read,
not by the call; the estimate (and ``omega_hat``) are written;
(b) a minimal hand-written numba kernel for the canonical order-1 DOb: the same arithmetic in
the same order (the velocity by backward difference, the estimate, the update), the
coefficients as arguments, only the estimate written. It is checked to give the same
estimate bit for bit, then timed in the same run. Target (issue 25): (a) >= 100 M samples/s
for every family at orders 0-2; the ratio (a)/(b) is printed for the canonical observer.

    python benchmarks/bench_estimate.py            # about 20 s; --samples N to change 1e7
    python benchmarks/bench_estimate.py --first-call 5   # a process's first call, 5 each

``--first-call K`` times instead the *first* call of K fresh processes each (after a call on
100 samples that compiles): the minimal kernel, ``estimate_disturbance`` of the canonical
observer without and with ``t=``, and with ``t=`` and read-only inputs (shared by the result,
as a Log's columns are, instead of copied). A first call writes fresh memory (its result
arrays), which the repeats above reuse; the ratio against the minimal kernel's first call
(which writes only its estimate) is printed, medians of the processes.

Interleaved repeats, best of each (the machine may be shared: ratios measured in the same run
are robust to load, absolute figures less so).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from hpdob import ServoModel, design_observer, estimate_disturbance
from hpdob.observers import design_eso, design_kalman, initial_state


@numba.njit(nogil=True)
def minimal(theta, u, Ts, s_init, c):
    """The order-1 DOb written by hand, as ``Program`` orders it (no copies, no time)."""
    c0, c1, c2, c3, c4, c5, c6, c7, c8, c9, c10 = c
    s0, s1 = s_init[0], s_init[1]
    tau = np.empty(theta.shape[0])
    previous = theta[0]
    for k in range(theta.shape[0]):
        th = theta[k]
        om = (th - previous) / Ts
        previous = th
        tau[k] = s1 + c9 * th + c10 * om
        uk = u[k]
        n0 = s1 + c0 * s1 + c1 * th + c2 * om + c3 * uk
        n1 = c4 * s1 + c5 * th + c6 * om + c7 * uk - s0 + c8 * s1
        s0, s1 = n0, n1
    return tau


def observers(model):
    """Every family at orders 0-2 (the order-m DOb on the state and on the position, the ESO,
    the Kalman filter)."""
    for m in range(3):
        yield f"DOb m={m} (state)", design_observer(model, order=m, bandwidth=100.0)
        yield (
            f"DOb m={m} (position)",
            design_observer(model, order=m, bandwidth=100.0, measurement="position"),
        )
        yield f"ESO m={m}", design_eso(model, bandwidth=100.0, extended_order=m)
        yield (
            f"Kalman m={m}",
            design_kalman(model, order=m, position_noise_std=1e-4, process_noise_std=1.0),
        )


def best(function, repeat):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def first_call(which: str, n: int) -> float:
    """The first call on ``n`` samples of ``which`` in this process [s], after one on 100."""
    theta, u, t, Ts, canonical, s_init, c = setup(n)
    if which == "minimal":
        minimal(theta[:100], u[:100], Ts, s_init, c)
        start = time.perf_counter()
        minimal(theta, u, Ts, s_init, c)
    else:
        times = None if which == "hpdob" else t
        if which == "read-only":  # as a Log's or a Parquet file's columns: shared, not copied
            for x in (theta, u, t):
                x.flags.writeable = False
        estimate_disturbance(canonical, theta=theta[:100], u=u[:100],
                             t=None if times is None else times[:100])  # fmt: skip
        start = time.perf_counter()
        estimate_disturbance(canonical, theta=theta, u=u, t=times)
    return time.perf_counter() - start


def setup(n: int):
    Ts = 1e-3
    model = ServoModel(2.8e-4).discretize(Ts)
    rng = np.random.default_rng(25)  # synthetic log
    theta = np.cumsum(rng.standard_normal(n)) * 1e-4
    u = rng.standard_normal(n) * 0.01
    t = np.arange(n) * Ts
    canonical = design_observer(model, order=1, bandwidth=100.0)
    program = canonical.system.program
    c = tuple(t.coefficient for rows in (program.update, program.output) for r in rows
              for t in r if abs(t.coefficient) != 1.0)  # fmt: skip
    s_init = np.array(initial_state(canonical, (float(theta[0]), 0.0)))  # at rest, tau0 = 0
    return theta, u, t, Ts, canonical, s_init, c


def first_calls(k: int, n: int) -> None:
    import statistics
    import subprocess
    import sys

    which = ("minimal", "hpdob", "hpdob, t=", "read-only")
    runs = {w: [] for w in which}
    for _ in range(k):  # interleaved fresh processes
        for w in which:
            out = subprocess.run([sys.executable, __file__, "--samples", str(n), "--child", w],
                                 capture_output=True, text=True, check=True).stdout  # fmt: skip
            runs[w].append(float(out))
    base = statistics.median(runs["minimal"])
    print(f"{n:.3g} samples (synthetic log), the first call of {k} fresh processes each, medians")
    for w in which:
        m = statistics.median(runs[w])
        print(f"    {w:12s} {m * 1e3:7.1f} ms {n / m / 1e6:7.1f} M samples/s  vs minimal "
              f"{m / base:5.2f}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, default=1e7)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--first-call", type=int, default=0, metavar="K",
                        help="time the first call of K fresh processes each instead")  # fmt: skip
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    n = int(args.samples)
    if args.child:
        print(first_call(args.child, n))
        return
    if args.first_call:
        first_calls(args.first_call, n)
        return
    theta, u, t, Ts, canonical, s_init, c = setup(n)
    model = ServoModel(2.8e-4).discretize(Ts)
    reference = minimal(theta, u, Ts, s_init, c)
    result = estimate_disturbance(canonical, theta=theta, u=u)
    assert np.array_equal(reference, result.tau_hat), "the minimal kernel must agree bit for bit"
    columns = {"theta": theta.copy(), "u": u.copy(), "t": t}  # as a Log's: read-only, shared
    for x in columns.values():
        x.flags.writeable = False
    calls = {  # the two ways a log reaches the call
        "writable": {"theta": theta, "u": u},  # copied into the result; t = k Ts
        "read-only": columns,  # shared by the result (the CLI's and a Log's case)
    }

    designs = list(observers(model))
    for _, design in designs:  # compile each program structure once
        for kw in calls.values():
            estimate_disturbance(design, **{k: v[:100] for k, v in kw.items()})
    timings = {"minimal": [], **{(name, how): [] for name, _ in designs for how in calls}}
    for _ in range(args.repeat):  # interleaved
        timings["minimal"].append(best(lambda: minimal(theta, u, Ts, s_init, c), 1))
        for name, design in designs:
            for how, kw in calls.items():
                timings[name, how].append(
                    best(lambda design=design, kw=kw: estimate_disturbance(design, **kw), 1)
                )
    t_min = min(timings["minimal"])
    print(f"{n:.3g} samples (synthetic log), best of {args.repeat} interleaved repeats")
    print(f"(b) minimal hand-written kernel, DOb m=1: {t_min * 1e3:7.1f} ms "
          f"({n / t_min / 1e6:6.1f} M samples/s)")  # fmt: skip
    print("(a) estimate_disturbance: writable theta, u (copied, t = k Ts) | read-only theta, u, "
          "t (shared)")  # fmt: skip
    print(f"    {'':28s} {'ms':>7s} {'M/s':>7s} {'vs (b)':>7s} | {'ms':>7s} {'M/s':>7s} "
          f"{'vs (b)':>7s}")  # fmt: skip
    worst = dict.fromkeys(calls, float("inf"))
    for name, _ in designs:
        cells = []
        for how in calls:
            best_t = min(timings[name, how])
            worst[how] = min(worst[how], n / best_t / 1e6)
            cells.append(f"{best_t * 1e3:7.1f} {n / best_t / 1e6:7.1f} {best_t / t_min:7.2f}")
        print(f"    {name:28s} {' | '.join(cells)}")
    for how in calls:
        print(f"slowest family, {how} inputs: {worst[how]:.1f} M samples/s (target >= 100)")


if __name__ == "__main__":
    main()
