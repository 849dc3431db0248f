"""Issue 21's tracking target: DOb- and HPDOb-based RTOBs at equal bandwidth and at equal noise.

tau_ref = 0.05 + 0.02 sin(2 pi 2 t) N m from 0.1 s on the stiff wall (10 N m/rad at theta_e),
the axis starting 0.01 rad before it at rest; the paper's motor (J = 3.06e-4 kg m^2,
b = 5e-5 N m s/rad, Coulomb 0.01 N m) and nominal model (J_n = 2.8e-4, b_n = 0), its
16384-count encoder with backward-difference velocity, one sample of delay, the 0.444 N m
torque limit; ForceControl(kf = 1000, kv = 40); the observer is the DOb and, shared, the RTOB
(minus the viscous friction beyond b_n): the conventional DOb (order 0) or the HPDOb (order 1).
RMS over 1-3 s of tau_reac - tau_env (the estimate) and tau_env - tau_ref (the tracking).

Not one lucky run: every loop runs twice per seed, with the encoder (quantised) and with an
unquantised one (2^52 counts, the same backward difference): the noise-free part, and the
noise in tau_reac as the RMS of the difference of the two tau_reac traces. Twenty seeds draw the
wall's position uniformly within one count (so the quantisation error sequence differs); the
tables give mean and spread (max - min) over the seeds.

Equal noise: the HPDOb bandwidth whose measured noise in tau_reac (mean over the seeds) equals
the DOb's at 100 rad/s, found by Brent's method; beside it, the bandwidth the exact noise gain
of hpdob.analysis.noise_gains predicts (the linear loop in contact, white position noise of
the quantisation's standard deviation q/sqrt(12)).

The comparison runs three times: on the paper's motor with the viscous friction model only
(the linear RTOB does not subtract the Coulomb torque, which then dominates tau_reac - tau_env;
the error against tau_env + c tanh(omega/v), what that RTOB estimates, is printed too); on the
paper's motor with the whole friction model known (``friction=PLANT``: the viscous friction and
c tanh(w/v), w the measured velocity low-passed at 100 rad/s, ``velocity_filter=100``); and
without the plant's Coulomb friction.

    PYTHONPATH=src python benchmarks/bench_force_tracking.py     # under a minute
"""

from __future__ import annotations

import math

import numpy as np

from hpdob import Actuator, Encoder, Environment, ServoLoop, noise_gains, paper, simulate
from hpdob.controllers import ForceControl
from hpdob.models import InContact
from hpdob.observers import design_observer, reaction_torque_observer

K_E = 10.0  # N m/rad
SEEDS = range(20)
FINE = Encoder(2**52, velocity="backward-difference")
COUNT = paper.VIRTUAL_SENSOR.resolution  # rad


def reference(t):
    on = t >= 0.1
    return np.where(on, 0.05 + 0.02 * np.sin(2 * np.pi * 2 * t), 0.0), 0 * t, 0 * t


#: The Coulomb term's velocity: the measured velocity low-passed at this bandwidth [rad/s]
#: (docs/force-control.md: the encoder's velocity moves in steps of 0.38 rad/s, far above the
#: smoothing scale 0.01 rad/s).
VELOCITY_FILTER = 100.0


