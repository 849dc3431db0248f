"""Speed of one closed-loop run, side by side in one process.

(a) ``hpdob.simulate`` (compiled kernel), (b) the straightforward Python reference loop of the
tests, (c) python-control's ``forced_response`` on the ZOH-discretised *linear* version of the
same closed loop (no Coulomb friction, disturbance held over each sample, no sub-steps: it
does less work than (a) and (b)), (d) ``simulate`` with a two-mass plant (the canonical motor's
inertia split evenly between motor and load, 40 Hz resonance) instead of the rigid one.
Canonical HPDOb-100 run: 10 s at 1 kHz, default sub-steps.
Targets (issue 11): (a) <= 7 ms once warm, >= 50x (b) and >= 4x (c); (d) <= 3x (a);
``import hpdob`` < 0.5 s.

    python benchmarks/bench_simulate.py          # needs python-control (pip install control)
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from hpdob import TwoMassServo, paper, simulate
from reference_loop import reference_loop


def best_of(function, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def linear_closed_loop():
    """The canonical HPDOb-100 loop as a discrete LTI system (python-control)."""
    import control

    kw = paper.scenario()
    plant = kw["plant"].discretize(kw["Ts"])
    design = paper.observer("HPDOb-100").design
    J_n, kp, kd = kw["nominal"].J, kw["controller"].kp, kw["controller"].kd
    A, B, D = plant.A, plant.B, plant.D
    M, Kx, Ku, L = design.error_matrix, design.state_input, design.control_input, design.gains[-1]
    m = M.shape[0]
    e = np.zeros(m)
    e[-1] = 1.0
    Kc = -J_n * np.array([kp, kd]) - L  # u = Kc x + e^T z + J_n (r_ddot + kp r + kd r_dot)
    Fw = J_n * np.array([kp, kd, 1.0])  # weights of (r, r_dot, r_ddot)
    Acl = np.block(
        [[A + np.outer(B, Kc), np.outer(B, e)], [Kx + np.outer(Ku, Kc), M + np.outer(Ku, e)]]
    )
    Bcl = np.block([[np.outer(B, Fw), -D[:, None]], [np.outer(Ku, Fw), np.zeros((m, 1))]])
    Ccl = np.zeros((1, 2 + m))
    Ccl[0, 0] = 1.0
    return control.ss(Acl, Bcl, Ccl, np.zeros((1, 4)), kw["Ts"])


def main() -> None:
    import control

    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "import time; t = time.perf_counter(); import hpdob; print(time.perf_counter() - t)",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    print(f"import hpdob: {float(done.stdout) * 1e3:.0f} ms (fresh process)")
    paper.run("HPDOb-100")  # compile / load the cached kernel
    t_a = best_of(lambda: paper.run("HPDOb-100"), 30)
    kw = paper.scenario()
    obs = paper.observer("HPDOb-100")
    t_b = best_of(
        lambda: reference_loop(**kw, observer=obs, substeps=paper.PLANT.default_substeps(paper.TS)),
        3,
    )
    sys_cl = linear_closed_loop()
    t = np.arange(10_000) * kw["Ts"]
    r, rd, rdd = (kw["reference"].derivative(t, i) for i in range(3))
    w = np.vstack([r, rd, rdd, kw["disturbance"](t)])
    t_c = best_of(lambda: control.forced_response(sys_cl, T=t, U=w), 10)
    J = paper.PLANT.J
    drive = TwoMassServo(J / 2, J / 2, (2 * np.pi * 40.0) ** 2 / (4 / J), 1e-4,
                         b_motor=paper.PLANT.b, coulomb=paper.PLANT.coulomb,
                         coulomb_velocity=paper.PLANT.coulomb_velocity)  # fmt: skip
    two_mass = {**paper.scenario(), "plant": drive, "label": "two-mass"}
    simulate(**two_mass, observer=paper.observer("HPDOb-100").design)
    t_d = best_of(lambda: simulate(**two_mass, observer=paper.observer("HPDOb-100").design), 30)
    print(f"{'method':<58}{'time [ms]':>10}{'vs (a)':>9}")
    print(f"{'(a) hpdob.simulate (compiled kernel)':<58}{t_a * 1e3:>10.2f}{1:>9.1f}")
    print(
        f"{'(b) straightforward Python reference loop (tests)':<58}{t_b * 1e3:>10.1f}"
        f"{t_b / t_a:>9.1f}"
    )
    print(
        f"{'(c) python-control forced_response, linear ZOH loop':<58}{t_c * 1e3:>10.2f}"
        f"{t_c / t_a:>9.1f}"
    )
    print(f"{'(d) hpdob.simulate, two-mass plant':<58}{t_d * 1e3:>10.2f}{t_d / t_a:>9.1f}")


if __name__ == "__main__":
    main()
