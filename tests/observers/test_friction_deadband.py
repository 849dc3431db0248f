"""The dead band on the RTOB's Coulomb term (docs/force-control.md, "The Coulomb term's dead
band"): tau_reac = tau^R - Delta_b omega - c tanh(dz_d(w)/v), dz_d(w) = w -+ d beyond +-d and 0
between, with d the velocity resolution of the measurement path (one encoder count through the
velocity filter). Reference values are derived here from the formulas, not read from the code:
the resolution (1 - exp(-omega_f Ts)) q / Ts, the one-count spike's move of the term (0 with the
dead band, c tanh(d / v) without) and the count train's bound c tanh(d a^M / ((1 - a^M) v))."""

from __future__ import annotations

import math

import numpy as np
import pytest

from force_step import force_step_run  # tests/force_step.py
from hpdob import (
    Observer,
    ParameterTypeError,
    ParameterValueError,
    design_observer,
    paper,
)
from hpdob.observers import (
    CoulombFriction,
    coulomb_torque,
    coulomb_velocity_resolution,
    design_reaction_observer,
    outputs,
    reaction_torque_observer,
)

TS = paper.TS
MODEL = paper.NOMINAL.discretize(TS)
PLANT = paper.PLANT  # c = 0.01 N m, v = 0.01 rad/s
DELTA_B = PLANT.b - paper.NOMINAL.b
COUNTS = paper.VIRTUAL_SENSOR.counts_per_rev  # 16384
Q = 2 * math.pi / COUNTS  # one count [rad]
A = math.exp(-100.0 * TS)  # the 100 rad/s velocity filter's pole
RESOLUTION = (1 - A) * Q / TS  # one count through the filter: 0.0365 rad/s


def _dob():
    return design_observer(MODEL, order=1, bandwidth=100.0)


def _rtob(deadband=0.0):
    return reaction_torque_observer(_dob(), friction=PLANT, velocity_filter=100.0,
                                    coulomb_deadband=deadband)  # fmt: skip


def test_the_dead_banded_term_is_the_literal_formula():
    """c tanh(dz_d(w)/v) against numpy's sign/maximum form; with d = 0 it is the plain term's
    c * math.tanh(w / v) to the last bit; a NaN velocity stays NaN."""
    c, v, d = 0.01, 0.01, RESOLUTION
    w = np.concatenate([np.linspace(-0.2, 0.2, 401), [d, -d, np.nextafter(d, 1.0), 0.0, -0.0]])
    expected = c * np.tanh(np.sign(w) * np.maximum(np.abs(w) - d, 0.0) / v)
    got = np.array([coulomb_torque(c, v, float(x), d) for x in w])
    np.testing.assert_allclose(got, expected, rtol=1e-15, atol=1e-18)  # math vs numpy tanh
    assert np.all(got[np.abs(w) <= d] == 0.0) and np.all(got[np.abs(w) > d + 1e-3] != 0.0)
    assert all(coulomb_torque(c, v, float(x), 0.0) == c * math.tanh(float(x) / v) for x in w)
    assert math.isnan(coulomb_torque(c, v, math.nan, d))
    term = CoulombFriction(c, v, "omega_hat", d)
    assert term.torque(0.05) == c * math.tanh((0.05 - d) / v)
    assert term.torque(-0.05) == c * math.tanh((-0.05 + d) / v)


