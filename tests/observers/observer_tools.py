"""Shared fixtures of the peer observers' tests (tests/observers/test_eso.py, test_kalman.py,
test_peers.py, test_realised.py): the motors they run, a random trace, the stateful observer's
sample loop and the 80-digit mpmath eigenvalues their realised poles are checked against."""

from __future__ import annotations

import numpy as np

from hpdob import ServoModel

TS = 1e-3
J_N, B_N = 2.8e-4, 2e-5
#: The damped nominal motor of the peer tests.
MODEL = ServoModel(J_N, B_N).discretize(TS)
#: The frictionless motor of the realised-pole tests.
RIGID_MODEL = ServoModel(2.8e-4).discretize(1e-3)


def trace(rng, n=600):
    return np.cumsum(rng.normal(scale=2e-3, size=n)), rng.normal(scale=0.05, size=n)


def run_observer(obs, theta, u):
    tau, omega = [], []
    for th, uk in zip(theta.tolist(), u.tolist(), strict=True):
        tau.append(obs.estimate(th))
        omega.append(obs.velocity)
        obs.update(th, uk)
    return np.array(tau), np.array(omega)


def mp_eigenvalues(F, digits=80) -> np.ndarray:
    """Eigenvalues of the double matrix ``F`` (every entry at its exact value) by mpmath."""
    import mpmath

    with mpmath.workdps(digits):
        matrix = mpmath.matrix([[mpmath.mpf(float(v)) for v in row] for row in np.asarray(F)])
        return np.array([complex(e) for e in mpmath.eig(matrix, left=False, right=False)])


def match(found, reference) -> float:
    """Largest distance between the two multisets of roots, paired greedily."""
    left = list(reference)
    worst = 0.0
    for z in found:
        i = int(np.argmin([abs(z - r) for r in left]))
        worst = max(worst, abs(z - left.pop(i)))
    return worst
