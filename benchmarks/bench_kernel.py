"""``simulate`` against a minimal hand-written numba kernel doing the same arithmetic (issue 25).

The minimal kernel is one plain numba loop written for the canonical scenario only: the
reference (quintic step + raised cosine) and the disturbance (step + sine) evaluated inline at
the samples and at the sub-step midpoints, the observer as its dense matrices ``F, G, H, E``,
the PD with feed-forward, the encoder (quantiser, backward difference), the actuator's limit and
delay, the rigid plant's exponential-midpoint sub-steps with Coulomb friction (its ZOH matrices
from ``scipy.linalg.expm``, not from hpdob) and the ground truth (eq. 3); it fills the same
twelve result arrays. Before timing, every case checks that the minimal kernel's trajectories
equal hpdob's to rounding (a wrong reference would be worthless).

Cases: the canonical ``HPDOb-100`` run (10 s, 8 sub-steps, ideal sensor), the ``PD`` run, the
``1 s`` run, and the ``virtual`` experiment (16384-count encoder, 0.444 N m limit, one sample of
delay); hpdob's signals are sampled once per time grid and kept (``sample_signals``), so a
repeated call reuses them: the ``new`` cases empty that cache before every call (the cost of a
first run, or of signals not seen before). Calls interleaved, best of ``--repeat``, timed by
the thread's CPU time (``--clock wall`` for the wall time); printed: each time and the ratio
simulate / minimal kernel. Targets: canonical <= 1.3x, 1 s run <= 2x. Then the memory of a
100 s canonical run beyond its result arrays, per sample (tracemalloc peak during ``simulate``
minus the result's arrays; target <= 120 B).

With ``--startup``: the first ``simulate`` of a fresh process, with an empty numba cache and
with the cache that run left (targets: <= 1.0 s and <= 0.2 s; ``import hpdob`` and
``import numba`` are timed on their own, before it).

The sweep's throughput is ``bench_sweep.py``'s (against ``_minimal_kernel.py``, the one
minimal reference of a sweep scenario: the loop with its row computed inline, nothing
recorded).

    python benchmarks/bench_kernel.py [--repeat 30] [--clock cpu|wall] [--startup]
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
import tracemalloc

import numba
import numpy as np
from scipy.linalg import expm

from hpdob import ServoLoop, paper, simulate
from hpdob.simulation import clear_sampled_signals

CLOCKS = {"cpu": time.thread_time, "wall": time.perf_counter}
RESULT = ("t", "theta", "omega", "theta_measured", "omega_measured", "r", "r_dot", "r_ddot",
          "u", "tau_hat", "tau_dn", "tau_ext")  # fmt: skip


@numba.njit(cache=True, nogil=True)
def minimal(n, S, Ts, Ad, Bd, Ah, Bh, b, J, c, v, F, G, H, E, J_n, kp, kd, counts, limit, delay):
    """The canonical loop, written out by hand; ``counts`` 0: ideal sensor."""
    t = np.empty(n)
    theta, omega, theta_m, omega_m = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    r, r_dot, r_ddot = np.empty(n), np.empty(n), np.empty(n)
    u, tau_hat, tau_dn, tau_ext = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    m = F.shape[0]
    s = np.zeros(m)
    s_new = np.zeros(m)
    th, om, prev = 0.0, 0.0, 0.0
    res = 2.0 * math.pi / counts if counts > 0 else 1.0
    h = Ts / S
    w_ref, w_dis = math.pi, 4.0 * math.pi
    for k in range(n):
        tk = k * Ts
        t[k] = tk
        # reference: SmoothStep(0.2, 1.2, 1) + Sine(-0.5, 0.5, start=4, phase=pi/2, offset=0.5)
        x = min(max((tk - 0.2) / 1.0, 0.0), 1.0)
        rk, rdk, rddk = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x), 0.0, 0.0
        if 0.2 < tk < 1.2:
            rdk = 30.0 * x * x * (1.0 - x) * (1.0 - x)
            rddk = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)
        if tk >= 4.0:
            phase = (tk - 4.0) * w_ref + math.pi / 2
            rk += -0.5 * math.sin(phase) + 0.5
            rdk += -0.5 * w_ref * math.cos(phase)
            rddk += 0.5 * w_ref * w_ref * math.sin(phase)
        r[k], r_dot[k], r_ddot[k] = rk, rdk, rddk
        # disturbance: Step(1.5005, 0.05) + Sine(0.02, 2, start=2.5005)
        dk = (0.05 if tk >= 1.5005 else 0.0) + (
            0.02 * math.sin((tk - 2.5005) * w_dis) if tk >= 2.5005 else 0.0
        )
        tau_ext[k] = dk
        theta[k], omega[k] = th, om
        if counts > 0:
            thm = res * math.floor(th / res + 0.5)
            omm = 0.0 if k == 0 else (thm - prev) / Ts
            prev = thm
        else:
            thm, omm = th, om
        theta_m[k], omega_m[k] = thm, omm
        est = E[0, 0] * thm + E[0, 1] * omm
        for i in range(m):
            est += H[0, i] * s[i]
        tau_hat[k] = est
        uk = J_n * (kp * (rk - thm) + kd * (rdk - omm) + rddk) + est
        uk = min(max(uk, -limit), limit)
        u[k] = uk
        for i in range(m):
            acc = G[i, 0] * thm + G[i, 1] * omm + G[i, 2] * uk
            for j in range(m):
                acc += F[i, j] * s[j]
            s_new[i] = acc
        s[:] = s_new
        a = u[k - delay] if k >= delay else 0.0
        accel = (a - b * om - c * math.tanh(om / v) - dk) / J
        tau_dn[k] = uk - J_n * accel
        for j in range(S):
            tm = tk + (j + 0.5) * h
            dm = (0.05 if tm >= 1.5005 else 0.0) + (
                0.02 * math.sin((tm - 2.5005) * w_dis) if tm >= 2.5005 else 0.0
            )
            f = a - c * math.tanh(om / v) - dm
            om_half = Ah[1, 0] * th + Ah[1, 1] * om + Bh[1] * f
            f = a - c * math.tanh(om_half / v) - dm
            th, om = (Ad[0, 0] * th + Ad[0, 1] * om + Bd[0] * f,
                      Ad[1, 0] * th + Ad[1, 1] * om + Bd[1] * f)  # fmt: skip
    return t, theta, omega, theta_m, omega_m, r, r_dot, r_ddot, u, tau_hat, tau_dn, tau_ext


def zoh(J, b, h):
    """``(A_h, B_h)`` of the rigid servo ``J th'' = a - b om`` over ``h`` (scipy's expm)."""
    M = np.zeros((3, 3))
    M[0, 1], M[1, 1], M[1, 2] = 1.0, -b / J, 1.0 / J
    P = expm(M * h)
    return P[:2, :2].copy(), P[:2, 2].copy()


CASES = {
    "HPDOb-100": {"observer": "HPDOb-100"},
    "PD": {"observer": None},
    "1 s": {"observer": "HPDOb-100", "duration": 1.0},
    "virtual": {"observer": "HPDOb-100", "virtual": True},
    # the same with the reference and disturbance sampled anew in every call (the time grid's
    # cache emptied first): a first run, or a run of signals not seen before
    "HPDOb-100 new": {"observer": "HPDOb-100", "new": True},
    "1 s new": {"observer": "HPDOb-100", "duration": 1.0, "new": True},
}


def case(name: str, duration: float | None = None):
    """``(simulate call, minimal-kernel call)`` of a case."""
    spec = CASES[name]
    kw = paper.scenario()
    kw["duration"] = duration or spec.get("duration", kw["duration"])
    if spec.get("virtual"):
        kw["sensor"], kw["actuator"] = paper.VIRTUAL_SENSOR, paper.VIRTUAL_ACTUATOR
    if spec["observer"]:
        kw["observer"] = paper.observer(spec["observer"]).design
    plant, nominal, Ts, S = kw["plant"], kw["nominal"], kw["Ts"], 8
    n = round(kw["duration"] / Ts)
    loop = ServoLoop(**{k: kw[k] for k in ("plant", "nominal", "Ts", "controller")},
                     observer=kw.get("observer"))  # fmt: skip
    system = loop.system
    if system is None:
        F, G, H, E = np.zeros((0, 0)), np.zeros((0, 3)), np.zeros((1, 0)), np.zeros((1, 2))
    else:
        F, G, H, E = system.F, system.G, system.H, system.E
        if G.shape[1] == 2:  # a position-only observer: no omega column
            G = np.insert(G, 1, 0.0, axis=1)
            E = np.insert(E, 1, 0.0, axis=1)
    Ad, Bd = zoh(plant.J, plant.b, Ts / S)
    Ah, Bh = zoh(plant.J, plant.b, Ts / S / 2)
    counts = paper.VIRTUAL_SENSOR.counts_per_rev if spec.get("virtual") else 0
    limit = paper.VIRTUAL_ACTUATOR.torque_limit if spec.get("virtual") else math.inf
    delay = paper.VIRTUAL_ACTUATOR.delay_samples if spec.get("virtual") else 0
    c = kw["controller"]
    args = (n, S, Ts, Ad, Bd, Ah, Bh, plant.b, plant.J, plant.coulomb, plant.coulomb_velocity,
            F, G, H, E, nominal.J, c.kp, c.kd, counts, limit, delay)  # fmt: skip
    if spec.get("new"):

        def run():
            clear_sampled_signals()
            return simulate(**kw, substeps=S)
    else:

        def run():
            return simulate(**kw, substeps=S)

    return run, (lambda: minimal(*args))


def check(name: str) -> float:
    """The largest difference of the two runs' trajectories, relative to each signal's size;
    raises if it is not rounding."""
    run, reference = case(name)
    ours, theirs = run(), reference()
    worst = 0.0
    for key, value in zip(RESULT, theirs, strict=True):
        mine = getattr(ours, key)
        scale = max(np.abs(value).max(), 1e-30)
        worst = max(worst, float(np.abs(mine - value).max() / scale))
    if not worst < 1e-6:
        raise AssertionError(f"{name}: the minimal kernel differs from simulate by {worst:.3g}")
    return worst


def best_interleaved(calls, repeat: int, clock) -> list:
    best = [math.inf] * len(calls)
    for _ in range(repeat):
        for i, call in enumerate(calls):
            start = clock()
            call()
            best[i] = min(best[i], clock() - start)
    return best


def memory_per_sample(duration: float = 100.0, new: bool = False) -> float:
    """Peak bytes traced during a warm canonical ``simulate`` beyond its result arrays, per
    sample; ``new``: with the signals sampled anew (the time grid's cache emptied first)."""
    run, _ = case("HPDOb-100", duration)
    run()
    if new:
        clear_sampled_signals()
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    result = run()
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    # the result's arrays: views of the run's own arrays
    owners = {}
    for key in RESULT:
        array = getattr(result, key)
        owner = array.base if array.base is not None else array
        owners[id(owner)] = owner
    held = sum(a.nbytes for a in owners.values())
    return (peak - held) / len(result.t)


STARTUP = """
import time
start = time.perf_counter()
import hpdob
imported = time.perf_counter()
import numba
numba_imported = time.perf_counter()
from hpdob import paper, simulate
kw = {**paper.scenario(), "observer": paper.observer("HPDOb-100").design}
ready = time.perf_counter()
simulate(**kw)
done = time.perf_counter()
print(imported - start, numba_imported - imported, ready - numba_imported, done - ready)
"""


def startup(rounds: int = 3) -> dict:
    """Wall times [s] of a fresh process: ``import hpdob``, ``import numba``, importing
    ``hpdob.paper`` and designing the observer, and the first canonical HPDOb-100 ``simulate``
    after them, with an empty numba cache (``fresh``: a new ``NUMBA_CACHE_DIR``) and with the
    cache the fresh run left (``later``); best of ``rounds``."""
    best = {"fresh": [math.inf] * 4, "later": [math.inf] * 4}
    for _ in range(rounds):
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "NUMBA_CACHE_DIR": cache}
            for kind in ("fresh", "later"):
                done = subprocess.run([sys.executable, "-c", STARTUP], env=env, check=True,
                                      capture_output=True, text=True)  # fmt: skip
                times = [float(x) for x in done.stdout.split()]
                best[kind] = [min(a, b) for a, b in zip(best[kind], times, strict=True)]
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=30)
    parser.add_argument("--clock", choices=tuple(CLOCKS), default="cpu")
    parser.add_argument("--startup", action="store_true",
                        help="also time the first simulate of fresh processes (wall)")  # fmt: skip
    args = parser.parse_args()
    clock = CLOCKS[args.clock]
    print(f"{'case':<10}{'simulate [ms]':>15}{'minimal [ms]':>14}{'ratio':>8}{'max rel diff':>14}")
    for name in CASES:
        worst = check(name)
        run, reference = case(name)
        ours, theirs = best_interleaved((run, reference), args.repeat, clock)
        print(f"{name:<10}{ours * 1e3:>15.3f}{theirs * 1e3:>14.3f}{ours / theirs:>8.2f}"
              f"{worst:>14.2g}", flush=True)  # fmt: skip
    print(f"100 s canonical run: {memory_per_sample():.1f} B per sample beyond its result arrays"
          f" ({memory_per_sample(new=True):.1f} B with the signals sampled anew)")  # fmt: skip
    if args.startup:
        for kind, (hpdob_s, numba_s, setup, first) in startup().items():
            print(f"first simulate, {kind} process: {first:.3f} s after import hpdob "
                  f"({hpdob_s:.3f} s), import numba ({numba_s:.3f} s), hpdob.paper and the "
                  f"design ({setup:.3f} s); {hpdob_s + numba_s + setup + first:.3f} s "
                  "in all")  # fmt: skip


if __name__ == "__main__":
    main()
