"""The disturbance evaluated inside the compiled loop at the sub-step midpoints: bit for bit the
numpy evaluation it replaces, for every form it takes; the others still sampled."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from hpdob import PD, Encoder, ServoLoop, ServoModel, paper, simulate
from hpdob.signals import Chirp, Constant, Noise, Ramp, Sine, SmoothStep, Step, Sum
from hpdob.simulation import run_loop, sample_signals

LOOP = ServoLoop(
    plant=ServoModel(3.06e-4, 5e-5, coulomb=0.01, coulomb_velocity=0.01),
    nominal=ServoModel(2.8e-4),
    Ts=1e-3,
    controller=PD(50.0, 5.0),
    observer={"order": 1, "bandwidth": 100.0},
    sensor=Encoder(16384),
)
REFERENCE = Sine(0.3, 1.5)

INLINE = {
    "constant": Constant(0.01),
    "step": Step(0.1005, 0.05),
    "ramp": Ramp(0.05, -0.2),
    "sine": Sine(0.02, 7.0, start=0.0503, phase=0.3, offset=-0.004),
    "bare sine": Sine(0.02, 3.0),
    "sum": Step(0.1005, 0.05) + Sine(0.02, 2.0, start=0.2005) - 0.5 * Ramp(0.1, 0.3),
    "scaled": -3.0 * Step(0.05, 0.01),
    "canonical": paper.DISTURBANCE,
}
SAMPLED = {
    "smooth step": SmoothStep(0.1, 0.2, 0.05),
    "chirp": Chirp(0.02, 1.0, 20.0, 0.0, 0.3),
    "noise": Noise(0.01, 1e-3, 0.3, seed=3),
    "nested sum": Sum(((1.0, Step(0.1, 0.05) + Constant(0.01)),)),
    "sum with a smooth step": Step(0.1, 0.05) + SmoothStep(0.1, 0.2, 0.05),
    "overflowing ramp": Ramp(0.0, 1e305),
}
NAMES = ("theta", "omega", "u", "tau_hat", "tau_dn", "tau_ext", "theta_measured")


def _assert_identical(a, b):
    for name in NAMES:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.mark.parametrize("name", sorted(INLINE))
def test_inline_disturbance_is_the_sampled_one_bit_for_bit(name):
    """The same signal run from its table (inline) and through a plain callable (sampled in
    numpy on the n * substeps midpoints, as before): identical results."""
    disturbance = INLINE[name]
    signals = sample_signals(REFERENCE, disturbance, Ts=1e-3, n=300, substeps=8)
    assert signals.midpoint is not None and signals.tau_mid.size == 0  # no midpoint array
    inline = simulate(LOOP, reference=REFERENCE, disturbance=disturbance, duration=0.3)
    sampled = simulate(LOOP, reference=REFERENCE, duration=0.3,
                       disturbance=lambda t: disturbance(t))  # fmt: skip
    _assert_identical(inline, sampled)


@pytest.mark.parametrize("name", sorted(SAMPLED))
def test_other_signals_are_sampled(name):
    signals = sample_signals(REFERENCE, SAMPLED[name], Ts=1e-3, n=300, substeps=8)
    assert signals.midpoint is None and signals.tau_mid.size == 300 * 8


def test_the_canonical_run_is_unchanged():
    """Canonical HPDOb-100 (10 s): the disturbance from its table equals it sampled."""
    kw = {**paper.scenario(), "observer": paper.observer("HPDOb-100").design}
    inline = simulate(**kw)
    disturbance = kw.pop("disturbance")
    sampled = simulate(**kw, disturbance=lambda t: disturbance(t))
    _assert_identical(inline, sampled)


def test_a_scaled_disturbance_is_the_scaled_samples():
    """``SampledSignals.scaled`` (the sweep's disturbance scale): factor * value, as the numpy
    product of the sampled arrays gives it; scaled twice, f2 * (f1 * value)."""
    disturbance = INLINE["sum"]
    inline = sample_signals(REFERENCE, disturbance, Ts=1e-3, n=300, substeps=8)
    sampled = sample_signals(REFERENCE, lambda t: disturbance(t), Ts=1e-3, n=300, substeps=8)
    for factors in ((0.7,), (0.7, -1.3)):
        a, b = inline, sampled
        for f in factors:
            a, b = a.scaled(f), b.scaled(f)
        x0 = np.zeros(2)
        _assert_identical(run_loop(LOOP, a, x0), run_loop(LOOP, b, x0))
        np.testing.assert_array_equal(a.midpoints(), b.tau_mid)


@numba.njit
def _numba_sin(x):
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = math.sin(x[i])
    return out


def test_numpy_and_numba_sines_agree():
    """The premise of evaluating Sine inline: numpy's float64 sin and numba's (libm) are the
    same function on this platform (0 differences measured over 6 million arguments)."""
    x = np.random.default_rng(0).uniform(-1e4, 1e4, 200_000)
    np.testing.assert_array_equal(np.sin(x), _numba_sin(x))


def test_signals_are_sampled_once_per_time_grid():
    """hpdob's Signals on one grid are sampled once and shared read-only (equal signals give
    equal samples); a plain callable is evaluated on every call; a new grid is sampled anew."""
    disturbance = Step(0.1005, 0.05) + Sine(0.02, 2.0)
    first = sample_signals(REFERENCE, disturbance, Ts=1e-3, n=300, substeps=8)
    again = sample_signals(Sine(0.3, 1.5), Step(0.1005, 0.05) + Sine(0.02, 2.0), Ts=1e-3, n=300,
                           substeps=8)  # fmt: skip
    assert not first.r.flags.writeable and again.midpoint is first.midpoint  # not re-sampled
    np.testing.assert_array_equal(again.r, first.r)
    assert not np.shares_memory(again.r, first.r)  # a result's columns are its own
    other = sample_signals(REFERENCE, disturbance, Ts=1e-3, n=200, substeps=8)
    assert other is not first
    calls = []

    def counted(t):
        calls.append(t.size)
        return disturbance(t)

    for _ in range(2):
        sample_signals(REFERENCE, counted, Ts=1e-3, n=300, substeps=8)
    assert calls == [300, 2400, 300, 2400]
    a = simulate(LOOP, reference=REFERENCE, disturbance=disturbance, duration=0.3)
    b = simulate(LOOP, reference=REFERENCE, disturbance=disturbance, duration=0.3)
    _assert_identical(a, b)


def test_the_grid_cache_is_bounded():
    from hpdob.simulation import _simulate

    for i in range(_simulate.SAMPLED_GRIDS + 5):
        sample_signals(REFERENCE, Step(0.001 * i, 1.0), Ts=1e-3, n=50, substeps=2)
    assert len(_simulate._SAMPLED) <= _simulate.SAMPLED_GRIDS


def test_a_signal_class_written_elsewhere_is_sampled_on_every_call():
    class Counting(Step):
        calls = 0

        def derivative(self, t, n=0):
            Counting.calls += 1
            return super().derivative(t, n)

    for _ in range(2):
        sample_signals(REFERENCE, Counting(0.1, 1.0), Ts=1e-3, n=30, substeps=2)
    assert Counting.calls == 4  # instants and midpoints, twice
