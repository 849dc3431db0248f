"""Per-sample cost of the exported C observer (estimate + update) and its state size.

For orders 0-3 in double and float, exports the HPDOb-style design (J_n = 2.8e-4 kg m^2,
b_n = 0, Ts = 1 ms, all poles at exp(-100 Ts)) with hpdob.export_c, compiles a timing driver
with ``gcc -std=c99 -O2`` and runs it. The driver closes the loop the way firmware does
(``u = u_pd + tau_hat`` feeds the update, so the samples form one dependency chain), cycles
through 4096 precomputed inputs and reports the best of 7 repeats of 2,000,000 samples, timed
with clock_gettime(CLOCK_MONOTONIC) around the whole loop (wall-clock time belongs in a
benchmark, not in the library). Two builds: the observer in its own translation unit
(function calls, as when dob.c is linked as is) and #included into the driver (the compiler
may inline it). The loop with the calls removed is reported as the overhead. Run with

    python benchmarks/bench_export_c.py

and copy the table into docs/deployment.md.
"""

from __future__ import annotations

import platform
import subprocess
import tempfile
from pathlib import Path

from hpdob import ServoModel, design_observer, export_c
from hpdob.testing import STRICT_FLAGS, compile_c, find_compiler

DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#ifdef SINGLE_TU
#include "dob.c"
#else
#include "dob.h"
#endif

#define N_IN 4096
#define SAMPLES 2000000L
#define REPEATS 7

static dob_real th[N_IN], om[N_IN], upd[N_IN];

static double now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

int main(void)
{
    volatile dob_real sink = 0;
    double best = 1e300, best_empty = 1e300;
    int i, r;
    for (i = 0; i < N_IN; ++i) { /* a slow wobble around 1 rad, deterministic */
        const double x = (double)(i % 97) / 97.0 - 0.5, y = (double)(i % 89) / 89.0 - 0.5;
        th[i] = (dob_real)(1.0 + 0.01 * x);
        om[i] = (dob_real)(0.5 * y);
        upd[i] = (dob_real)(1e-3 * (x + y));
    }
    for (r = 0; r < REPEATS; ++r) {
        dob_state s;
        dob_real acc = 0;
        long k;
        double t0, t1;
        dob_init(&s, th[0], om[0], (dob_real)0);
        t0 = now_ns();
        for (k = 0; k < SAMPLES; ++k) {
            const long j = k & (N_IN - 1);
            const dob_real tau_hat = dob_estimate(&s, th[j], om[j]);
            dob_update(&s, th[j], om[j], upd[j] + tau_hat);
            acc += tau_hat;
        }
        t1 = now_ns();
        sink = acc;
        if (t1 - t0 < best) {
            best = t1 - t0;
        }
        acc = 0;
        t0 = now_ns();
        for (k = 0; k < SAMPLES; ++k) {
            const long j = k & (N_IN - 1);
            acc += th[j] + om[j] + upd[j];
        }
        t1 = now_ns();
        sink = acc;
        if (t1 - t0 < best_empty) {
            best_empty = t1 - t0;
        }
    }
    (void)sink;
    printf("%.2f %.2f %lu\n", best / (double)SAMPLES, best_empty / (double)SAMPLES,
           (unsigned long)sizeof(dob_state));
    return 0;
}
"""


def measure(order: int, dtype: str, workdir: Path) -> tuple[float, float, float, int]:
    model = ServoModel(J=2.8e-4).discretize(1e-3)
    design = design_observer(model, order=order, bandwidth=100.0)
    out = workdir / f"order{order}_{dtype}"
    _, source = export_c(design, out, dtype=dtype)
    driver = out / "bench.c"
    driver.write_text(DRIVER)
    flags = (*STRICT_FLAGS, "-O2", f"-I{out}")
    results = []
    for single in (False, True):
        sources = [driver] if single else [driver, source]
        extra = ("-DSINGLE_TU",) if single else ()
        exe = compile_c(sources, out / f"bench{int(single)}", flags=(*flags, *extra))
        done = subprocess.run([str(exe)], capture_output=True, text=True, check=True)
        results.append([float(v) for v in done.stdout.split()])
    (calls, empty, size), (inlined, _, _) = results
    return calls, inlined, empty, int(size)


def main() -> None:
    if find_compiler() is None:
        raise SystemExit("no C compiler found (set CC or install gcc)")
    cc = subprocess.run([find_compiler(), "--version"], capture_output=True, text=True)
    print(f"{cc.stdout.splitlines()[0]} on {platform.machine()}, -std=c99 -O2")
    print("| order | type   | separate TU [ns] | inlined [ns] | loop alone [ns] | state [bytes] |")
    print("|------:|--------|-----------------:|-------------:|----------------:|--------------:|")
    with tempfile.TemporaryDirectory() as tmp:
        for order in range(4):
            for dtype in ("double", "float"):
                calls, inlined, empty, size = measure(order, dtype, Path(tmp))
                print(
                    f"| {order:>5} | {dtype:<6} | {calls:>16.1f} | {inlined:>12.1f} "
                    f"| {empty:>15.1f} | {size:>13} |"
                )


if __name__ == "__main__":
    main()
