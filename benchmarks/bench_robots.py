"""The numbers of docs/robots.md: an observer per joint on the Franka Panda (MuJoCo), the
computed-torque peer, the external-force estimates, and the loop's speed.

1. Tracking: 7 joints at 1 kHz, a fast joint-space trajectory (every joint 0.5 rad swing at
   1.4 Hz: 2.2 rad/s peak) under gravity with a 1 kg payload at the flange that no controller
   knows; an 18-bit encoder per joint (backward-difference velocity). RMS tracking error per
   joint for PD alone, PD + per-joint DOb (order 0), HPDOb (order 1) and order 2 -- at equal
   bandwidth and at equal noise in tau_hat (each observer's bandwidth chosen so that its
   encoder-noise gain equals that of the DOb at 100 rad/s, joint by joint) -- and computed
   torque on the nominal model (without the payload). 1b: the nominal model's masses and
   inertias 20 % low instead (no payload). 1c: what rms_estimation_error measures (with the
   encoder and with ideal sensing).
2. External force: a 10 N step at the flange, robot at rest and in motion: the momentum
   observer (K_o = 50 1/s) and the per-joint observers' estimates of J^T F after 5/K_o (at rest
   also against the step error of each observer's own 1 - Q, and the HPDOb at 55 and 60 rad/s);
   the false force with no contact during the fast trajectory.
3. Speed: the 7-joint loop (DOb per joint) against real time, MuJoCo Euler and RK4, in
   wall-clock and CPU time (with the load average), and against MuJoCo's mj_step alone for
   the same steps, measured in the same run.

    pip install 'hpdob[mujoco]' && python benchmarks/bench_robots.py [--short] [--speed]
"""

from __future__ import annotations

import argparse
import os
import time
from itertools import product

import numpy as np
from scipy.signal import lfilter

from hpdob import PD, Actuator, Encoder, ServoModel, design_observer, observer_noise_gain
from hpdob.robots import (
    PANDA_READY,
    PANDA_TORQUE_LIMITS,
    ArmLoop,
    ComputedTorque,
    JointSines,
    joint_observer_external,
    momentum_observer,
    panda,
    simulate_arm,
)

TS = 1e-3
Q0 = np.array(PANDA_READY)
REFERENCE = JointSines(center=Q0, amplitude=0.5, frequency=1.4)
PD_GAINS = PD(400.0, 40.0)
ACTUATORS = [Actuator(torque_limit=t) for t in PANDA_TORQUE_LIMITS]
ENCODER = Encoder(2**18)
K_O = 50.0


def hold(t):
    return np.tile(Q0, (len(t), 1)), np.zeros((len(t), 7)), np.zeros((len(t), 7))


def equal_noise_bandwidth(J_n: float, order: int, target: float) -> float:
    """The bandwidth [rad/s] at which an order-m observer on ServoModel(J_n) has the encoder
    noise gain ``target`` (bisection on the log of the bandwidth)."""
    model = ServoModel(J_n).discretize(TS)
    lo, hi = 1.0, 2000.0
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        gain = observer_noise_gain(design_observer(model, order=order, bandwidth=mid),
                                   noise="encoder")  # fmt: skip
        lo, hi = (mid, hi) if gain < target else (lo, mid)
    return float(np.sqrt(lo * hi))


def observers_at_equal_noise(J_n, order):
    specs = []
    for J in J_n:
        dob = design_observer(ServoModel(J).discretize(TS), order=0, bandwidth=100.0)
        target = observer_noise_gain(dob, noise="encoder")
        specs.append({"order": order, "bandwidth": equal_noise_bandwidth(J, order, target)})
    return specs


