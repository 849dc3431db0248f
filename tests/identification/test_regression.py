"""The regression's rows (identification/_regression.py): which rows the adaptive defaults drop
as the log's rests; and positions too short to filter or to read a spectrum from."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import identify
from hpdob._validation import ParameterValueError
from hpdob.identification import differentiate
from hpdob.identification._regression import REST_SPEED_FRACTION, rest_rows_mask, signal_bandwidth


def test_a_rest_and_its_margin_are_dropped_and_a_brief_reversal_is_kept():
    """Speed 1 for 300 samples, at rest for 200, -1 for 300, through 0 for 5 samples, then 1;
    rows every 10 samples, rests longer than 10 samples, margin 20: the rows from 280 to 510
    are dropped (the rest and 20 samples either side), the reversal at 800 is not a rest."""
    velocity = np.concatenate([np.ones(300), np.zeros(200), -np.ones(300), np.zeros(5),
                               np.ones(195)])  # fmt: skip
    index = np.arange(0, 1000, 10)
    resting, speed = rest_rows_mask(velocity, index, 10, 20)
    assert speed == REST_SPEED_FRACTION * 1.0
    np.testing.assert_array_equal(index[resting], np.arange(280, 520, 10))


def test_slow_but_not_resting_motion_is_kept():
    """A sine has no rests: it passes through zero speed in a few samples."""
    t = np.arange(20000) * 1e-3
    velocity = np.cos(2 * np.pi * 2.0 * t)
    index = np.arange(0, t.size, 20)
    resting, _ = rest_rows_mask(velocity, index, 20, 40)
    assert not resting.any()
    # the same sine with holds of 0.5 s at every other zero crossing
    held = np.where((t % 1.0) < 0.5, 0.0, velocity)
    resting, _ = rest_rows_mask(held, index, 20, 40)
    assert 0.45 < resting.mean() < 0.6


@pytest.mark.parametrize(
    ("n", "kwargs", "message"),
    [
        (2, {}, r"x must be positions \[rad or m\] of at least 3 samples .* got 2"),
        (20, {"like": [0.0, 1.0]}, r"like must be .* at least 3 samples .* got 2"),
        (15, {"cutoff": 50.0}, r"x must be .* more than 15 samples \(the padding .* got 15"),
        (6, {"cutoff": 50.0, "order": 1}, r"more than 6 samples .* order-1 filter.* got 6"),
    ],
)
def test_differentiate_refuses_a_position_too_short_naming_it(n, kwargs, message):
    """Too short for the filter run forward and backward (scipy's sosfiltfilt pads three times
    the filter's taps: 5 at order 4, 2 at order 1), or for the spectrum the default cut-off is
    read from (a second difference of at least one sample): a ParameterValueError naming the
    parameter, not scipy's or the spectrum's bare ValueError."""
    with pytest.raises(ParameterValueError, match=message):
        differentiate(np.linspace(0.0, 1.0, n), 1e-3, **kwargs)
    velocity, _ = differentiate(np.linspace(0.0, 1.0, 16), 1e-3, cutoff=50.0)  # 16 will do
    assert velocity.shape == (16,)


def test_a_log_too_short_for_a_spectrum_is_refused_as_too_short():
    """Two samples have no second difference, so no spectrum: no signal bandwidth (0), and
    identify's adaptive defaults refuse the log as too short to identify (they raised
    scipy-welch's bare 'nperseg' ValueError before)."""
    assert signal_bandwidth(np.array([0.0, 1.0]), 1e-3) == 0.0
    t = np.arange(2) * 1e-3
    with pytest.raises(ParameterValueError, match="the log is too short to identify: 2 samples"):
        identify(t, np.array([0.0, 1e-3]), np.zeros(2), method="auto")
