"""The Kalman disturbance observer (hpdob.observers: design_kalman, kalman_process_noise,
KalmanDisturbanceObserver).

Moved here unchanged from tests/observers/test_peers.py (against filterpy's KalmanFilter sample
by sample), tests/observers/test_realised.py (stability against mpmath eigenvalues at 80
digits) and tests/test_reliability_families.py (issue 16's audit). ``RIGID_MODEL`` is the
frictionless motor those last two used under the name ``MODEL``.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from observer_tools import MODEL, RIGID_MODEL, mp_eigenvalues, trace

from hpdob import (
    KalmanDisturbanceObserver,
    ParameterValueError,
    estimation_response,
)
from hpdob.observers import design_kalman, kalman_process_noise


# -- Kalman -------------------------------------------------------------------------------------
@pytest.mark.parametrize("m", [0, 1])
def test_kalman_equals_filterpy_sample_by_sample(rng, m):
    from filterpy.kalman import KalmanFilter

    r, q = 1e-4, (1e-3 if m == 0 else 2e-5)
    design = design_kalman(MODEL, order=m, position_noise_std=r, process_noise_std=q)
    n = m + 3
    kf = KalmanFilter(dim_x=n, dim_z=1, dim_u=1)
    kf.F = np.array(design.A)
    kf.H = np.array(design.C)
    kf.B = np.array(design.B)[:, None]
    kf.Q = np.zeros((n, n))
    kf.Q[-1, -1] = q * q
    kf.R = np.array([[r * r]])
    kf.P = np.array(design.covariance)  # start from the DARE (steady-state a-priori) covariance
    kf.x = np.zeros((n, 1))
    obs = KalmanDisturbanceObserver(MODEL, order=m, position_noise_std=r, process_noise_std=q)
    theta, u = trace(rng, 400)
    for th, uk in zip(theta, u, strict=True):
        kf.update(np.array([[th]]))
        tau_hat = obs.estimate(float(th))
        assert tau_hat == pytest.approx(float(kf.x[2, 0]), rel=1e-7, abs=1e-12)
        assert obs.velocity == pytest.approx(float(kf.x[1, 0]), rel=1e-7, abs=1e-9)
        obs.update(float(th), float(uk))
        kf.predict(u=np.array([[uk]]))
    np.testing.assert_allclose(kf.K.ravel(), design.gain, rtol=1e-9)


@pytest.mark.parametrize("m", [0, 1])
def test_kalman_process_noise_gives_the_bandwidth(m):
    r = 2 * math.pi / 16384 / math.sqrt(12)
    q = kalman_process_noise(MODEL, bandwidth=120.0, position_noise_std=r, order=m)
    design = design_kalman(MODEL, order=m, position_noise_std=r, process_noise_std=q)
    assert abs(estimation_response(design, 120.0 / (2 * math.pi))[0]) == pytest.approx(
        1 / math.sqrt(2), rel=1e-3
    )


# -- realised poles (mpmath at 80 digits) ---------------------------------------------------------
@pytest.mark.parametrize(
    ("order", "r", "q", "lowest"),
    # scipy's non-stabilising Riccati answer depends on the LAPACK build: spectral radii (80-digit
    # mpmath eigenvalues of F) 15938.877, 1.018438, 1.064843 on one, 1.02581 and 1.06576 for the
    # last two on another; the refusal, not the exact radius, is the invariant
    [(2, 1e-9, 1e-4, 100.0), (3, 1e-9, 1e-8, 1.0), (4, 1e-9, 1e-12, 1.0)],
)
def test_kalman_designs_that_are_not_stable_are_refused(order, r, q, lowest):
    with pytest.raises(ParameterValueError, match=r"is not stable in double precision") as info:
        design_kalman(RIGID_MODEL, order=order, position_noise_std=r, process_noise_std=q)
    message = str(info.value)
    assert f"position_noise_std={r!r}" in message and f"process_noise_std={q!r}" in message
    shown = float(message.split("spectral radius about ")[1].split(",")[0])
    assert shown > lowest


@pytest.mark.parametrize(("order", "r", "q"), [(0, 1e-9, 1.0), (1, 1e-4, 1e4), (2, 1e-9, 1.0)])
def test_kalman_designs_close_to_the_unit_circle_stay_accepted(order, r, q):
    design = design_kalman(RIGID_MODEL, order=order, position_noise_std=r, process_noise_std=q)
    radius = np.max(np.abs(mp_eigenvalues(design.system.F)))
    assert 0.9999 < radius < 1.0  # measured: 0.99999993, 0.99991, 0.9999989


# -- Kalman: noise levels whose variance leaves the float range; unreachable bandwidths --------
@pytest.mark.parametrize(
    ("name", "value", "how"),
    [
        ("position_noise_std", 1e-300, "underflows to 0"),
        ("process_noise_std", 1e-300, "underflows to 0"),
        ("position_noise_std", 1e300, "overflows"),
        ("process_noise_std", 1e300, "overflows"),
    ],
)
def test_kalman_noise_whose_variance_leaves_the_float_range(name, value, how):
    noise = {"position_noise_std": 1e-4, "process_noise_std": 1e-3, name: value}
    pattern = rf"^{name}={re.escape(repr(value))} is out of range: .*{how}"
    with pytest.raises(ParameterValueError, match=pattern):
        design_kalman(RIGID_MODEL, **noise)  # 1e-300 was accepted, or warned (0/0) on the way


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [  # returned 0.0 (bandwidth 1e-300) or a q that cannot be designed (r = 1e300)
        ({"bandwidth": 1e-300, "position_noise_std": 1e-4}, r"^bandwidth=1e-300 rad/s is not"),
        ({"bandwidth": 100.0, "position_noise_std": 1e300}, r"^position_noise_std=1e\+300 is"),
        ({"bandwidth": 100.0, "position_noise_std": 1e-300}, r"^position_noise_std=1e-300 is"),
    ],
)
def test_kalman_process_noise_never_returns_an_unusable_value(kwargs, pattern):
    with pytest.raises(ParameterValueError, match=pattern):
        kalman_process_noise(RIGID_MODEL, **kwargs)
    q = kalman_process_noise(RIGID_MODEL, bandwidth=1.0, position_noise_std=1e-4, order=2)
    assert q > 0 and design_kalman(
        RIGID_MODEL, order=2, position_noise_std=1e-4, process_noise_std=q
    )


def test_kalman_process_noise_designs_each_process_noise_once(monkeypatch):
    """The bracket's ends are asked by the bracketing loops, the sign check and brentq: each
    trial process noise is designed once (tune calls this six times), the result unchanged."""
    import hpdob.observers._kalman as kalman

    expected = kalman_process_noise(MODEL, bandwidth=300.0, position_noise_std=1e-4, order=1)
    designed = []

    def counting(*args, **kwargs):
        designed.append(kwargs["process_noise_std"])
        return design_kalman(*args, **kwargs)

    monkeypatch.setattr(kalman, "design_kalman", counting)
    q = kalman_process_noise(MODEL, bandwidth=300.0, position_noise_std=1e-4, order=1)
    assert q == expected
    # the final check designs q itself; every trial before it is new
    assert len(set(designed[:-1])) == len(designed) - 1 >= 5