def tracking(duration: float) -> None:
    plant, nominal = panda(payload=1.0), panda()
    print(f"1. tracking: RMS position error per joint [mrad], t >= 1 s of {duration:g} s "
          f"(peak reference velocity {REFERENCE.peak_velocity.min():.2f} rad/s)")  # fmt: skip
    base = ArmLoop(plant, TS, PD_GAINS, nominal=nominal, q0=Q0, actuator=ACTUATORS, sensor=ENCODER)
    runs = [("PD", base)]
    for order, name in ((0, "DOb"), (1, "HPDOb"), (2, "order 2")):
        runs.append(
            (f"PD + {name} 100", base.replace(observers={"order": order, "bandwidth": 100.0}))
        )
    for order, name in ((1, "HPDOb"), (2, "order 2")):
        specs = observers_at_equal_noise(base.nominal_inertia, order)
        bands = ", ".join(f"{s['bandwidth']:.0f}" for s in specs)
        print(f"   {name} at the DOb-100's encoder noise: bandwidths {bands} rad/s")
        runs.append((f"PD + {name} eq. noise", base.replace(observers=specs)))
    runs.append(("computed torque", base.replace(controller=ComputedTorque(nominal, 400.0, 40.0))))
    print("{:24s}".format("run") + "".join(f"{f'j{i}':>8s}" for i in range(1, 8))
          + "   tau_hat noise [N m]  samples at the torque limit")  # fmt: skip
    for name, loop in runs:
        res = simulate_arm(loop, duration=duration, reference=REFERENCE, tau0="gravity")
        e = 1e3 * np.array(res.metrics(start=1.0)["rms_position_error"])
        # the estimate's high-frequency content: RMS of its second difference / sqrt(6)
        noise = np.sqrt(np.mean(np.diff(res.tau_hat[res.t >= 1.0], 2, axis=0) ** 2, axis=0) / 6)
        flag = " (diverged)" if res.diverged else ""
        limited = int(np.sum(np.abs(res.u) >= np.array(PANDA_TORQUE_LIMITS)))
        print(f"{name:24s}" + "".join(f"{v:8.2f}" for v in e)
              + f"   max {noise.max():.2e}   {limited}{flag}")  # fmt: skip


def wrong_inertia(duration: float) -> None:
    """The nominal model's masses and inertias 20 % low (the plant: the Panda with no payload)."""
    plant, nominal = panda(), panda(inertia_scale=0.8)
    print("1b. nominal masses and inertias x 0.8 (no payload): RMS position error [mrad]")
    base = ArmLoop(plant, TS, PD_GAINS, nominal=nominal, q0=Q0, actuator=ACTUATORS, sensor=ENCODER)
    runs = [
        ("PD + DOb 100", base.replace(observers={"order": 0, "bandwidth": 100.0})),
        ("PD + HPDOb eq. noise", base.replace(observers=observers_at_equal_noise(
            base.nominal_inertia, 1))),
        ("computed torque", base.replace(controller=ComputedTorque(nominal, 400.0, 40.0))),
    ]  # fmt: skip
    for name, loop in runs:
        res = simulate_arm(loop, duration=duration, reference=REFERENCE, tau0="gravity")
        e = 1e3 * np.array(res.metrics(start=1.0)["rms_position_error"])
        print(f"{name:24s}" + "".join(f"{v:8.2f}" for v in e))
        if name == "PD + DOb 100":
            est = momentum_observer(nominal, res, gain=K_O)
            f = np.linalg.norm(est.force[res.t >= 0.5], axis=1)
            print(f"   momentum observer on this model, no contact: false force max {f.max():.2f}"
                  f" N, rms {np.sqrt(np.mean(f**2)):.2f} N")  # fmt: skip


def estimation_error(duration: float) -> None:
    """What rms_estimation_error measures: the estimate against eq. 3's ground truth, whose
    high-frequency part is the command's encoder noise reflected through M^-1."""
    plant, nominal = panda(payload=1.0), panda()
    M = nominal.mass_matrix(Q0)
    print("1c. rms_estimation_error [N m] per joint (t >= 1 s); J_n,i (M^-1)_ii at q0: "
          + " ".join(f"{v:.2f}" for v in np.diag(M) * np.diag(np.linalg.inv(M))))  # fmt: skip
    for (sensor_name, sensor), (name, spec) in product(
        (("encoder", ENCODER), ("ideal", None)),
        (("DOb 100", {"order": 0, "bandwidth": 100.0}),
         ("HPDOb 49", {"order": 1, "bandwidth": 49.0})),
    ):  # fmt: skip
        loop = ArmLoop(plant, TS, PD_GAINS, nominal=nominal, q0=Q0, actuator=ACTUATORS,
                       sensor=sensor, observers=spec)  # fmt: skip
        res = simulate_arm(loop, duration=duration, reference=REFERENCE, tau0="gravity")
        err = res.metrics(start=1.0)["rms_estimation_error"]
        late = res.t >= 1.0
        hf = np.sqrt(np.mean(np.diff(res.tau_dn[late], 2, axis=0) ** 2, axis=0) / 6)
        print(f"   {sensor_name:8s} {name:9s}" + "".join(f"{v:7.2f}" for v in err)
              + "   tau_dn's high-frequency part: " + " ".join(f"{v:.2f}" for v in hf))  # fmt: skip


