"""Tests of the built-in reference and disturbance signals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hpdob.signals import (
    Chirp,
    Constant,
    Noise,
    Ramp,
    Sine,
    SmoothStep,
    Step,
    Sum,
    trajectory,
)

SMOOTH = [
    SmoothStep(0.2, 1.2, 1.0),
    Sine(0.3, 1.5, start=-1.0, phase=0.4, offset=0.1),
    Chirp(0.5, 0.5, 3.0, start=-1.0, stop=5.0),
    Ramp(-1.0, 0.7),
    Constant(2.0),
    SmoothStep(0.0, 2.0, -1.0) + 3.0 * Sine(0.1, 2.0, start=-1.0),
]


@pytest.mark.parametrize("signal", SMOOTH, ids=repr)
def test_derivatives_match_finite_differences(signal):
    t = np.linspace(0.05, 1.95, 97)
    h = 1e-5
    for n in (1, 2):
        numeric = (signal.derivative(t + h, n - 1) - signal.derivative(t - h, n - 1)) / (2 * h)
        scale = max(1.0, np.max(np.abs(numeric)))
        np.testing.assert_allclose(signal.derivative(t, n), numeric, atol=1e-6 * scale)


def test_smooth_step_is_the_quintic():
    s = SmoothStep(0.2, 1.2, 2.0)
    t = np.array([0.0, 0.2, 0.45, 0.7, 1.2, 3.0])
    x = np.clip((t - 0.2) / 1.0, 0, 1)
    np.testing.assert_allclose(s(t), 2.0 * (10 * x**3 - 15 * x**4 + 6 * x**5), atol=1e-15)
    np.testing.assert_allclose(s.derivative(np.array([0.2, 1.2]), 1), 0.0, atol=1e-15)
    np.testing.assert_allclose(s.derivative(np.array([0.2, 1.2]), 2), 0.0, atol=1e-15)
    assert s.derivative(np.array([0.7]), 1)[0] == pytest.approx(2.0 * 30 / 16)  # peak speed


def test_canonical_reference_formula():
    """1 + 0.5 (1 - cos(pi (t - 4))) for t >= 4 from the built-ins."""
    ref = SmoothStep(0.2, 1.2, 1.0) + Sine(-0.5, 0.5, start=4.0, phase=math.pi / 2, offset=0.5)
    t = np.linspace(4.0, 10.0, 61)
    np.testing.assert_allclose(ref(t), 1 + 0.5 * (1 - np.cos(np.pi * (t - 4))), atol=1e-14)
    assert ref(np.array([3.9]))[0] == 1.0


def test_step_and_sine_disturbance():
    d = Step(1.5005, 0.05) + Sine(0.02, 2.0, start=2.5005)
    np.testing.assert_allclose(d(np.array([1.5, 1.501, 2.5])), [0.0, 0.05, 0.05])
    t = np.array([3.0, 7.3])
    np.testing.assert_allclose(d(t), 0.05 + 0.02 * np.sin(4 * np.pi * (t - 2.5005)))


def test_chirp_frequency_sweep():
    c = Chirp(1.0, 1.0, 5.0, start=0.0, stop=2.0)
    t = np.array([0.25, 1.0])  # instantaneous frequency f0 + (f1 - f0) t / T
    phase = 2 * np.pi * (1.0 * t + 0.5 * 2.0 * t**2)
    np.testing.assert_allclose(c(t), np.sin(phase))
    assert c(np.array([2.0]))[0] == 0.0
    with pytest.raises(ValueError, match="derivatives up to n=2"):
        c.derivative(t, 3)


def test_noise_is_seeded_and_grid_independent():
    a = Noise(0.1, hold=0.01, stop=1.0, seed=4)
    b = Noise(0.1, hold=0.01, stop=1.0, seed=4)
    fine = np.linspace(0, 0.999, 10_000)
    np.testing.assert_array_equal(a(fine), b(fine))
    coarse = fine[::7]
    np.testing.assert_array_equal(a(coarse), a(fine)[::7])  # value depends on t only
    assert not np.array_equal(a(fine), Noise(0.1, hold=0.01, stop=1.0, seed=5)(fine))
    assert np.std(a(fine)) == pytest.approx(0.1, rel=0.25)
    assert a(np.array([-0.1, 1.0, 2.0])).tolist() == [0.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="Noise has no derivative"):
        a.derivative(fine, 1)


def test_arithmetic():
    s = 2.0 * Step(0.0, 1.0) - Constant(0.5) + Ramp(0.0, 1.0) * 3
    assert isinstance(s, Sum)
    np.testing.assert_allclose(s(np.array([1.0])), [2.0 - 0.5 + 3.0])
    np.testing.assert_allclose((-Constant(1.0))(np.array([0.0])), [-1.0])
    assert s == 2.0 * Step(0.0, 1.0) - Constant(0.5) + Ramp(0.0, 1.0) * 3


def test_trajectory():
    r, rd, rdd = trajectory(Sine(1.0, 1.0))(np.array([0.0]))
    assert (r[0], rd[0], rdd[0]) == pytest.approx((0.0, 2 * np.pi, 0.0), abs=1e-12)
    with pytest.raises(TypeError, match="signal must be an hpdob Signal"):
        trajectory(lambda t: t)


@pytest.mark.parametrize(
    ("factory", "pattern"),
    [
        (lambda: SmoothStep(1.0, 1.0, 1.0), r"^end must be after start=1.0, got 1.0"),
        (lambda: Sine(1.0, 0.0), r"^frequency must be a positive finite frequency \[Hz\]"),
        (lambda: Sine(1.0, 1.0, start=math.nan), r"^start must be a finite time"),
        (lambda: Chirp(1.0, -1.0, 2.0, 0.0, 1.0), r"^f0 must be a non-negative"),
        (lambda: Chirp(1.0, 1.0, 2.0, 1.0, 0.5), r"^stop must be after start"),
        (lambda: Noise(-0.1, hold=0.1, stop=1.0), r"^std must be a non-negative"),
        (lambda: Noise(0.1, hold=0.0, stop=1.0), r"^hold must be a positive"),
        (lambda: Noise(0.1, hold=1e-12, stop=1.0), r"needs 1000000000000 samples"),
        (lambda: Step(math.inf, 1.0), r"^time must be a finite time"),
    ],
)
def test_bad_parameters(factory, pattern):
    with pytest.raises(ValueError, match=pattern):
        factory()


def test_bad_types():
    with pytest.raises(TypeError, match=r"^amplitude must be"):
        Step(0.0, "big")
    with pytest.raises(TypeError, match=r"^seed must be"):
        Noise(0.1, hold=0.1, stop=1.0, seed=1.5)
    with pytest.raises(ValueError, match=r"^n must be a non-negative integer"):
        Constant(1.0).derivative(np.zeros(2), -1)


@pytest.mark.parametrize(
    "signal",
    [
        Constant(1.0),
        Step(0.5, 1.0),
        Ramp(0.1, 2.0),
        SmoothStep(0.0, 1.0, 1.0),
        Sine(1.0, 2.0, start=0.1, phase=0.3, offset=0.2),
        Chirp(1.0, 1.0, 5.0, 0.0, 2.0),
        Sine(1.0, 1.0) + Ramp(0.0, 1.0),
    ],
    ids=lambda s: type(s).__name__,
)
@pytest.mark.parametrize("n", [0, 1, 2])
def test_scalar_times_give_the_array_values(signal, n):
    # A scalar t gives a 0-d result equal to the same time evaluated inside an array.
    times = np.array([0.05, 0.7, 1.5])
    values = signal.derivative(times, n)
    for t, expected in zip(times, values, strict=True):
        value = signal.derivative(float(t), n)
        assert np.shape(value) == ()
        np.testing.assert_allclose(float(value), expected, rtol=1e-14, atol=1e-14)


def test_noise_at_a_scalar_time():
    noise = Noise(0.1, 0.01, 2.0, seed=1)
    assert float(noise(0.7)) == noise(np.array([0.7]))[0]


def _bits(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=np.float64).view(np.int64)


#: Terms that start late, early or mid-grid, of either sign (a -0 of each kind).
TERMS = [
    (1.0, SmoothStep(0.2, 1.2, 1.0)),
    (-2.0, SmoothStep(0.5, 0.9, -0.3)),
    (1.0, Sine(-0.5, 0.5, start=4.0, phase=math.pi / 2, offset=0.5)),
    (-0.7, Sine(0.02, 2.0, start=0.6)),
    (1.0, Step(1.5005, 0.05)),
    (-1.0, Step(0.3, -0.2)),
    (0.5, Ramp(0.7, -0.4)),
    (1.0, Chirp(0.5, 0.5, 3.0, start=2.0, stop=5.0)),
    (3.0, Constant(0.0)),
    (1.0, Constant(-1.5)),
]


@pytest.mark.parametrize("last", [0.1, 0.55, 1.0, 1.6, 10.0])
@pytest.mark.parametrize("n", [0, 1, 2])
def test_a_sum_skips_silent_terms_with_the_bits_of_every_term_added(last, n):
    """Terms that are 0 over the whole grid (they start after it, or their derivative is 0)
    are not evaluated; the sum is the one of every term added in order, bit for bit (signed
    zeros included), on grids ending before, inside and after the terms' starts."""
    rng = np.random.default_rng(round(100 * last) + n)
    for trial in range(20):
        chosen = [TERMS[i] for i in rng.choice(len(TERMS), size=rng.integers(1, 5))]
        t = np.sort(rng.uniform(-0.5, last, size=rng.integers(1, 300)))
        t[-1] = last
        total = np.zeros_like(t)
        for weight, signal in chosen:
            total = total + weight * signal.derivative(t, n)
        got = Sum(tuple(chosen)).derivative(t, n)
        assert np.array_equal(_bits(got), _bits(total)), (trial, chosen)


