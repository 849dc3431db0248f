"""Shared fixtures and reference values for the hpdob test suite."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob import ServoModel

# The paper's set-up (section IV): Maxon EC 90 flat class motor, Ts = 1 ms.
PAPER_J = 3.06e-4  # kg m^2
PAPER_B = 5e-5  # N m s/rad
PAPER_TS = 1e-3  # s


@pytest.fixture
def rng():
    return np.random.default_rng(20261123)


@pytest.fixture
def paper_model():
    """Nominal discrete model of the paper's motor (J_n = 2.8e-4, b_n = 0, Ts = 1 ms)."""
    return ServoModel(J=2.8e-4).discretize(PAPER_TS)