def estimates(nominal, res, loop, name, with_momentum):
    """The momentum observer's and the per-joint observers' external-torque estimates."""
    if with_momentum:
        yield "momentum", momentum_observer(nominal, res, gain=K_O)
    yield name, joint_observer_external(res, nominal, loop=loop)


def external_force(duration: float) -> None:
    print("2. external force: 10 N along x at the flange from t = 0.5 s (K_o = 50 1/s)")
    nominal, heavy = panda(), panda(payload=1.0)
    F = np.array([10.0, 0.0, 0.0])

    def force(t):
        return np.where(np.asarray(t)[:, None] >= 0.5, F, 0.0)

    J_n = ArmLoop(nominal, TS, PD_GAINS, q0=Q0).nominal_inertia
    observers = {"DOb 100": {"order": 0, "bandwidth": 100.0},
                 "HPDOb eq.": observers_at_equal_noise(J_n, 1)}  # fmt: skip
    sensors = (("ideal", None), ("encoder", ENCODER))
    for label, reference in (("at rest", hold), ("in motion", REFERENCE)):
        for (sensor_name, sensor), (i, obs_name) in product(sensors, enumerate(observers)):
            loop = ArmLoop(nominal, TS, PD_GAINS, observers=observers[obs_name], q0=Q0,
                           actuator=ACTUATORS, sensor=sensor)  # fmt: skip
            res = simulate_arm(loop, duration=duration, reference=reference, external=force,
                               tau0="gravity")  # fmt: skip
            late = res.t >= 0.5 + 5.0 / K_O
            truth = res.tau_external[late]
            for name, est in estimates(nominal, res, loop, obs_name, i == 0):
                err = np.linalg.norm(est.tau[late] - truth, axis=1) / np.linalg.norm(truth, axis=1)
                f_err = np.linalg.norm(est.force[late] - F, axis=1)
                print(f"   {label:9s} {sensor_name:8s} {name:10s} |tau - J^T F|/|J^T F| after "
                      f"5/K_o: max {100 * err.max():6.2f} %, "
                      f"rms {100 * np.sqrt(np.mean(err**2)):6.2f} %; "
                      f"|F - F_true| rms {np.sqrt(np.mean(f_err**2)):.3f} N")  # fmt: skip
    # the per-joint estimate is Q tau_ext: its error at 5/K_o is the step error of 1 - Q there
    print(
        "   per-joint observers at rest, ideal sensor: error after 5/K_o against the step "
        "error of their own 1 - Q = (z - 1)^(m+1) / prod(z - p_i) at 5/K_o"
    )
    specs = dict(observers)
    specs.update({f"HPDOb {g:g}": {"order": 1, "bandwidth": g} for g in (55.0, 60.0)})
    dob_noise = observer_noise_gain(design_observer(ServoModel(J_n[0]).discretize(TS), order=0,
                                                    bandwidth=100.0), noise="encoder")  # fmt: skip
    for obs_name, spec in specs.items():
        loop = ArmLoop(nominal, TS, PD_GAINS, observers=spec, q0=Q0, actuator=ACTUATORS)
        res = simulate_arm(loop, duration=0.5 + 5.0 / K_O + 0.05, reference=hold, external=force,
                           tau0="gravity")  # fmt: skip
        late = res.t >= 0.5 + 5.0 / K_O
        truth = res.tau_external[late]
        est = joint_observer_external(res, nominal, loop=loop)
        err = np.linalg.norm(est.tau[late] - truth, axis=1) / np.linalg.norm(truth, axis=1)
        first = spec[0] if isinstance(spec, list) else spec
        design = design_observer(ServoModel(J_n[0]).discretize(TS), **first)
        step = np.ones(round(5.0 / K_O / TS) + 1)
        predicted = lfilter(np.poly(np.ones(first["order"] + 1)), np.real(np.poly(design.poles)),
                            step)[-1]  # fmt: skip
        noise = observer_noise_gain(design, noise="encoder") / dob_noise
        print(f"   {obs_name:10s} ({first['bandwidth']:5.1f} rad/s): max {100 * err.max():5.2f} %,"
              f" its 1 - Q at 5/K_o {100 * abs(predicted):5.2f} %; encoder noise gain "
              f"{noise:.2f} x the DOb-100's")  # fmt: skip
    print("   false force, no contact, the fast trajectory (t >= 0.5 s), |F| [N]: max / rms")
    for (model_name, plant), (sensor_name, sensor), (i, obs_name) in product(
        (("exact model", nominal), ("unknown 1 kg payload", heavy)), sensors,
        enumerate(observers),
    ):  # fmt: skip
        loop = ArmLoop(plant, TS, PD_GAINS, observers=observers[obs_name], nominal=nominal,
                       q0=Q0, actuator=ACTUATORS, sensor=sensor)  # fmt: skip
        res = simulate_arm(loop, duration=duration, reference=REFERENCE, tau0="gravity")
        late = res.t >= 0.5
        for name, est in estimates(nominal, res, loop, obs_name, i == 0):
            f = np.linalg.norm(est.force[late], axis=1)
            print(f"   {model_name:21s} {sensor_name:8s} {name:10s} "
                  f"{f.max():8.3f} / {np.sqrt(np.mean(f**2)):8.3f}")  # fmt: skip


