"""IDIM-LS regression: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import identify
from hpdob.identification._regression import build_regression, resolve_settings, rest_rows_mask


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
