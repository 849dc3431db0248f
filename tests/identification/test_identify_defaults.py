"""Issue 23: identification right with default settings, on SYNTHETIC logs of hpdob's own
``simulate`` (tests/synthetic_logs.py) whose truth is known. The targets: J within 3 %, b
within 10 % or 0.02 J 2 pi B, Coulomb within 5 % or 2 % of the input's RMS. The whole grid is
benchmarks/bench_identify_grid.py (192 logs, all within, worst J 1.1 %, b 39 % and Coulomb
21 % of their allowances: docs/real-data.md, measured 2026-12-01); here a few of its points."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import identify
from hpdob.identification._regression import noise_floor, signal_bandwidth
from synthetic_logs import synthetic_log, within_targets


@pytest.fixture(scope="module")
def issue_log():
    """The issue's log: J 1.2e-3, b 2e-3, Coulomb 0.03, 4096 counts, 0.5 ms, 20 s chirp+PRBS."""
    return synthetic_log(kind="chirp+prbs", counts=4096, Ts=5e-4, coulomb=0.03, seed=0)


def test_the_issues_log_fails_with_the_benchmark_rules(issue_log):
    """What the issue saw: IDIM-LS with the EMPS rules underestimates J by far more than 3 %
    (here -5.9 %), many standard deviations from the truth (14.9 textbook ones, 8.7 of the
    batch-means ones identify reports), and nothing warns."""
    s = issue_log
    fit = identify(s.log.t, s.log.theta, s.log.u, method="idim-ls", diagnostics=False)
    assert fit.J / s.J - 1.0 < -0.04
    assert (s.J - fit.J) / fit.std_iid["J"] > 10
    assert (s.J - fit.J) / fit.J_std > 5


def test_the_issues_log_is_right_by_default(issue_log):
    """Default settings: J +0.3 %, b -0.7 %, Coulomb +0.1 % (measured)."""
    s = issue_log
    fit = identify(s.log.t, s.log.theta, s.log.u)
    assert fit.method == "idim-iv-input" and fit.settings["adaptive"]
    np.testing.assert_allclose(fit.J, s.J, rtol=0.015)
    np.testing.assert_allclose(fit.b, s.b, rtol=0.05)
    np.testing.assert_allclose(fit.coulomb, s.coulomb, rtol=0.025)


GRID_POINTS = [  # kind, counts, Ts, Coulomb / input RMS
    ("multisine", 1024, 2.5e-4, 0.3),
    ("prbs", 1024, 2.5e-4, 0.1),
    ("chirp", 65536, 2e-3, 0.3),
    ("pd", 4096, 5e-4, 0.3),
    ("pd", 1024, 2.5e-4, 0.1),
]


@pytest.mark.parametrize(("kind", "counts", "Ts", "fraction"), GRID_POINTS)
def test_grid_points_meet_the_targets_by_default(kind, counts, Ts, fraction):
    """Errors measured on these points (% of the allowance): at most J 0.6 % (of 3 %), b 39 %,
    Coulomb 10 % - every one well inside."""
    s = synthetic_log(kind=kind, counts=counts, Ts=Ts, coulomb_fraction=fraction, seed=1)
    fit = s.log.identify()
    assert all(within_targets(fit, s).values()), within_targets(fit, s)


def test_closed_loop_log_with_its_loop_by_default():
    """With the loop given, the default is IDIM-IV through it; without, the input instruments.
    IDIM-LS with the benchmark's rules loses a fifth of the inertia on this log (-20 %)."""
    s = synthetic_log(kind="pd", counts=4096, Ts=5e-4, coulomb=0.03, seed=0)
    ls = s.log.identify(method="idim-ls", diagnostics=False)
    with_loop = s.log.identify(loop=s.loop)
    without = s.log.identify()
    assert ls.J / s.J - 1.0 < -0.1
    assert with_loop.method == "idim-iv" and without.method == "idim-iv-input"
    for fit in (with_loop, without):
        assert all(within_targets(fit, s).values())


def test_noise_floor_of_a_quantised_position_is_the_quantisation_noise():
    """q^2/12 spread over fs/2: PSD q^2 Ts / 6, with q the encoder step."""
    Ts, q = 1e-3, 2 * np.pi / 4096
    t = np.arange(20000) * Ts
    theta = q * np.round((0.3 * np.sin(2 * np.pi * 0.7 * t) + 0.2 * t) / q)
    floor, step = noise_floor(theta, Ts)
    assert step == pytest.approx(q, rel=1e-9)
    assert floor == pytest.approx(q * q * Ts / 6.0, rel=1e-9)


def test_signal_bandwidth_finds_the_last_line_above_the_noise():
    """Two sines, 3 Hz far above and 40 Hz 10x (20 dB amplitude) above the white noise floor
    of 1e-4 rad: the bandwidth is the 40 Hz line. Alone, the 3 Hz line 100 dB above the floor
    leaks a little (Blackman-Harris window, 0.24 Hz bins): 5.1 Hz."""
    rng = np.random.default_rng(3)
    Ts = 1e-3
    t = np.arange(40000) * Ts
    noise = 1e-5 * rng.standard_normal(t.size)
    theta = np.sin(2 * np.pi * 3 * t) + 1e-2 * np.sin(2 * np.pi * 40 * t) + noise
    assert signal_bandwidth(theta, Ts) == pytest.approx(40.0, abs=2.0)
    assert signal_bandwidth(np.sin(2 * np.pi * 3 * t) + noise, Ts) == pytest.approx(3.0, abs=2.5)
