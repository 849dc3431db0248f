"""The numbers of docs/mujoco.md: hpdob's closed loop on a MuJoCo-simulated servo.

1. Cross-validation: canonical scenario without Coulomb friction, MuJoCo (RK4, Euler) vs
   hpdob's integrator at the same sub-steps; largest relative gap over the three metrics and
   over the theta trace, and the time of one 10 s run.
2. Pendulum (20 g at 10 cm, nominal = rigid body): DOb vs HPDOb error against MuJoCo's gravity
   torque, at 50, 100 and 200 rad/s.
3. Dry friction: MuJoCo's frictionloss vs hpdob's tanh model (both 0.01 N m), canonical runs,
   and the position error late in a step + load-step run.
4. A sweep of 8 MuJoCo scenarios (2 s each) on 1 and 2 local threads.

    pip install 'hpdob[mujoco]' && python benchmarks/bench_mujoco.py
"""

from __future__ import annotations

import time

import numpy as np

from hpdob import MujocoServo, ServoModel, design_observer, paper, simulate
from hpdob.signals import SmoothStep, Step

METRICS = ("rms_estimation_error", "rms_position_error_regulation", "rms_position_error_tracking")


def timed(**kwargs):
    start = time.perf_counter()
    result = simulate(**kwargs)
    return result, time.perf_counter() - start


def cross_validation() -> None:
    print("1. cross-validation (no Coulomb friction): max relative gap, metrics | theta trace")
    head = ("run", "integrator", "substeps", "metrics", "theta", "time")
    print("{:10s} {:10s} {:>8s} {:>9s} {:>9s} {:>7s}".format(*head))
    for name in ("DOb-100", "HPDOb-100"):
        kwargs = paper.scenario()
        kwargs["plant"] = paper.PLANT.replace(coulomb=0.0)
        kwargs["observer"] = paper.observer(name).design
        for integrator in ("RK4", "Euler", "implicitfast"):
            for substeps in (4, 8, 16, 32):
                reference, kernel_time = timed(**kwargs, substeps=substeps)
                plant = MujocoServo(paper.PLANT.J, paper.PLANT.b, integrator=integrator)
                result, elapsed = timed(**{**kwargs, "plant": plant}, substeps=substeps)
                want, got = reference.metrics(), result.metrics()
                metric_gap = max(abs(got[k] - want[k]) / want[k] for k in METRICS)
                theta_gap = np.max(np.abs(result.theta - reference.theta)) / np.max(
                    np.abs(reference.theta)
                )
                print(
                    f"{name:10s} {integrator:10s} {substeps:8d} {metric_gap:9.1e} "
                    f"{theta_gap:9.1e} {elapsed:6.2f}s  (kernel {kernel_time * 1e3:.0f} ms)"
                )


def pendulum() -> None:
    print("\n2. pendulum, 8 s: |tau_hat - gravity| [N m]")
    plant = MujocoServo(paper.PLANT.J, paper.PLANT.b, link_mass=0.02, link_length=0.1)
    nominal = ServoModel(plant.inertia, paper.PLANT.b)
    print(f"{'bandwidth':>9s} {'order':>5s} {'rms':>9s} {'max':>9s} {'rms pos err (track)':>20s}")
    for bandwidth in (50.0, 100.0, 200.0):
        for order in (0, 1):
            obs = design_observer(nominal.discretize(paper.TS), order=order, bandwidth=bandwidth)
            result = simulate(
                plant=plant,
                nominal=nominal,
                Ts=paper.TS,
                duration=8.0,
                controller=paper.CONTROLLER,
                observer=obs,
                reference=paper.REFERENCE,
            )
            error = result.tau_hat - plant.bias_torque(result.theta)
            print(
                f"{bandwidth:9.0f} {order:5d} {np.sqrt(np.mean(error**2)):9.2e} "
                f"{np.max(np.abs(error)):9.2e} "
                f"{result.metrics()['rms_position_error_tracking']:20.2e}"
            )


def friction() -> None:
    print("\n3a. canonical runs, tanh (hpdob) vs frictionloss (MuJoCo), 0.01 N m")
    print(f"{'run':10s} {'model':12s} " + " ".join(f"{m[4:]:>26s}" for m in METRICS))
    for name in ("PD", "DOb-50", "DOb-100", "DOb-200", "HPDOb-100"):
        obs = paper.observer(name)  # None for the PD alone
        kwargs = {**paper.scenario(), "observer": None if obs is None else obs.design}
        tanh = simulate(**kwargs)
        plant = MujocoServo(paper.PLANT.J, paper.PLANT.b, coulomb=paper.PLANT.coulomb)
        mujoco = simulate(**{**kwargs, "plant": plant})
        for label, result in (("tanh", tanh), ("frictionloss", mujoco)):
            m = result.metrics()
            print(f"{name:10s} {label:12s} " + " ".join(f"{m[k]:26.3e}" for k in METRICS))
    print("\n3b. step to 1 rad + 0.05 N m load step at 1.5 s, 10 s: max |theta - r| [rad]")
    head = ("run", "model", "2-3 s", "5-6 s", "9-10 s", "est. err 9-10 s")
    print("{:10s} {:12s} {:>9s} {:>9s} {:>9s} {:>16s}".format(*head))
    for name in ("DOb-100", "HPDOb-100"):
        kwargs = paper.scenario()
        kwargs.update(
            reference=SmoothStep(0.2, 1.2, 1.0),
            disturbance=Step(1.5005, 0.05),
            observer=paper.observer(name).design,
        )
        plant = MujocoServo(paper.PLANT.J, paper.PLANT.b, coulomb=paper.PLANT.coulomb)
        for label, result in (
            ("tanh", simulate(**kwargs)),
            ("frictionloss", simulate(**{**kwargs, "plant": plant})),
        ):
            t, e = result.t, np.abs(result.theta - result.r)
            windows = [np.max(e[(t >= a) & (t < a + 1)]) for a in (2.0, 5.0, 9.0)]
            est = np.max(np.abs(result.estimation_error[t >= 9.0]))
            print(
                f"{name:10s} {label:12s} "
                + " ".join(f"{w:9.2e}" for w in windows)
                + f" {est:16.2e}"
            )


def sweep_threads() -> None:
    from hpdob import sweep

    print("\n4. sweep of 8 MuJoCo scenarios (2 s each, HPDOb, frictionloss)")
    base = {
        **paper.scenario(),
        "duration": 2.0,
        "plant": MujocoServo(paper.PLANT.J, paper.PLANT.b, coulomb=paper.PLANT.coulomb),
        "observer": {"order": 1, "bandwidth": 100.0},
    }
    grid = {"observer.bandwidth": [50.0 * i for i in range(1, 9)]}
    sweep(base, grid={"observer.bandwidth": [100.0]}, scheduler=1, progress=False)  # warm up
    for workers in (1, 2):
        start = time.perf_counter()
        sweep(base, grid=grid, scheduler=workers, progress=False)
        print(f"{workers} thread(s): {time.perf_counter() - start:.2f} s")


if __name__ == "__main__":
    import mujoco

    print(f"mujoco {mujoco.__version__}")
    cross_validation()
    pendulum()
    friction()
    sweep_threads()
