"""Fixed-point export on a Cortex-M: code size, executed instructions per sample, accuracy.

For every family (the paper's order-m DOb, its position-only form, ADRC's ESO, the Kalman
observer) and orders 0-2, on the canonical nominal model (J_n = 2.8e-4 kg m^2, Ts = 1 ms) with
the ranges of tests/export/test_fixed.py (16384 counts/rev, 50 rad/s, 0.5 N m, 0.5 N m):

* part 1 -- the q31 export compiled with zig cc -O2 for the Cortex-M0+ and the Cortex-M3
  (soft float): bytes of the observer's object file (.text + .rodata), the helpers it calls,
  and the instructions unicorn executes for one ``estimate`` (+ ``velocity``) + ``update``
  (the ``_step`` function of hpdob.testing._target, call included; mean over 100 samples of
  the closed-loop run). The float export of the same design is the reference measured in the
  same run: "ratio" is float instructions / q31 instructions.
* part 2 -- accuracy on the 10^5-sample closed-loop run of the tests (encoder, Coulomb
  friction, torque limit, load step and sine): the largest |tau_hat_q31 - tau_hat_double|, the
  largest a-posteriori bound along the run, the a-priori bound of the design, and the a-priori
  bound of q15 for comparison.

    python benchmarks/bench_export_fixed.py [--part 1|2]

and copy the tables into docs/deployment.md.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from hpdob import Actuator, Encoder, design_observer, export_c, paper, simulate
from hpdob.export import FixedPointObserver, fixed_point_design, fixed_point_error_bound
from hpdob.observers import design_eso, design_kalman, kalman_process_noise
from hpdob.signals import Sine, Step
from hpdob.testing import (
    EmulatedCortexM,
    cross_compile,
    fixed_drive_source,
    float_step_source,
    read_elf,
)

MODEL = paper.NOMINAL.discretize(paper.TS)
CPR = 16384
RANGES = {"counts_per_rev": CPR, "omega_max": 50.0, "u_max": 0.5, "tau_max": 0.5}
R = 2 * math.pi / CPR / math.sqrt(12)
CPUS = ("cortex-m0plus", "cortex-m3")


def designs():
    for m in range(3):
        yield f"DOb order {m}", design_observer(MODEL, order=m, bandwidth=100.0)
    for m in range(3):
        yield f"position order {m}", design_observer(MODEL, order=m, bandwidth=150.0,
                                                     measurement="position")  # fmt: skip
    for m in range(3):
        yield f"ESO m = {m}", design_eso(MODEL, bandwidth=150.0, extended_order=m)
    for m in range(3):
        q = kalman_process_noise(MODEL, order=m, bandwidth=100.0, position_noise_std=R)
        yield f"Kalman order {m}", design_kalman(MODEL, order=m, position_noise_std=R,
                                                 process_noise_std=q)  # fmt: skip


def closed_loop():
    kwargs = paper.scenario()
    kwargs.update(observer=paper.observer("HPDOb-100").design, sensor=Encoder(CPR),
                  actuator=Actuator(torque_limit=0.444),
                  reference=Sine(1.0, 0.3) + Sine(0.5, 1.7),
                  disturbance=Step(1.5, 0.05) + Sine(0.02, 2.0, start=2.5),
                  duration=100.0, substeps=8)  # fmt: skip
    run = simulate(**kwargs)
    counts = np.rint(run.theta_measured / (2 * math.pi / CPR)).astype(np.int64)
    return counts, run.omega_measured, run.u


def part1(trace) -> None:
    counts, omega, u = trace
    sl = slice(2000, 2100)
    rows = {cpu: [] for cpu in CPUS}
    for name, design in designs():
        fx = fixed_point_design(design, **RANGES)
        system = fx.system
        W, U = fx.to_int("omega0", omega[sl]), fx.to_int("u", u[sl])
        fixed_in = list(zip(counts[sl], W, U, strict=True))
        theta = counts[sl] * fx.radians_per_count
        two = len(system.measures) == 2
        float_in = [((t, w, v) if two else (t, v)) for t, w, v in
                    zip(theta, omega[sl], u[sl], strict=True)]  # fmt: skip
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            _, q_src = export_c(fx, tmp / "q", dtype="q31")
            (tmp / "q" / "dob_drive.c").write_text(fixed_drive_source(fx, "dob"))
            _, f_src = export_c(design, tmp / "f", dtype="float")
            (tmp / "f" / "dob_step.c").write_text(
                float_step_source("dob", "float", system.measures, velocity=system.has_velocity)
            )
            for cpu in CPUS:
                obj = read_elf(cross_compile([q_src], tmp / f"q_{cpu}.o", cpu=cpu, link=False))
                floats = [s for s in obj.undefined() if s.startswith(("__aeabi_f", "__aeabi_d"))]
                assert not floats, floats
                f_obj = read_elf(cross_compile([f_src], tmp / f"f_{cpu}.o", cpu=cpu, link=False))
                q_elf = cross_compile([q_src, tmp / "q" / "dob_drive.c"], tmp / f"q_{cpu}.elf",
                                      cpu=cpu)  # fmt: skip
                f_elf = cross_compile([f_src, tmp / "f" / "dob_step.c"], tmp / f"f_{cpu}.elf",
                                      cpu=cpu)  # fmt: skip
                nq = EmulatedCortexM(q_elf, cpu=cpu).step_instructions(
                    "dob", fixed_in, state_size=4 * (system.n_states + 1), dtype=np.int32
                )
                nf = EmulatedCortexM(f_elf, cpu=cpu).step_instructions(
                    "dob", float_in, state_size=4 * system.n_states, dtype=np.float32
                )
                rows[cpu].append([name, str(system.n_states), str(obj.allocated_size()),
                                  str(f_obj.allocated_size()), f"{nq.mean():.0f}",
                                  f"{nf.mean():.0f}", f"{nf.mean() / nq.mean():.2f}",
                                  ", ".join(obj.undefined()) or "none",
                                  ", ".join(f_obj.undefined())])  # fmt: skip
    for cpu in CPUS:
        print(f"\n{cpu} (zig cc -O2, soft float):\n")
        print(
            "| observer | states | q31 object [B] | float object [B] | q31 instructions | "
            "float instructions | ratio | q31 calls | float calls |"
        )
        print("|---|---:|---:|---:|---:|---:|---:|---|---|")
        for row in rows[cpu]:
            print("| " + " | ".join(row) + " |")
    sys.stdout.flush()


def part2(trace) -> None:
    counts, omega, u = trace
    print(
        "| observer | max error q31 [N m] | max bound on the run [N m] | ratio | a-priori bound "
        "q31 [N m] | a-priori bound q15 [N m] |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for name, design in designs():
        fx = fixed_point_design(design, **RANGES)
        W, U = fx.to_int("omega0", omega), fx.to_int("u", u)
        init = (int(counts[0]), 0, 0)
        Y, S = FixedPointObserver(fx, *init).run(counts, W, U)
        system = fx.system
        reset, outputs, _, update = system.python
        theta = counts * fx.radians_per_count
        om, v = fx.to_real("omega0", W), fx.to_real("u", U)
        s = reset(theta[0], 0.0, 0.0)
        ref = np.empty(len(theta))
        two = len(system.measures) == 2
        for k in range(len(theta)):
            meas = (theta[k], om[k]) if two else (theta[k],)
            ref[k] = outputs(s, *meas)[0]
            s = update(s, *meas, v[k])
        error = np.abs(fx.to_real("tau_hat", Y[:, 0]) - ref)
        bound = fixed_point_error_bound(fx, counts, W, U, S, init=init)
        try:
            q15 = f"{fixed_point_design(design, word='q15', **RANGES).error_bound[0]:.2g}"
        except ValueError as err:
            q15 = f"refused ({str(err).split(':')[1].strip()[:40]}...)"
        print(
            f"| {name} | {error.max():.2g} | {bound.max():.2g} | "
            f"{(error / bound).max():.2f} | {fx.error_bound[0]:.2g} | {q15} |"
        )
        sys.stdout.flush()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", type=int, choices=(1, 2), default=None)
    args = parser.parse_args()
    trace = closed_loop()
    if args.part in (None, 1):
        part1(trace)
    if args.part in (None, 2):
        part2(trace)


if __name__ == "__main__":
    main()
