"""IDIM-LS regression: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from hpdob import identify
from hpdob.identification import _lean, differentiate
from hpdob.identification._regression import (
    MIN_ROWS,
    build_regression,
    minimum_samples,
    near_slow,
    noise_floor,
    resolve_settings,
    rest_rows_mask,
    rows_inside_border,
)


def _analytic_log(Ts: float = 1e-3):
    """Noise-free motion of eq. (1) with J = 2, b = 3, Coulomb 1.5, offset -0.4 (SI units)."""
    t = np.arange(20000) * Ts
    w1, w2 = 2 * np.pi * 0.5, 2 * np.pi * 3.0
    q = 0.3 * np.sin(w1 * t) + 0.05 * np.sin(w2 * t + 0.3)
    qd = 0.3 * w1 * np.cos(w1 * t) + 0.05 * w2 * np.cos(w2 * t + 0.3)
    qdd = -0.3 * w1**2 * np.sin(w1 * t) - 0.05 * w2**2 * np.sin(w2 * t + 0.3)
    return t, q, 2.0 * qdd + 3.0 * qd + 1.5 * np.sign(qd) - 0.4


@pytest.mark.parametrize("decimation", [4, 10])
def test_reported_decimation_cutoff_is_that_of_scipy_decimate(decimation):
    """The reported cut-off is scipy.signal.decimate's: 0.8 of the decimated Nyquist frequency.

    Reference: scipy.signal.decimate's documentation (Chebyshev type I, order 8, cut-off
    0.8/q of the Nyquist frequency), here 0.8 * 500 Hz / q at 1 kHz.
    """
    t, q, u = _analytic_log()
    fit = identify(t, q, u, method="idim-ls", decimation=decimation, diagnostics=False)
    assert fit.settings["decimation"] == decimation
    assert fit.settings["decimation_cutoff"] == pytest.approx(0.8 * 500.0 / decimation)


def test_a_rest_at_either_end_of_the_log_is_dropped():
    """Rests that start at the first sample or last through the last one: their rows and the
    margin inside the log are dropped, the moving middle kept (the marker of a rest's end
    sits one past the last sample)."""
    velocity = np.concatenate([np.zeros(100), np.ones(400), np.zeros(100)])
    index = np.arange(0, 600, 10)
    resting, _ = rest_rows_mask(velocity, index, 10, 20)
    np.testing.assert_array_equal(index[~resting], np.arange(120, 480, 10))


def _log_with_a_rest(Ts: float = 1e-3):
    """A 1 Hz sine for 2 s, 0.3 s at rest, the sine again; the input of a unit inertia."""
    t = np.arange(6000) * Ts
    theta = np.where(t < 2.0, np.sin(2 * np.pi * t),
                     np.where(t < 2.3, 0.0, np.sin(2 * np.pi * (t - 0.3))))  # fmt: skip
    return theta, np.gradient(np.gradient(theta, Ts), Ts)


@pytest.mark.parametrize("min_speed", [0.0, 0.05])
def test_rest_rows_count_the_rows_the_rest_rule_drops(min_speed):
    """A rest is a slow stretch longer than REST_LENGTH (1) decimated row, i.e. 10 samples at
    decimation 10: the 300-sample rest is one. rest_rows is the number of rows dropped for
    rests beyond those the min_speed rule drops already (none with min_speed = 0.05 rad/s,
    which removes the whole rest and its filter lobe)."""
    theta, u = _log_with_a_rest()
    rows = {}
    for rests in (False, True):
        settings = resolve_settings(1e-3, decimation=10, min_speed=min_speed, rests=rests)
        regression = build_regression(theta, u, settings)
        rows[rests] = (regression.X.shape[0], regression.rest_rows)
    assert rows[False][1] == 0
    assert rows[True][1] == rows[False][0] - rows[True][0]
    assert (rows[True][1] > 0) is (min_speed == 0.0)


def test_the_reported_decimation_cutoff_is_not_rounded():
    """0.8 of the decimated Nyquist frequency: 0.8 * 500 Hz / 3 = 133.3 Hz at 1 kHz."""
    settings = resolve_settings(1e-3, decimation=3, cutoff=200.0)
    assert settings.decimation_cutoff == pytest.approx(400.0 / 3)


def test_the_adaptive_cutoff_is_clipped_at_five_twelfths_of_fs_unrounded():
    """A position with motion up to 200 Hz at 1 kHz (a 1 mm sine at 200 Hz over a slow one,
    1e-9 white noise): half its signal bandwidth (about 100 Hz) is above the adaptive
    bandwidth's upper clip fs/12 (83.33 Hz, not 83), so differentiate's default cut-off is
    5 fs/12 exactly (adaptive_bandwidth's documented range, [fs/500, fs/12])."""
    Ts = 1e-3
    t = np.arange(8192) * Ts
    noise = 1e-9 * np.random.default_rng(0).standard_normal(t.size)
    x = np.sin(2 * np.pi * 0.5 * t) + 1e-3 * np.sin(2 * np.pi * 200.0 * t) + noise
    velocity, acceleration = differentiate(x, Ts)
    want = differentiate(x, Ts, cutoff=5.0 * (1.0 / Ts / 12.0))
    assert np.array_equal(velocity, want[0]) and np.array_equal(acceleration, want[1])


@pytest.mark.parametrize("block", [7, 8])
def test_the_quantisation_step_is_found_at_a_block_boundary(monkeypatch, block):
    """noise_floor's step q is the smallest positive step between consecutive samples
    (its docstring), found block by block: wherever the one step of 0.25 among steps of 1
    sits, on either side of a block's end (blocks of 7 and 8 samples), q is 0.25."""
    monkeypatch.setattr(_lean, "BLOCK", block)
    for k in range(40):
        steps = np.ones(40)
        steps[k] = 0.25
        theta = np.concatenate([[0.0], np.cumsum(steps)])
        assert noise_floor(theta, 1e-3)[1] == 0.25, k


@pytest.mark.parametrize("n", [1000, 1001, 1002, 1003, 4098, 4099, 4100, 4101, 9000])
def test_the_noise_floor_is_read_from_scipys_welch_of_the_second_difference(n):
    """The floor is the larger of q^2 Ts / 6 and the median, over the top quarter of the band
    (f >= 0.375 fs), of the position's PSD estimated as scipy.signal.welch of its second
    difference (Blackman-Harris segments of min(n - 2, 4096) samples) over the difference's
    gain (2 sin(pi f Ts))^4 (noise_floor's docstring); bit for bit, at lengths of every
    remainder mod 4 (segment bounds) below and above one segment."""
    Ts = 1e-3
    rng = np.random.default_rng(n)
    theta = np.cumsum(rng.standard_normal(n)) * 1e-3 + 1e-6 * rng.standard_normal(n)
    second = np.diff(theta, 2)
    f, psd = signal.welch(second, fs=1.0 / Ts, window="blackmanharris",
                          nperseg=min(second.size, 4096))  # fmt: skip
    whitened = psd[1:] / (2.0 * np.sin(np.pi * f[1:] * Ts)) ** 4
    q = np.abs(np.diff(theta)).min()
    floor = max(q * q * Ts / 6.0, float(np.median(whitened[f[1:] >= 0.375 / Ts])))
    assert noise_floor(theta, Ts) == (floor, q)


def _near_slow_reference(velocity, index, speed, half):
    """Whether |velocity| < speed anywhere within half samples of each row, one row at a time
    (near_slow's docstring)."""
    return np.array([
        bool(np.any(np.abs(velocity[max(r - half, 0) : r + half + 1]) < speed)) for r in index
    ])  # fmt: skip


@pytest.mark.parametrize("block", [5, 1 << 16])
@pytest.mark.parametrize("start", [0, 3, 6, 7, 8, 9])
def test_near_slow_is_its_definition_row_by_row(monkeypatch, block, start):
    """Rows every 3 samples (odd and even ones) from `start` (below, at and just above the
    window's half width 6: where a row's window is cut by the log's start), slow samples
    within 6 of either end, blocks of 5 rows or one block: the window of +-6 samples around
    each row, counted block by block, is the window taken row by row."""
    monkeypatch.setattr(_lean, "BLOCK", block)
    velocity = np.random.default_rng(start).choice([-1.0, 1.0], 200)
    velocity[[1, 30, 31, 100, 157, 198]] = 0.1  # slow samples, two within 6 of either end
    index = np.arange(start, 200, 3)
    got = near_slow(velocity, index, 0.5, 6)
    want = _near_slow_reference(velocity, index, 0.5, 6)
    assert want.any() and not want.all()
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    ("decimation", "border"), [(1, 0), (1, 50), (3, 7), (4, 50), (10, 50), (10, 0), (7, 23)]
)
def test_minimum_samples_is_the_fewest_that_leave_min_rows(decimation, border):
    """minimum_samples is the fewest raw samples whose rows inside the border number
    MIN_ROWS (its docstring): one sample fewer leaves fewer rows."""
    settings = resolve_settings(1e-3, decimation=decimation, border=border, cutoff=400.0)
    n = minimum_samples(settings)
    assert rows_inside_border(n, settings).size == MIN_ROWS
    assert rows_inside_border(n - 1, settings).size < MIN_ROWS


def test_the_decimation_rule_keeps_at_least_one():
    """decimation = round(0.8 (fs/2) / (2 bandwidth)) (resolve_settings' docstring) rounds to
    0 for a bandwidth of 450 Hz at 1 kHz (0.44): the factor is then 1, no decimation."""
    settings = resolve_settings(1e-3, bandwidth=450.0, cutoff=400.0)
    assert settings.decimation == 1
