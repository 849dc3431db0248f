"""The Kalman disturbance observer: tests that kill the mutants benchmarks/mutation.py found
surviving."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import ServoModel, design_observer, estimation_response
from hpdob.observers import design_eso, design_kalman, kalman_process_noise

MODEL = ServoModel(2.8e-4, 1e-5).discretize(1e-3)


@pytest.mark.parametrize("order", [0, 1])
def test_process_noise_for_a_bandwidth_scales_with_the_inertia(order):
    """With b_n = 0 the model's input enters as tau / J_n: the filter of (J_n, q) has the poles
    of (1, q / J_n), so the process noise giving a bandwidth is proportional to J_n, for an
    inertia of a small motor as for a heavy axis (where the search's bracket sits at q >> 1)."""
    asked = {"order": order, "bandwidth": 100.0, "position_noise_std": 1e-4}
    unit = kalman_process_noise(ServoModel(1.0).discretize(1e-3), **asked)
    for J in (2.8e-4, 2.8e2, 2.8e5):
        q = kalman_process_noise(ServoModel(J).discretize(1e-3), **asked)
        # brentq stops at 1e-6 in log10(q): both ends to ~2.3e-6 relative
        np.testing.assert_allclose(q, J * unit, rtol=1e-5)


@pytest.mark.parametrize(
    "design",
    [
        design_observer(MODEL, order=1, bandwidth=100.0),
        design_observer(MODEL, order=1, bandwidth=100.0, measurement="position"),
        design_eso(MODEL, bandwidth=200.0),
        design_kalman(MODEL, order=1, position_noise_std=1e-4, process_noise_std=1.0),
    ],
    ids=["order-m", "position", "eso", "kalman"],
)
def test_design_reprs_name_the_parameters_not_the_matrices(design):
    """A design's repr identifies it by its parameters on one line; its gain and covariance
    arrays are attributes, not part of the repr (as the notebook table, test_notebook_repr)."""
    text = repr(design)
    assert "array(" not in text and "\n" not in text, text


@pytest.mark.parametrize(("order", "bandwidth"), [(0, 0.5), (3, 10.0), (4, 3.0), (4, 10.0)])
def test_process_noise_reaches_low_bandwidths_at_every_order(order, bandwidth):
    """The search centres its bracket on q ~ r J / Ts^2 (g Ts)^(m + 2): at a bandwidth far
    below the sampling rate the (g Ts)^(m + 2) factor spans many decades, and the design at the
    q found has the asked bandwidth (the -3 dB point of |Q|) to 1 %."""
    model = ServoModel(2.8e-4).discretize(1e-3)
    q = kalman_process_noise(model, order=order, bandwidth=bandwidth, position_noise_std=1e-4)
    design = design_kalman(model, order=order, position_noise_std=1e-4, process_noise_std=q)
    w = np.geomspace(bandwidth / 1.01, bandwidth * 1.01, 3)
    gain = np.abs(estimation_response(design, w / (2 * np.pi)))
    assert gain[0] > 1 / np.sqrt(2) > gain[-1], gain


def test_a_bandwidth_above_half_the_nyquist_frequency_is_refused():
    """kalman_process_noise searches bandwidths below pi / (2 Ts) only (1570.8 rad/s at 1 ms)."""
    model = ServoModel(2.8e-4).discretize(1e-3)
    with pytest.raises(ValueError, match=r"below half the Nyquist frequency pi/\(2 Ts\) = 1570\.8"):
        kalman_process_noise(model, bandwidth=1600.0, position_noise_std=1e-6)
