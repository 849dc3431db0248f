"""Tuning: recommend the observer for a motor, a sensor and an uncertainty, verified by simulation.

tune, TuningResult
    Search every family, order and bandwidth analytically (accuracy, sensor noise, robust
    stability with a margin), simulate the Pareto front, verify the best at every corner of the
    uncertainty set.
"""

from ._result import TuningResult
from ._tune import OBJECTIVES, candidate_families, tune

__all__ = ["OBJECTIVES", "TuningResult", "candidate_families", "tune"]