def test_the_resolution_is_one_count_through_the_velocity_path():
    """(1 - exp(-omega_f Ts)) q / Ts through the low-pass, q / Ts for the measured velocity
    itself, and for a position-only observer the largest |omega_hat| of the runtime observer
    (stepped here independently) after one count from rest."""
    assert coulomb_velocity_resolution(_rtob(), counts_per_rev=COUNTS) == pytest.approx(
        RESOLUTION, rel=1e-12
    )
    slow = reaction_torque_observer(_dob(), friction=PLANT, velocity_filter=30.0)
    assert coulomb_velocity_resolution(slow, counts_per_rev=COUNTS) == pytest.approx(
        (1 - math.exp(-30.0 * TS)) * Q / TS, rel=1e-12
    )
    raw = reaction_torque_observer(_dob(), friction=PLANT)
    assert coulomb_velocity_resolution(raw, counts_per_rev=COUNTS) == Q / TS
    position_only = design_observer(MODEL, order=1, bandwidth=100.0, measurement="position")
    pos = reaction_torque_observer(position_only, coulomb=0.01)
    runtime = Observer.of(pos)
    runtime.reset((0.0, 0.0))
    peak = 0.0
    for _ in range(2000):
        y = outputs(pos, tuple(map(float, runtime.state)), Q)
        peak = max(peak, abs(y[pos.outputs.index("omega_hat")]))
        runtime.update(Q, 0.0)
    assert coulomb_velocity_resolution(pos, counts_per_rev=COUNTS) == pytest.approx(peak, 1e-12)
    assert peak > Q / TS / 10  # the estimate answers the count: not vacuous


def _coulomb_part(system, theta, omega):
    """The Coulomb term the composition subtracts at each sample (Python runtime): the DOb's
    tau_hat minus Delta_b omega minus tau_reac, u = 0, from rest."""
    runtime = Observer.of(system)
    runtime.reset((0.0, 0.0))
    part, w = [], []
    for th, om in zip(theta, omega, strict=True):
        y = outputs(system, tuple(map(float, runtime.state)), (float(th), float(om)))
        part.append(y[0] - DELTA_B * om - y[-1])
        w.append(y[1])
        runtime.update((float(th), float(om)), 0.0)
    return np.array(part), np.array(w)


def _counts(n, every, start=50):
    """Angle and backward-difference velocity of an axis that gains one count every ``every``
    samples from sample ``start`` on."""
    steps = np.zeros(n)
    steps[start::every] = 1.0
    theta = np.cumsum(steps) * Q
    return theta, steps * Q / TS


def test_an_isolated_count_change_leaves_the_term_at_zero():
    """One count from rest: the low-passed velocity jumps to d = (1 - a) q / Ts. Without the
    dead band the term answers with c tanh(d / v) = 0.9986 c (X = c tanh(3.65)); with the dead
    band at the resolution it stays at 0 (X = 0, to round-off: 1e-15 N m)."""
    theta, omega = _counts(400, 10**6)  # a single count at sample 50
    plain, w = _coulomb_part(_rtob(), theta, omega)
    assert np.max(w) == pytest.approx(RESOLUTION, rel=1e-12)
    assert np.max(plain) == pytest.approx(0.01 * math.tanh(RESOLUTION / 0.01), rel=1e-9)
    d = coulomb_velocity_resolution(_rtob(), counts_per_rev=COUNTS)
    banded, _ = _coulomb_part(_rtob(d), theta, omega)
    assert np.max(np.abs(banded)) <= 1e-15


@pytest.mark.parametrize("every", [5, 10, 38, 100])
def test_a_count_train_moves_the_term_by_at_most_the_derived_bound(every):
    """A count every M samples (an axis creeping at q / (M Ts)): the filtered velocity peaks at
    d / (1 - a^M) just after each count, so the dead-banded term is at most
    X(M) = c tanh(d a^M / ((1 - a^M) v)), reached as the train settles; without the dead band
    each count moves it by at least c tanh(d / v). At a count per 10 samples (0.038 rad/s, the
    resolution itself) X = 0.97 c: motion the sensor resolves is compensated."""
    theta, omega = _counts(3000, every)
    d = coulomb_velocity_resolution(_rtob(), counts_per_rev=COUNTS)
    banded, _ = _coulomb_part(_rtob(d), theta, omega)
    aM = A**every
    bound = 0.01 * math.tanh(RESOLUTION * aM / ((1 - aM) * 0.01))
    assert np.max(banded) <= bound * (1 + 1e-9) + 1e-15
    assert np.max(banded[-500:]) >= 0.999 * bound  # attained: the bound is tight
    plain, _ = _coulomb_part(_rtob(), theta, omega)
    assert np.max(plain[-500:]) >= 0.01 * math.tanh(RESOLUTION / 0.01)
    if every >= 38:  # creeping at or below v = 0.01 rad/s: under a tenth of c
        assert bound < 0.1 * 0.01