def test_a_sum_of_silent_terms_still_refuses_what_a_term_would():
    """Skipping a term loses none of its errors: a bad order, a Sine derivative beyond the
    float range and a Chirp beyond n = 2 raise although the grid ends before they start."""
    early = np.linspace(0.0, 1.0, 11)
    with pytest.raises(ValueError, match="n must be"):
        Sum(((1.0, Step(5.0, 1.0)),)).derivative(early, -1)
    with pytest.raises(ValueError, match="exceeds the float range"):
        Sum(((1.0, Sine(1.0, 1e300, start=5.0)),)).derivative(early, 2)
    with pytest.raises(ValueError, match="up to n=2"):
        Sum(((1.0, Chirp(1.0, 1.0, 2.0, start=5.0, stop=6.0)),)).derivative(early, 3)
    with pytest.raises(ValueError, match="no derivative"):
        Sum(((1.0, Noise(1.0, 0.01, start=5.0, stop=6.0)),)).derivative(early, 1)


def test_a_subclass_that_changes_the_derivative_is_always_evaluated():
    """A user's subclass of a built-in signal that overrides derivative (not where it is
    silent) is evaluated even before the parent's start: its own values count."""

    class Shifted(Sine):
        def derivative(self, t, n=0):
            return super().derivative(t, n) + 1.0

    t = np.linspace(0.0, 1.0, 5)
    signal = Shifted(1.0, 1.0, start=5.0)
    assert np.array_equal(Sum(((2.0, signal),)).derivative(t), 2.0 * signal.derivative(t))


def test_a_sum_of_silent_terms_gives_the_type_and_orders_of_every_term_added():
    """What skipping must not change besides the bits: a scalar time gives a numpy scalar
    (as adding a term does: JSON- and hash-able), an empty sum its zeros, and an order the
    sum does not know (a user's term that takes n = -1) still goes to the terms."""
    late = Step(1.0, 2.0) + Sine(0.5, 1.0, start=1.0)
    value = late(0.0)
    assert isinstance(value, float) and value == 0.0 and not np.signbit(value)
    assert np.array_equal(late(np.array([0.0, 0.5])), [0.0, 0.0])
    assert Sum(()).derivative(0.0, -1) == 0.0

    class Integral(Sine):
        def derivative(self, t, n=0):
            t = np.asarray(t, dtype=float)
            return t if n == -1 else super().derivative(t, n)

    assert np.array_equal(Sum(((1.0, Integral(1.0, 1.0, start=5.0)),)).derivative([2.0], -1),
                          [2.0])  # fmt: skip