def loop(order, bandwidth, *, plant=paper.PLANT, wall=0.0, sensor=paper.VIRTUAL_SENSOR,
         coulomb=False):  # fmt: skip
    """The force loop; ``coulomb``: the RTOB subtracts the whole friction model of ``plant``
    (viscous beyond b_n and c tanh(w/v)), else the viscous friction beyond b_n only."""
    model = paper.NOMINAL.discretize(paper.TS)
    dob = design_observer(model, order=order, bandwidth=bandwidth)
    if coulomb:
        observer = reaction_torque_observer(dob, friction=plant, velocity_filter=VELOCITY_FILTER)
    else:
        observer = reaction_torque_observer(dob, viscous=paper.PLANT.b - paper.NOMINAL.b)
    return ServoLoop(plant=plant.replace(environment=Environment(K_E, position=wall)),
                     nominal=paper.NOMINAL, Ts=paper.TS, observer=observer,
                     controller=ForceControl(1000.0, kv=40.0), sensor=sensor,
                     actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip


def runs(order, bandwidth, plant=paper.PLANT, seeds=SEEDS, coulomb=False) -> dict:
    """RMS figures over 1-3 s per seed: quantised and noise-free estimate and tracking errors,
    the noise in tau_reac, the error against tau_env + Coulomb (noise-free run)."""
    rows = []
    for seed in seeds:
        wall = float(np.random.default_rng(seed).uniform(0.0, COUNT))
        pair = [simulate(loop(order, bandwidth, plant=plant, wall=wall, sensor=sensor,
                              coulomb=coulomb),
                         reference=reference, duration=3.0, x0=(wall - 0.01, 0.0))
                for sensor in (paper.VIRTUAL_SENSOR, FINE)]  # fmt: skip
        quantised, free = pair
        window = quantised.t >= 1.0

        def rms(x, window=window):
            return float(np.sqrt(np.mean(x[window] ** 2)))

        friction = plant.coulomb * np.tanh(free.omega / plant.coulomb_velocity)
        rows.append({
            "estimate": rms(quantised.tau_reac - quantised.tau_contact),
            "tracking": rms(quantised.tau_contact - quantised.r),
            "estimate_free": rms(free.tau_reac - free.tau_contact),
            "tracking_free": rms(free.tau_contact - free.r),
            "noise": rms(quantised.tau_reac - free.tau_reac),
            "total_free": rms(free.tau_reac - free.tau_contact - friction),
        })  # fmt: skip
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def equal_noise_bandwidth(target: float, plant, coulomb=False) -> float:
    """The HPDOb bandwidth [rad/s] whose mean measured noise in tau_reac is ``target``."""
    from scipy.optimize import brentq

    def f(x):
        return float(np.mean(runs(1, math.exp(x), plant, coulomb=coulomb)["noise"])) - target

    # from 25 rad/s: with the Coulomb term the measured noise is not monotone in the bandwidth
    # (least near 20 rad/s, 2.8e-3 N m, and 4.0e-3 at 10 rad/s): the crossing above it
    return math.exp(brentq(f, math.log(25.0), math.log(100.0), xtol=1e-4))


def predicted_noise(order, bandwidth, plant) -> float:
    """RMS of tau_hat (= tau_reac up to Delta_b omega_m) per white position noise q/sqrt(12)."""
    linear = loop(order, bandwidth, plant=plant).replace(
        plant=InContact(plant.replace(environment=Environment(K_E))),
        actuator=Actuator(delay_samples=1),
    )
    return noise_gains(linear).tau_hat_position * COUNT / math.sqrt(12.0)


def predicted_equal_noise_bandwidth(target: float, plant) -> float:
    from scipy.optimize import brentq

    def f(x):
        return predicted_noise(1, math.exp(x), plant) - target

    return math.exp(brentq(f, math.log(10.0), math.log(100.0), xtol=1e-6))


def show(label, figures, coulomb=False) -> None:
    cells = []
    for key in ("estimate", "tracking", "estimate_free", "tracking_free", "noise", "total_free"):
        values = figures[key]
        # with the Coulomb term subtracted, tau_env is what the RTOB estimates: no last column
        cells.append("-" if coulomb and key == "total_free"
                     else f"{values.mean():.3e} ({np.ptp(values):.0e})")  # fmt: skip
    print(f"{label:>22} " + "  ".join(f"{c:>18}" for c in cells))


def main() -> None:
    header = ("est. quantised", "track. quantised", "est. noise-free", "track. noise-free",
              "noise in tau_reac", "vs tau_env+Coulomb")  # fmt: skip
    for name, plant, coulomb in (
        ("the paper's motor, viscous friction model", paper.PLANT, False),
        ("the paper's motor, viscous + Coulomb friction model", paper.PLANT, True),
        ("without Coulomb", paper.PLANT.replace(coulomb=0.0), False),
    ):
        dob = runs(0, 100.0, plant, coulomb=coulomb)
        target = float(np.mean(dob["noise"]))
        g_measured = equal_noise_bandwidth(target, plant, coulomb)
        g_predicted = predicted_equal_noise_bandwidth(predicted_noise(0, 100.0, plant), plant)
        print(f"\n{name}: RMS over 1-3 s [N m], mean (spread) over {len(SEEDS)} seeds")
        print(f"{'RTOB':>22} " + "  ".join(f"{h:>18}" for h in header))
        show("DOb 100 rad/s", dob, coulomb)
        at_100 = runs(1, 100.0, plant, coulomb=coulomb)
        show("HPDOb 100 rad/s", at_100, coulomb)
        equal = runs(1, g_measured, plant, coulomb=coulomb)
        show(f"HPDOb {g_measured:.1f} rad/s", equal, coulomb)
        print(f"equal noise: HPDOb at {g_measured:.1f} rad/s (measured noise, Brent); the noise "
              f"gains predict {g_predicted:.1f} rad/s")  # fmt: skip
        print(f"predicted noise at 100 rad/s: DOb {predicted_noise(0, 100.0, plant):.3e}, "
              f"measured {target:.3e} N m")  # fmt: skip
        for what, other in (("equal noise", equal), ("equal bandwidth", at_100)):
            ratios = ", ".join(f"{key} {np.mean(other[key]) / np.mean(dob[key]):.3f}"
                               for key in ("tracking", "estimate", "estimate_free"))  # fmt: skip
            print(f"RMS HPDOb/DOb at {what}: {ratios}")


if __name__ == "__main__":
    main()