def test_no_dead_band_is_the_old_term_bit_for_bit():
    """coulomb_deadband = 0 builds the same observer (matrices and term) as leaving it out, and
    the kernel's run is the same to the last bit."""
    old = reaction_torque_observer(_dob(), friction=PLANT, velocity_filter=100.0)
    new = _rtob(0.0)
    assert new.coulomb == old.coulomb == CoulombFriction(0.01, 0.01, "omega_hat")
    for name in ("F", "G", "H", "E", "N"):
        np.testing.assert_array_equal(getattr(new, name), getattr(old, name))
    a, b = force_step_run(old), force_step_run(new)
    for name in ("tau_reac", "tau_contact", "u", "theta"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_kernel_and_python_runtime_agree_bit_for_bit_with_the_dead_band():
    """The compiled kernel's tau_reac is the Python runtime's to the last bit with a dead band,
    on a trace where the velocity is inside the band at some samples and beyond at others."""
    both = _rtob(RESOLUTION)
    result = force_step_run(both, duration=0.4)
    runtime = Observer.of(both)
    runtime.reset((-0.01, 0.0))
    tau_reac = []
    for k, (th, om) in enumerate(zip(result.theta_measured, result.omega_measured, strict=True)):
        y = outputs(both, tuple(map(float, runtime.state)), (float(th), float(om)))
        tau_reac.append(y[-1])
        runtime.update((th, om), float(result.u[k]))
    np.testing.assert_array_equal(result.tau_reac, tau_reac)
    w = np.abs(result.omega_hat)
    assert np.any((w > 0) & (w <= RESOLUTION)) and np.any(w > RESOLUTION + 0.02)


def test_bad_dead_bands_are_refused_naming_the_parameter():
    with pytest.raises(ParameterValueError, match=r"^coulomb_deadband must be a non-negative"):
        _rtob(-1e-3)
    with pytest.raises(ParameterValueError, match=r"^coulomb_deadband must be a non-negative"):
        _rtob(math.nan)
    with pytest.raises(ParameterTypeError, match=r"^coulomb_deadband must be"):
        _rtob("encoder")  # the scenario file's and the map's word, not the function's
    with pytest.raises(ParameterValueError, match=r"^coulomb_deadband = 0.01 is the Coulomb"):
        reaction_torque_observer(_dob(), viscous=DELTA_B, coulomb_deadband=0.01)
    with pytest.raises(ParameterValueError, match=r"^coulomb_deadband must be a non-negative"):
        CoulombFriction(0.01, 0.01, "omega", -1.0)
    with pytest.raises(ParameterValueError, match=r"has no Coulomb term"):
        coulomb_velocity_resolution(reaction_torque_observer(_dob(), viscous=DELTA_B),
                                    counts_per_rev=COUNTS)  # fmt: skip
    with pytest.raises(ParameterValueError, match=r"^counts_per_rev must be a positive"):
        coulomb_velocity_resolution(_rtob(), counts_per_rev=0)


def test_the_design_keeps_the_dead_band():
    """design_reaction_observer carries it into its system and into ``friction`` (the
    scenario file's keys), and a design with the Coulomb term off leaves it out."""
    design = design_reaction_observer(_dob(), friction=PLANT, velocity_filter=100.0,
                                      coulomb_deadband=np.float64(RESOLUTION))  # fmt: skip
    assert type(design.coulomb_deadband) is float
    assert design.system.coulomb.deadband == RESOLUTION
    assert design.friction["coulomb_deadband"] == RESOLUTION
    assert "coulomb_deadband" not in design_reaction_observer(_dob(), viscous=DELTA_B).friction
