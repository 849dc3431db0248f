"""Issue 21's tracking target (benchmarks/bench_force_tracking.py, with margin): DOb- and
HPDOb-based RTOBs on the stiff wall at equal bandwidth and at equal noise in tau_reac.

The noise in tau_reac is measured: each loop runs with the 16384-count encoder and with an
unquantised one (same backward difference), the noise is the RMS of the difference of the two
tau_reac traces; eight seeds draw the wall's position within one count."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob import Actuator, Encoder, Environment, ServoLoop, noise_gains, paper, simulate
from hpdob.controllers import ForceControl
from hpdob.models import InContact
from hpdob.observers import design_observer, reaction_torque_observer

K_E = 10.0  # N m/rad, the stiff wall
FINE = Encoder(2**52, velocity="backward-difference")
COUNT = paper.VIRTUAL_SENSOR.resolution
NO_COULOMB = paper.PLANT.replace(coulomb=0.0)
DELTA_B = paper.PLANT.b - paper.NOMINAL.b


def _reference(t):
    return np.where(t >= 0.1, 0.05 + 0.02 * np.sin(2 * np.pi * 2 * t), 0.0), 0 * t, 0 * t


def _loop(order, g, *, plant, wall=0.0, sensor=paper.VIRTUAL_SENSOR, coulomb=False):
    """The force loop; ``coulomb``: the RTOB subtracts the whole friction model of ``plant``
    (``friction=plant``, the Coulomb term's velocity low-passed at 100 rad/s)."""
    dob = design_observer(paper.NOMINAL.discretize(paper.TS), order=order, bandwidth=g)
    rtob = (reaction_torque_observer(dob, friction=plant, velocity_filter=100.0) if coulomb
            else reaction_torque_observer(dob, viscous=DELTA_B))  # fmt: skip
    return ServoLoop(plant=plant.replace(environment=Environment(K_E, position=wall)),
                     nominal=paper.NOMINAL, Ts=paper.TS, sensor=sensor, observer=rtob,
                     controller=ForceControl(1000.0, kv=40.0),
                     actuator=paper.VIRTUAL_ACTUATOR)  # fmt: skip


def _figures(order, g, plant, seeds=range(8), coulomb=False) -> dict:
    """Mean over the seeds of the RMS (1-3 s): tracking (quantised), noise in tau_reac, and the
    noise-free error against tau_env + c tanh(omega/v)."""
    out = {"tracking": [], "noise": [], "estimate": [], "estimate_free": [], "total_free": []}
    for seed in seeds:
        wall = float(np.random.default_rng(seed).uniform(0.0, COUNT))
        quantised, free = (simulate(_loop(order, g, plant=plant, wall=wall, sensor=s,
                                          coulomb=coulomb),
                                    reference=_reference, duration=3.0, x0=(wall - 0.01, 0.0))
                           for s in (paper.VIRTUAL_SENSOR, FINE))  # fmt: skip
        w = quantised.t >= 1.0
        friction = plant.coulomb * np.tanh(free.omega / plant.coulomb_velocity)
        for key, x in (("tracking", quantised.tau_contact - quantised.r),
                       ("noise", quantised.tau_reac - free.tau_reac),
                       ("estimate", quantised.tau_reac - quantised.tau_contact),
                       ("estimate_free", free.tau_reac - free.tau_contact),
                       ("total_free", free.tau_reac - free.tau_contact - friction)):  # fmt: skip
            out[key].append(np.sqrt(np.mean(x[w] ** 2)))
    return {k: float(np.mean(v)) for k, v in out.items()}


def _equal_noise(target, plant, coulomb=False) -> float:
    from scipy.optimize import brentq

    def f(x):
        return _figures(1, math.exp(x), plant, coulomb=coulomb)["noise"] - target

    # from 25 rad/s: with the Coulomb term the noise is least near 20 rad/s (not monotone)
    return math.exp(brentq(f, math.log(25.0), math.log(100.0), xtol=1e-3))


@pytest.mark.parametrize(("plant", "accuracy"), [(paper.PLANT, 1.1), (NO_COULOMB, 0.9)],
                         ids=["paper-motor", "no-coulomb"])  # fmt: skip
def test_hpdob_tracks_the_force_better_at_equal_noise(plant, accuracy):
    """At equal measured noise in tau_reac (the HPDOb at a lower bandwidth: 42 and 47 rad/s
    measured with 20 seeds) the HPDOb-based loop tracks tau_ref with a lower RMS error than
    the DOb-based loop at 100 rad/s (0.82 and 0.75 of it measured; test: < 0.93). Its
    noise-free estimate of what the RTOB estimates (tau_env + Coulomb) is 0.91 and 0.72 of the
    DOb's: within the seeds' uncertainty of the equal-noise bandwidth on the paper's motor
    (test: < 1.1), better without Coulomb (test: < 0.9). At equal bandwidth the tracking is
    better still (0.67 and 0.31 measured; test: < 0.75)."""
    dob = _figures(0, 100.0, plant)
    g = _equal_noise(dob["noise"], plant)
    assert 30.0 < g < 60.0
    equal = _figures(1, g, plant)
    assert equal["noise"] == pytest.approx(dob["noise"], rel=0.02)
    assert equal["tracking"] < 0.93 * dob["tracking"]
    assert equal["total_free"] < accuracy * dob["total_free"]
    assert _figures(1, 100.0, plant)["tracking"] < 0.75 * dob["tracking"]


def test_coulomb_torque_dominates_the_estimate_error_on_the_paper_motor():
    """The linear RTOB keeps the plant's Coulomb torque: on the paper's motor tau_reac - tau_env
    is larger for the HPDOb (it estimates tau_env + Coulomb more faithfully), though its error
    against tau_env + Coulomb is 4x smaller at equal bandwidth (measured 4.3x; test: > 3x)."""
    dob, hpdob = (_figures(order, 100.0, paper.PLANT, seeds=[0]) for order in (0, 1))
    assert hpdob["estimate"] > dob["estimate"]
    assert hpdob["total_free"] < dob["total_free"] / 3.0


def test_noise_gains_give_a_close_equal_noise_bandwidth():
    """The other way to equal noise: the exact closed-loop noise gain of the linear loop in
    contact (white position noise) puts the HPDOb's equal-noise bandwidth near the measured one
    (49 against 43-47 rad/s); quantisation on a nearly still axis is not white, so the absolute
    noise is over-predicted (4.2e-3 against 1.8e-3 N m measured; test: within a factor 4)."""
    from scipy.optimize import brentq

    def predicted(order, g):
        loop = _loop(order, g, plant=paper.PLANT)
        linear = loop.replace(plant=InContact(loop.plant), actuator=Actuator(delay_samples=1))
        return noise_gains(linear).tau_hat_position * COUNT / math.sqrt(12.0)

    target = predicted(0, 100.0)
    g = math.exp(brentq(lambda x: predicted(1, math.exp(x)) - target, math.log(10.0),
                        math.log(100.0)))  # fmt: skip
    assert 40.0 < g < 60.0
    measured = _figures(0, 100.0, paper.PLANT)["noise"]
    assert measured < target < 4.0 * measured


def test_with_the_coulomb_model_the_hpdob_tracks_and_estimates_better():
    """The friction model known (viscous + c tanh(w/v), w low-passed at 100 rad/s): at equal
    measured noise in tau_reac (the HPDOb at 45 rad/s, 20 seeds) the HPDOb-based loop tracks
    tau_ref with 0.77 of the DOb-based loop's RMS error (test: < 0.9) and its noise-free
    estimate of tau_env has 0.51 of the DOb's error (test: < 0.7); at equal bandwidth 0.43 and
    0.62 (tests: < 0.6, < 0.8). The total estimate error at equal noise is about the DOb's
    (0.98: the noise, which now holds the Coulomb term's flips at encoder ticks, dominates)."""
    dob = _figures(0, 100.0, paper.PLANT, coulomb=True)
    g = _equal_noise(dob["noise"], paper.PLANT, coulomb=True)
    assert 35.0 < g < 60.0
    equal = _figures(1, g, paper.PLANT, coulomb=True)
    assert equal["noise"] == pytest.approx(dob["noise"], rel=0.02)
    assert equal["tracking"] < 0.9 * dob["tracking"]
    assert equal["estimate_free"] < 0.7 * dob["estimate_free"]
    assert 0.8 < equal["estimate"] / dob["estimate"] < 1.2
    same = _figures(1, 100.0, paper.PLANT, coulomb=True)
    assert same["tracking"] < 0.6 * dob["tracking"]
    assert same["estimate_free"] < 0.8 * dob["estimate_free"]
    # the Coulomb term subtracted: the noise-free estimate error is 3x below the viscous
    # model's (1.9e-3 against 6.2e-3 N m for the DOb, 20 seeds; test: < 0.5)
    assert dob["estimate_free"] < 0.5 * _figures(0, 100.0, paper.PLANT, seeds=[0])["estimate_free"]
