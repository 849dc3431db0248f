"""Realised poles: tests that kill the mutants benchmarks/mutation.py found surviving."""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from hpdob import ServoModel, design_observer
from hpdob.observers import error_matrix


@pytest.mark.parametrize(
    "poles",
    [
        [0.995 + 0.001j, 0.995 - 0.001j, 0.995 + 0.002j, 0.995 - 0.002j, 0.99],
        [0.98 + 0.01j, 0.98 - 0.01j, 0.98 + 0.0101j, 0.98 - 0.0101j],
    ],
)
def test_complex_poles_near_one_are_realised_as_high_precision_eigenvalues(poles):
    """Complex poles clustered near z = 1 at a high order: the gains rounded to doubles move
    them measurably, and the realised poles (the exact characteristic polynomial shifted to each
    complex centre in Gaussian integers) are the eigenvalues, at 60 digits, of the exact error
    matrix M = C - k e_(m+1)^T (eqs. 12, 22; C the integer companion matrix of (z - 1)^(m+1),
    every double gain taken at its exact value)."""
    model = ServoModel(2.8e-4, 5e-5).discretize(1e-3)
    design = design_observer(model, order=len(poles) - 1, poles=poles, pole_tolerance=None)
    n = len(poles)
    companion = error_matrix(np.zeros(n))  # integers, exact
    with mpmath.workdps(60):
        M = mpmath.matrix([[mpmath.mpf(float(v)) for v in row] for row in companion])
        for i, k in enumerate(design.k):
            M[i, n - 1] -= mpmath.mpf(float(k))
        reference = np.array([complex(z) for z in mpmath.eig(M, left=False, right=False)])
    realised = np.asarray(design.realised_poles, dtype=complex)
    moved = np.max(np.abs(realised - np.asarray(poles)))
    assert moved > 1e-10  # rounding really moved them: the test is not trivial
    for p in realised:
        assert np.min(np.abs(reference - p)) < 1e-3 * moved, (p, reference)