def timed(run, repeats: int = 3) -> tuple[float, float]:
    """Best of ``repeats`` of ``run()``: (wall-clock [s], CPU time of this process [s]).

    numba and MuJoCo run single-threaded here, so CPU time is the loop's own cost, the wall
    clock that plus the time other processes on the machine take the core away."""
    wall = cpu = np.inf
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        run()
        wall = min(wall, time.perf_counter() - w0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def mj_steps_alone(arm, steps: int):
    """The reference: MuJoCo's ``mj_step`` alone, ``steps`` times on the same compiled model
    (the arm held at the ready pose by its gravity torque, no observers, no Python loop body)."""
    mujoco, model, data = arm.compile(TS)
    data.qpos[:] = Q0
    mujoco.mj_forward(model, data)
    data.qfrc_applied[:] = data.qfrc_bias

    def run():
        for _ in range(steps):
            mujoco.mj_step(model, data)

    return run


def speed(duration: float) -> None:
    print(f"3. speed: the 7-joint loop (DOb per joint, encoder), {duration:g} s at 1 kHz, best "
          f"of 3; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")  # fmt: skip
    steps = round(duration / TS)
    for integrator in ("Euler", "RK4"):
        plant = panda(payload=1.0, integrator=integrator)
        loop = ArmLoop(plant, TS, PD_GAINS, observers={"order": 0, "bandwidth": 100.0},
                       nominal=panda(), q0=Q0, actuator=ACTUATORS, sensor=ENCODER)  # fmt: skip
        simulate_arm(loop, duration=0.01, reference=REFERENCE)  # compile / warm up
        wall, cpu = timed(
            lambda loop=loop: simulate_arm(
                loop, duration=duration, reference=REFERENCE, tau0="gravity"
            )
        )
        ref_wall, ref_cpu = timed(mj_steps_alone(plant, steps))
        print(
            f"   MuJoCo {integrator:5s}: {wall:.3f} s wall, {cpu:.3f} s CPU for {duration:g} s "
            f"simulated: {duration / wall:.1f}x real time (wall), {duration / cpu:.1f}x (CPU); "
            f"mj_step alone {ref_cpu:.3f} s CPU ({duration / ref_cpu:.0f}x): the loop costs "
            f"{cpu / ref_cpu:.2f}x MuJoCo's steps alone (CPU; {wall / ref_wall:.2f}x wall)"
        )
    print(f"   load average after: {os.getloadavg()[0]:.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", action="store_true", help="shorter runs (smoke test)")
    parser.add_argument("--speed", action="store_true", help="only the speed section (3)")
    args = parser.parse_args()
    if args.speed:
        speed(2.0 if args.short else 10.0)
        return
    d = 1.5 if args.short else 4.0
    tracking(d)
    wrong_inertia(d)
    estimation_error(d)
    external_force(1.5 if args.short else 2.0)
    speed(2.0 if args.short else 10.0)


if __name__ == "__main__":
    main()
