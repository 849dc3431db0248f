"""Tests that kill surviving mutants of hpdob/analysis/_describing.py (benchmarks/mutation.py):
the harmonic balance where the quasi-linear loop has no oscillatory mode."""

from __future__ import annotations

import numpy as np
import pytest

from hpdob.analysis._describing import harmonic_balance


@pytest.mark.parametrize(("real_pole", "expected"), [(1.5, 1.5), (1.05, 1.05), (0.5, 0.0)])
def test_without_an_oscillatory_mode_a_real_mode_decides_only_beyond_one(real_pole, expected):
    """A loop whose modes are all real (here diag(real_pole, 0.2)) has no harmonic balance:
    its modulus is the spectral radius where a real mode grows (beyond 1), else 0."""

    def build(gains):
        return np.diag([real_pole, 0.2]), {"x": np.array([1.0, 0.0])}

    modulus, angle, converged = harmonic_balance(build, {}, [1.0, 0.1], reference="x")
    assert modulus.tolist() == [expected, expected]
    assert np.isnan(angle).all() and converged.all()
